"""Taking every frame waiting on a python-can bus in one go."""
from __future__ import annotations

import can
from can.interfaces.virtual import VirtualBus


def drain(bus: can.BusABC, timeout: float = 0.0, limit: int | None = None) -> list[can.Message]:
    """Frames waiting on ``bus``, in arrival order: waits up to ``timeout`` (s) for the first one, then
    takes the rest without waiting (at most ``limit`` frames in all).

    On python-can's ``virtual`` interface without receive filters the waiting frames are taken from its
    receive queue in one locked step instead of one ``recv`` call per frame; any other bus is read
    frame by frame with ``recv``.
    """
    first = bus.recv(timeout)
    if first is None:
        return []
    frames = [first]
    room = None if limit is None else limit - 1
    if isinstance(bus, VirtualBus) and bus.filters is None:
        rx = bus.queue
        with rx.mutex:
            take = len(rx.queue) if room is None else min(room, len(rx.queue))
            frames.extend(rx.queue.popleft() for _ in range(take))
            rx.not_full.notify_all()
        return frames
    while room is None or len(frames) <= room:
        msg = bus.recv(0.0)
        if msg is None:
            break
        frames.append(msg)
    return frames
