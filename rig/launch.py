"""The ``rig`` console script's first module: it is imported before :mod:`rig.cli` and its imports, so Ctrl-C from
here on ends the command with one line (``rig: interrupted``, status 130) and no traceback. Only the interpreter's
own start-up before this module (site, the console-script wrapper) is out of its reach."""
import os
import signal
import sys


def _interrupted_while_starting(signum: int, frame: object) -> None:
    sys.stderr.write("rig: interrupted\n")
    sys.stderr.flush()
    os._exit(130)


signal.signal(signal.SIGINT, _interrupted_while_starting)


def entry() -> None:
    """Import the command line under the start-up handler, then hand Ctrl-C back to Python (a KeyboardInterrupt that
    :func:`rig.cli.main` turns into its one line and the recorder into an interrupted, closed recording)."""
    from rig.cli import entry as run
    signal.signal(signal.SIGINT, signal.default_int_handler)
    run()
