"""The stop by SIGTERM, told apart from Ctrl-C (both stop a command the same way; the recording and the console name
which)."""


class Terminated(KeyboardInterrupt):
    """SIGTERM (sent by ``timeout``, ``docker stop``, systemd, CI runners) where the console script takes it
    (:func:`rig.launch.entry`): stops the command as Ctrl-C does; a recording names it ``Terminated: SIGTERM``."""

    def __init__(self) -> None:
        super().__init__("SIGTERM")
