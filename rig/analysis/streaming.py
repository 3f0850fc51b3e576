"""Per-column statistics of samples that arrive in blocks, never all held: moments and exact quantiles.

Samples come as blocks (rows = samples, columns = e.g. cam angles) from tasks that can regenerate them
(seeded). A *fold* is what a task computes over its blocks; the caller runs it over every task and hands back
the partial results in task order (``run(fold) -> iterable``), so floating-point merges happen in one fixed
order and the result does not depend on who computed what.

* Moments: per block mean and sum of squared deviations, merged by Chan's formula (one pass).
* Quantiles, exact (the same numbers as ``np.percentile(..., method="linear")`` on all samples): each wanted
  percent needs the order statistics k and k+1 of every column. Starting from [min, max], a histogram pass
  counts the values of each (column, percent) range in ``bins`` sub-bins and narrows the range to the bin(s)
  holding those ranks (counts are integers: exact and order-free); once every range holds at most ``cap``
  values, a last pass collects them and the order statistics are picked after sorting. Cost: the moments
  pass, usually one histogram pass (10⁶–10⁷ samples, 1024 bins: a tail bin holds ~10²) and the collect pass;
  memory: ``bins`` counts per range and at most ``cap`` values per range (unless a range cannot be cut
  further: then all its values are collected).
* One pass instead, when the number of samples is known beforehand and every wanted order statistic lies
  among the ``cap`` smallest or largest of its column (the ±3σ points of up to ~3·10⁶ samples at the default
  ``cap``): each task keeps, beside its moments, the k smallest and largest values of each column (a buffer of
  2k values per column, cut to its k smallest by ``np.partition`` when full; once the bound is set a value
  costs one comparison); the tails of all tasks are merged the same way and the order statistics picked from
  them. The same numbers as the passes above, every sample generated once instead of three times.
* Samples must be finite: a NaN or infinite value is an error naming the columns that hold one.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Iterable, Sequence

import numpy as np
from numba import njit

BINS = 1024
CAP = 4096


@dataclass(frozen=True)
class Moments:
    """Count, per-column mean, sum of squared deviations ``m2``, minimum and maximum."""

    n: int
    mean: np.ndarray
    m2: np.ndarray
    minimum: np.ndarray
    maximum: np.ndarray

    @classmethod
    def of_block(cls, block: np.ndarray) -> "Moments":
        mean = block.mean(axis=0)
        return cls(block.shape[0], mean, ((block - mean) ** 2).sum(axis=0), block.min(axis=0), block.max(axis=0))

    def merge(self, other: "Moments") -> "Moments":
        """Both sample sets together (Chan et al.'s pairwise update)."""
        n = self.n + other.n
        delta = other.mean - self.mean
        return Moments(n, self.mean + delta * (other.n / n), self.m2 + other.m2 + delta ** 2 * (self.n * other.n / n),
                       np.minimum(self.minimum, other.minimum), np.maximum(self.maximum, other.maximum))

    def scaled(self, factor: float) -> "Moments":
        """The same values in another unit (each × ``factor`` > 0)."""
        return Moments(self.n, self.mean * factor, self.m2 * factor ** 2, self.minimum * factor, self.maximum * factor)

    def std(self, ddof: int = 1) -> np.ndarray:
        return np.sqrt(self.m2 / (self.n - ddof))


class MomentsFold:
    """Fold: the :class:`Moments` of a task's blocks."""

    def __call__(self, blocks: Iterable[np.ndarray]) -> Moments:
        return TailsFold(0, 0)(blocks)[0]


@njit(cache=True, nogil=True)
def _keep_smallest(block: np.ndarray, sign: float, buf: np.ndarray, size: np.ndarray, top: np.ndarray) -> None:
    """Fold ``sign * block`` (rows, columns) into per-column buffers ``buf`` (columns, 2k) that hold the k
    smallest values seen among their first ``size`` entries: a value below its column's bound ``top`` is
    appended; a full buffer is cut to its k smallest, whose largest becomes the bound. Once the bound is set a
    value costs one comparison."""
    k = buf.shape[1] // 2
    for j in range(block.shape[1]):          # column by column: one buffer stays in cache
        b = buf[j]
        n = size[j]
        t = top[j]
        for i in range(block.shape[0]):
            v = sign * block[i, j]
            if v < t:
                b[n] = v
                n += 1
                if n == 2 * k:
                    b[:] = np.partition(b, k - 1)
                    n = k
                    t = b[k - 1]
        size[j] = n
        top[j] = t


class _Tail:
    """The ``k`` smallest (``largest=False``) or largest values of each column of the blocks added."""

    def __init__(self, k: int, columns: int, largest: bool) -> None:
        self.k = k
        self.sign = -1.0 if largest else 1.0           # the largest values are kept as the smallest negated
        self.buf = np.empty((columns, 2 * k))
        self.size = np.zeros(columns, dtype=np.int64)
        self.top = np.full(columns, np.inf)

    def add(self, block: np.ndarray) -> None:
        if self.k and len(block):
            _keep_smallest(np.ascontiguousarray(block, dtype=float), self.sign, self.buf, self.size, self.top)

    def values(self) -> np.ndarray:
        """The kept values, (≤ k, columns), unordered (every column holds as many: all its values, or k)."""
        k = self.k
        cols = [b[:n] if n <= k else np.partition(b[:n], k - 1)[:k] for b, n in zip(self.buf, self.size.tolist())]
        return self.sign * (np.array(cols).T if cols else np.empty((0, 0)))


@dataclass(frozen=True)
class TailsFold:
    """Fold: the :class:`Moments` of a task's blocks and, per column, its ``low`` smallest and ``high``
    largest values (arrays of shape (≤ low, columns) and (≤ high, columns), unordered)."""

    low: int
    high: int

    def __call__(self, blocks: Iterable[np.ndarray]) -> tuple[Moments, np.ndarray, np.ndarray]:
        out, low, high = None, None, None
        for block in blocks:
            if not len(block):
                continue
            part = Moments.of_block(block)
            out = part if out is None else out.merge(part)
            if low is None:
                low, high = _Tail(self.low, block.shape[1], False), _Tail(self.high, block.shape[1], True)
            low.add(block)
            high.add(block)
        if out is None:
            raise ValueError("a task produced no samples")
        if not np.all(np.isfinite(out.mean)):       # NaN/inf: the tails drop them unevenly; the caller names it
            empty = np.empty((0, out.mean.size))
            return out, empty, empty
        return out, low.values(), high.values()


@njit(cache=True)
def _edges(lo: float, hi: float, k: int, bins: int) -> float:
    return hi if k == bins else lo + (hi - lo) * k / bins


@njit(cache=True, nogil=True)
def _bin(v: float, lo: float, hi: float, scale: float, bins: int) -> int:
    """Bin of v in [lo, hi) cut into ``bins`` at :func:`_edges` (-1: outside); ``scale`` = bins/(hi − lo) only
    guesses it, the edges decide."""
    if not (v >= lo and v < hi):
        return -1
    x = (v - lo) * scale
    k = min(int(x), bins - 1) if x < bins else bins - 1   # x ≥ 0; inf or nan (tiny range) → last bin
    while k > 0 and v < _edges(lo, hi, k, bins):
        k -= 1
    while k < bins - 1 and v >= _edges(lo, hi, k + 1, bins):
        k += 1
    return k


@njit(cache=True, nogil=True)
def _histogram(block: np.ndarray, lo: np.ndarray, hi: np.ndarray, counts: np.ndarray) -> None:
    bins, q = counts.shape[2], lo.shape[1]
    scale = bins / (hi - lo)
    for j in range(block.shape[1]):          # column by column: one column's counts stay in cache
        for i in range(block.shape[0]):
            v = block[i, j]
            k = -1
            for t in range(q):
                if t == 0 or lo[j, t] != lo[j, t - 1] or hi[j, t] != hi[j, t - 1]:   # same range: same bin
                    k = _bin(v, lo[j, t], hi[j, t], scale[j, t], bins)
                if k >= 0:
                    counts[j, t, k] += 1


@njit(cache=True, nogil=True)
def _collect(block: np.ndarray, lo: np.ndarray, hi: np.ndarray, values: np.ndarray, target: np.ndarray,
             fill: int) -> int:
    q = lo.shape[1]
    for i in range(block.shape[0]):
        for j in range(block.shape[1]):
            v = block[i, j]
            for t in range(q):
                if v >= lo[j, t] and v < hi[j, t]:
                    values[fill] = v
                    target[fill] = j * q + t
                    fill += 1
    return fill


@dataclass(frozen=True)
class HistogramFold:
    """Fold: counts (columns, ranges, bins) of the values in each range [lo, hi) of each column."""

    lo: np.ndarray
    hi: np.ndarray
    bins: int

    def __call__(self, blocks: Iterable[np.ndarray]) -> np.ndarray:
        counts = np.zeros(self.lo.shape + (self.bins,), dtype=np.int64)
        for block in blocks:
            _histogram(block, self.lo, self.hi, counts)
        return counts


@dataclass(frozen=True)
class CollectFold:
    """Fold: the values in each range [lo, hi) and their range index (column·ranges + range); ``total`` bounds
    their number over all tasks."""

    lo: np.ndarray
    hi: np.ndarray
    total: int

    def __call__(self, blocks: Iterable[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        values, target, fill = np.empty(self.total), np.empty(self.total, dtype=np.int64), 0
        for block in blocks:
            fill = _collect(block, self.lo, self.hi, values, target, fill)
        return values[:fill].copy(), target[:fill].copy()


def linear_ranks(n: int, percents: Sequence[float]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Order statistics (0-based) k, k+1 and weight γ of numpy's "linear" percentile for ``n`` samples
    (its formulas, so the interpolation is bit for bit the same)."""
    q = np.true_divide(np.asarray(percents, dtype=float), 100)
    virtual = (n - 1) * q
    prev = np.floor(virtual)
    gamma = virtual - prev
    k0 = prev.astype(np.int64)
    k1 = k0 + 1
    top, bottom = virtual >= n - 1, virtual < 0
    k0[top], k1[top], k0[bottom], k1[bottom] = n - 1, n - 1, 0, 0
    return k0, k1, gamma


def _lerp(a: np.ndarray, b: np.ndarray, t: np.ndarray) -> np.ndarray:
    """numpy's percentile interpolation (numpy.lib._function_base_impl._lerp)."""
    diff = b - a
    out = a + diff * t
    return np.where(t >= 0.5, b - diff * (1 - t), out)


@dataclass(frozen=True)
class ColumnStats:
    """Per-column n, mean, σ (ddof = 1), min, max and the exact percentiles {percent: values}."""

    n: int
    mean: np.ndarray
    std: np.ndarray
    minimum: np.ndarray
    maximum: np.ndarray
    percentiles: dict[float, np.ndarray]


Run = Callable[[Callable], Iterable]


def _tail_sizes(n: int, percents: Sequence[float]) -> tuple[int, int]:
    """How many smallest and largest values per column hold the order statistics of ``percents`` of ``n``
    samples (each percent from the nearer end)."""
    k0, k1, _ = linear_ranks(n, percents)
    low = [int(b) + 1 for a, b in zip(k0, k1) if b + 1 <= n - a]
    high = [n - int(a) for a, b in zip(k0, k1) if b + 1 > n - a]
    return max(low, default=0), max(high, default=0)


def passes(n: int, percents: Sequence[float], cap: int = CAP) -> int:
    """Passes over the samples :func:`column_statistics` usually makes for ``n`` samples given beforehand:
    1 when the tails hold every wanted order statistic, else 3 (moments, histogram, collect)."""
    return 1 if max(_tail_sizes(n, percents)) <= cap else 3


def _check_finite(moments: Moments) -> None:
    bad = np.flatnonzero(~np.isfinite(moments.mean))
    if bad.size:
        raise ValueError(f"samples are not all finite (NaN or infinite values) in {bad.size} column(s), the first "
                         f"{bad[:5].tolist()}: no statistics")


def _one_pass(run: Run, n: int, pct: tuple[float, ...], low: int, high: int) -> ColumnStats:
    """Moments and percentiles from the tasks' tails in one pass (module docstring)."""
    moments, lows, highs = None, None, None
    for part, part_low, part_high in run(TailsFold(low, high)):
        if moments is None:
            lows, highs = _Tail(low, part.mean.size, False), _Tail(high, part.mean.size, True)
        moments = part if moments is None else moments.merge(part)
        lows.add(part_low)
        highs.add(part_high)
    if moments is None or moments.n != n:
        got = 0 if moments is None else moments.n
        raise RuntimeError(f"the tasks produced {got} samples, {n} were announced")
    _check_finite(moments)
    lows, highs = np.sort(lows.values(), axis=0), np.sort(highs.values(), axis=0)
    k0, k1, gamma = linear_ranks(n, pct)
    out: dict[float, np.ndarray] = {}
    for a, b, g, p in zip(k0.tolist(), k1.tolist(), gamma, pct):
        if b + 1 <= n - a:
            va, vb = lows[a], lows[b]
        else:
            va, vb = highs[a - (n - len(highs))], highs[b - (n - len(highs))]
        out[p] = _lerp(va, vb, np.full(va.shape, g))
    return ColumnStats(n, moments.mean, moments.std(1), moments.minimum, moments.maximum, out)


def column_statistics(run: Run, percents: Sequence[float], bins: int = BINS, cap: int = CAP,
                      n: int | None = None) -> ColumnStats:
    """Statistics of all samples the tasks produce; ``run(fold)`` applies a fold to every task's blocks and
    yields the results in task order. ``n``: the number of samples, when known beforehand (allows the one-pass
    method). Passes: one, or moments, histogram(s), collect (module docstring)."""
    if bins < 2 or cap < 2:
        raise ValueError(f"quantile search needs bins >= 2 and cap >= 2, got bins={bins}, cap={cap}")
    pct = tuple(float(p) for p in percents)
    if n is not None:
        if n < 2:
            raise ValueError("column statistics need at least 2 samples")
        low, high = _tail_sizes(n, pct)
        if max(low, high) <= cap:
            return _one_pass(run, n, pct, low, high)
    moments = None
    for part in run(MomentsFold()):
        moments = part if moments is None else moments.merge(part)
    if moments is None or moments.n < 2:
        raise ValueError("column statistics need at least 2 samples")
    if n is not None and moments.n != n:
        raise RuntimeError(f"the tasks produced {moments.n} samples, {n} were announced")
    _check_finite(moments)
    n = moments.n
    k0, k1, gamma = linear_ranks(n, pct)
    m, q = moments.mean.size, len(pct)
    lo = np.repeat(moments.minimum[:, None], q, axis=1)
    hi = np.repeat(np.nextafter(moments.maximum, np.inf)[:, None], q, axis=1)
    below, count = np.zeros((m, q), dtype=np.int64), np.full((m, q), n, dtype=np.int64)
    rows = np.arange(m)[:, None]
    while q:      # at least one histogram pass: the number of passes does not depend on n
        counts = None
        for part in run(HistogramFold(lo, hi, bins)):
            counts = part if counts is None else counts + part
        cum = np.cumsum(counts, axis=2)
        if not np.array_equal(cum[..., -1], count):
            raise RuntimeError("tasks gave different samples in two passes (not reproducible from their seeds)")
        b0 = np.empty((m, q), dtype=np.int64)
        b1 = np.empty((m, q), dtype=np.int64)
        for t in range(q):
            for out, k in ((b0, k0[t]), (b1, k1[t])):
                out[:, t] = [np.searchsorted(cum[j, t], k - below[j, t], side="right") for j in range(m)]
        before = np.where(b0 > 0, np.take_along_axis(cum, np.maximum(b0 - 1, 0)[..., None], axis=2)[..., 0], 0)
        upto = np.take_along_axis(cum, b1[..., None], axis=2)[..., 0]
        new_lo, new_hi = lo + (hi - lo) * b0 / bins, np.where(b1 + 1 == bins, hi, lo + (hi - lo) * (b1 + 1) / bins)
        stuck = (new_lo == lo) & (new_hi == hi)
        lo, hi, below, count = new_lo, new_hi, below + before, upto - before
        if np.all(stuck | (count <= cap)):
            break
    values, target = (np.empty(0), np.empty(0, dtype=np.int64)) if not q else (None, None)
    if q:
        parts = list(run(CollectFold(lo, hi, int(count.sum()))))
        values = np.concatenate([p[0] for p in parts])
        target = np.concatenate([p[1] for p in parts])
        if not np.array_equal(np.bincount(target, minlength=m * q), count.ravel()):
            raise RuntimeError("tasks gave different samples in two passes (not reproducible from their seeds)")
    out: dict[float, np.ndarray] = {}
    order = np.lexsort((values, target))
    values, target = values[order], target[order]
    start = np.searchsorted(target, np.arange(m * q))
    for t, p in enumerate(pct):
        idx = rows[:, 0] * q + t
        a = values[start[idx] + (k0[t] - below[:, t])]
        b = values[start[idx] + (k1[t] - below[:, t])]
        out[p] = _lerp(a, b, np.full(m, gamma[t]))
    return ColumnStats(n, moments.mean, moments.std(1), moments.minimum, moments.maximum, out)
