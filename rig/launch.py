"""The ``rig`` console script's first module: it is imported before :mod:`rig.cli` and its imports, so Ctrl-C from
here on ends the command with one line (``rig: interrupted``, status 130) and no traceback. Only the interpreter's
own start-up before this module (site, the console-script wrapper) is out of its reach."""
import os
import signal
import sys

from rig.stops import spawned_worker, stop_on_signals


def _interrupted_while_starting(signum: int, frame: object) -> None:
    sys.stderr.write("rig: interrupted\n")
    sys.stderr.flush()
    os._exit(130)


# A worker process that multiprocessing spawns (Dask's) runs the console script again, as __mp_main__, and a Ctrl-C
# at the terminal reaches every process of the group: the workers ignore it, the parent says it once and closes them.
if "__mp_main__" in sys.modules:
    spawned_worker()
else:
    signal.signal(signal.SIGINT, _interrupted_while_starting)


def entry() -> None:
    """Import the command line under the start-up handler, then hand Ctrl-C back to Python (a KeyboardInterrupt that
    :func:`rig.cli.main` turns into its one line and the recorder into an interrupted, closed recording); SIGTERM (sent
    by ``timeout``, ``docker stop``, systemd, CI runners) stops the command the same way (as
    :class:`rig.stops.Terminated`, named so in the recording and the console), instead of leaving a cut recording
    without a word."""
    from rig.cli import entry as run
    stop_on_signals()
    run()
