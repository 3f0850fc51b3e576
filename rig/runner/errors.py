"""Why a run could not complete: the errors the runner raises and the command line names (a module of its own, so
that a command catching them does not import the runner)."""


class RunError(RuntimeError):
    """A run could not complete (the machine did not produce what the scene asks for in time). ``stop_cause``: the
    ``TxStatus.StopCause`` the unit sends when this stops its run (its hosts learn why)."""

    stop_cause = "Fault"


class OutOfTime(RunError):
    """The scene's cycles were not complete by its ``max_time`` of simulated time."""

    stop_cause = "OutOfTime"


class HostLeft(RunError):
    """The served host disconnected without releasing the device."""

    stop_cause = "HostLeft"


class HostStalled(RunError):
    """The served host stopped reading (the machine waited for it in vain)."""

    stop_cause = "HostStalled"


class BusTooSlow(RunError):
    """The scene's CAN link cannot carry what the unit measures."""

    stop_cause = "BusOverload"
