"""CAN arbitration in virtual time for a whole transmit queue at once (compiled with numba).

Whenever the bus falls idle, the frame with the lowest rank among those ready goes next (CAN
arbitration: lowest identifier wins; the rank adds the enqueue order so equal identifiers leave in
order). A frame once started is not interrupted. A frame whose expiry time has passed when it would
start is dropped instead of sent (stale live data). This is the per-frame loop of a real node's
transmit scheduler, run over arrays so a chunk of thousands of frames costs microseconds.
"""
from __future__ import annotations

import numpy as np
from numba import njit

PENDING, SENT, DROPPED = 0, 1, 2


@njit(cache=True)
def _sift_down(heap, n, rank, pos):
    item = heap[pos]
    while True:
        child = 2 * pos + 1
        if child >= n:
            break
        if child + 1 < n and rank[heap[child + 1]] < rank[heap[child]]:
            child += 1
        if rank[heap[child]] >= rank[item]:
            break
        heap[pos] = heap[child]
        pos = child
    heap[pos] = item


@njit(cache=True)
def _push(heap, n, rank, item):
    pos = n
    while pos > 0:
        parent = (pos - 1) // 2
        if rank[heap[parent]] <= rank[item]:
            break
        heap[pos] = heap[parent]
        pos = parent
    heap[pos] = item


@njit(cache=True)
def arbitrate(ready, rank, duration, expires, by_ready, bus_free, t_end):
    """Send frames on an idle-from-``bus_free`` bus up to ``t_end`` (s).

    ready, rank, duration, expires: per frame (s; int64 unique ranks; s; s, inf = never stale);
    by_ready: frame indices sorted by ready time. Returns (state per frame: PENDING/SENT/DROPPED,
    end time of each sent frame (s), indices of the sent frames in wire order, the new bus-free time).
    A frame is sent only if it is complete by ``t_end``.
    """
    n = ready.shape[0]
    state = np.zeros(n, np.int8)
    ends = np.zeros(n)
    order = np.empty(n, np.int64)
    heap = np.empty(n, np.int64)
    size, p, sent = 0, 0, 0
    while True:
        while p < n and ready[by_ready[p]] <= bus_free:
            _push(heap, size, rank, by_ready[p])
            size += 1
            p += 1
        if size == 0:
            if p >= n or ready[by_ready[p]] >= t_end:
                bus_free = max(bus_free, t_end)
                break
            bus_free = ready[by_ready[p]]
            continue
        i = heap[0]
        if bus_free > expires[i]:
            state[i] = DROPPED
        else:
            end = bus_free + duration[i]
            if end > t_end:
                break
            state[i] = SENT
            ends[i] = end
            order[sent] = i
            sent += 1
            bus_free = end
        size -= 1
        if size > 0:
            heap[0] = heap[size]
            _sift_down(heap, size, rank, 0)
    return state, ends, order[:sent], bus_free
