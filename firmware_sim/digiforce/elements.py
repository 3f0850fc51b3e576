"""Evaluation elements: graphical criteria, each a pass/fail with a reason and its process values.

Elements are data: a dict with ``kind`` (a key of :data:`ELEMENT_KINDS`), ``name``, ``enabled``,
``part`` (forward / return / complete), ``channel`` (y or y2) and kind-specific keys. The registry
turns them into element objects whose ``check(x, y)`` is vectorised over the curve part.
Edge semantics (closed regions, touching, corners, wrong side) are documented in docs/digiforce.md.

A failed check says which rule failed and where (``"entry top: entered through the left side at x = 0.036 m,
y = -52 N, not through the top"``); numbers are written by a *formatter* ``fmt(channel, value)`` (channel
``"x"``, ``"y"`` or ``"y2"``, value in SI), so the unit writes its engineering units and a host can write the
same reasons in the units its user reads (:func:`build_elements`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Callable, ClassVar, Mapping

import numpy as np

from . import checks
from .errors import DigiForceError
from .geometry import SIDES, ConvexQuad

PARTS = ("forward", "return", "complete")
SIDE_RULES = SIDES + ("any", "none", "ignore")
EXTREMES = ("x_max", "x_min", "y_max", "y_min")
COMMON_KEYS = ("kind", "name", "enabled", "part", "channel")
Verdict = tuple[bool, str, dict[str, float]]
Formatter = Callable[[str, float], str]


def plain_format(channel: str, value: float) -> str:
    """A number without a unit (6 significant digits)."""
    return f"{value:.6g}"


def unit_format(units: Mapping[str, str]) -> Formatter:
    """Numbers (6 significant digits) followed by the channel's unit: ``"0.0412 m"``."""
    return lambda channel, value: f"{value:.6g} {units[channel]}"


@dataclass(frozen=True)
class Check:
    """Outcome of one element on one curve part: pass/fail, why (the rule and where; empty when it passed),
    its process values, and ``at``: the (x, y) where it failed, when there is such a point."""

    ok: bool
    reason: str = ""
    values: dict[str, float] = field(default_factory=dict)
    at: tuple[float, float] | None = None


class Element:
    """Base of all elements: holds the normalised config; subclasses implement ``check``."""

    kind: ClassVar[str]
    keys: ClassVar[tuple[str, ...]]
    values: ClassVar[tuple[str, ...]] = ()

    def __init__(self, cfg: Mapping[str, Any], fmt: Formatter | None = None) -> None:
        self.cfg = cfg
        self.name: str = cfg["name"]
        self.part: str = cfg["part"]
        self.channel: str = cfg["channel"]
        self.fmt: Formatter = fmt or plain_format

    @classmethod
    def normalize(cls, cfg: Mapping[str, Any], xu: str, yu: str, where: str) -> dict[str, Any]:
        raise NotImplementedError

    def check(self, x: np.ndarray, y: np.ndarray) -> Check:
        raise NotImplementedError

    def evaluate(self, x: np.ndarray, y: np.ndarray) -> Verdict:
        """``(ok, reason, process values)`` of the curve part (x, y)."""
        c = self.check(x, y)
        return c.ok, c.reason, c.values

    # number formatting: X in the X channel's terms, Y in those of the element's channel
    def _x(self, value: float) -> str:
        return self.fmt("x", float(value))

    def _y(self, value: float) -> str:
        return self.fmt(self.channel, float(value))

    def _pt(self, x: float, y: float) -> str:
        return f"x = {self._x(x)}, y = {self._y(y)}"

    @property
    def _subject(self) -> str:
        """What the element sees: the forward or return part, or the complete curve."""
        return {"forward": "the forward part", "return": "the return part"}.get(self.part, "the curve")


class _Region(Element):
    """Shared evaluation of windows and trapezoids: entry/exit sides, optional extreme-in-region check."""

    values = ("x_entry", "y_entry", "x_exit", "y_exit")
    region: ConvexQuad

    def check(self, x: np.ndarray, y: np.ndarray) -> Check:
        c = self.region.crossings(x, y)
        nan = math.nan
        vals = {"x_entry": float(c.entry_points[0, 0]) if len(c.entry_points) else nan,
                "y_entry": float(c.entry_points[0, 1]) if len(c.entry_points) else nan,
                "x_exit": float(c.exit_points[-1, 0]) if len(c.exit_points) else nan,
                "y_exit": float(c.exit_points[-1, 1]) if len(c.exit_points) else nan}
        entry, exit_, check = self.cfg["entry"], self.cfg["exit"], self.cfg.get("check")
        between = self._excursion(x, y) if max(len(c.entry_points), len(c.exit_points)) > 1 else ""
        failed = (self._side(entry, True, c.starts_inside, c.entry_points, c.entry_sides, x[0], y[0], between)
                  or self._side(exit_, False, c.ends_inside, c.exit_points, c.exit_sides, x[-1], y[-1], between))
        if failed is None and check is not None:
            axis = x if check[0] == "x" else y
            i = int(np.argmax(axis) if check.endswith("max") else np.argmin(axis))
            if not self.region.contains(x[i], y[i])[0]:
                value, where = ((self._x(x[i]), f"y = {self._y(y[i])}") if check[0] == "x"
                                else (self._y(y[i]), f"x = {self._x(x[i])}"))
                failed = (f"check {check}: {check.replace('_', ' ')} {value} at {where} lies "
                          f"{self._outside(x[i], y[i])}", (float(x[i]), float(y[i])))
        if failed is None and entry == exit_ == "ignore" and check is None and not c.touched:
            failed = (f"{self._subject} does not pass through the {self.kind}", None)
        if failed is None:
            return Check(True, "", vals)
        return Check(False, failed[0], vals, failed[1])

    def _excursion(self, x: np.ndarray, y: np.ndarray) -> str:
        """Where the curve, once inside, went farthest out before coming back (what makes it cross more than once):
        ``"; in between it went below the window (y min -55 N) to y = -56.76 N at x = 39.8 mm, 1.76 N beyond"``;
        empty when it never comes back."""
        sv = self.region._signed(x, y)
        inside = np.flatnonzero(sv.min(axis=0) >= 0.0)
        if inside.size < 2:
            return ""
        span = np.arange(inside[0], inside[-1] + 1)
        depth = sv[:, span].min(axis=0)
        if depth.min() >= 0.0:
            return ""
        k = int(span[np.argmin(depth)])
        return f"; in between it went {self._beyond(SIDES[int(np.argmin(sv[:, k]))], float(x[k]), float(y[k]))}"

    def _beyond(self, side: str, px: float, py: float) -> str:
        """The deepest point of an excursion beyond ``side``, in words."""
        return f"beyond the {side} side of the {self.kind} to {self._pt(px, py)}"

    def _side(self, rule: str, entering: bool, inside_at_end: bool, points: np.ndarray, sides: np.ndarray,
              x_end: float, y_end: float, between: str = "") -> tuple[str, tuple[float, float] | None] | None:
        """Why the entry (``entering``) or exit violates ``rule`` and where; None if it complies. ``x_end``,
        ``y_end``: the curve's first (entry) or last (exit) pair; ``between``: :meth:`_excursion`, told when the
        curve crossed more than once."""
        if rule == "ignore":
            return None
        tag = f"{'entry' if entering else 'exit'} {rule}"
        verb, past, end = ("enter", "entered", "start") if entering else ("leave", "exited", "end")
        kind, n, who = self.kind, len(points), self._subject
        first = (float(points[0, 0]), float(points[0, 1])) if n else None
        end_pt = (float(x_end), float(y_end))
        if rule == "none":
            if not inside_at_end:
                return f"{tag}: {who} must {end} inside the {kind} but {end}s outside, at {self._pt(*end_pt)}", end_pt
            if n:
                return (f"{tag}: {who} {past} the {kind} at {self._pt(*first)}; it must {end} inside and never "
                        f"{verb} it"), first
            return None
        through = "any side" if rule == "any" else f"the {rule}"
        if inside_at_end:
            return f"{tag}: {who} {end}s inside the {kind}, at {self._pt(*end_pt)}; it must {verb} through {through}", end_pt
        if n == 0:
            return f"{tag}: {who} never {'enters' if entering else 'leaves'} the {kind}", None
        if n > 1:
            at = "; ".join(f"through the {self._sides(k, sides)} at {self._pt(px, py)}"
                           for k, (px, py) in enumerate(points[:3])) + ("; …" if n > 3 else "")
            again = (float(points[1, 0]), float(points[1, 1]))         # where it failed: the first crossing too many
            return f"{tag}: {who} {past} the {kind} {n} times (exactly once allowed): {at}{between}", again
        if rule != "any" and not sides[0][SIDES.index(rule)]:
            used = "/".join(side for side, hit in zip(SIDES, sides[0]) if hit)
            return f"{tag}: {past} through the {used} side at {self._pt(*first)}, not through the {rule}", first
        return None

    def _sides(self, k: int, sides: np.ndarray) -> str:
        """The side(s) crossing ``k`` passed (``top``, ``bottom/left`` at a corner), with the limit there."""
        names = [s for s, hit in zip(SIDES, sides[k]) if hit]
        if len(names) != 1:
            return "/".join(names) or "boundary"
        return f"{names[0]} ({limit})" if (limit := self._limit(names[0])) else names[0]

    def _limit(self, side: str) -> str:
        """The limit a side stands for (``"y min -56 N"``); empty for a region without one per side."""
        return ""

    def _outside(self, px: float, py: float) -> str:
        """Which sides of the region the point (px, py) lies beyond."""
        beyond = self.region._signed(np.array([px]), np.array([py]))[:, 0] < 0.0
        return f"beyond the {'/'.join(s for s, b in zip(SIDES, beyond) if b)} side of the {self.kind}"


class Window(_Region):
    """Rectangle [x_min, x_max] x [y_min, y_max]; entry/exit side rules; optional extreme check."""

    kind = "window"
    keys = ("x_min", "x_max", "y_min", "y_max", "entry", "exit", "check")

    def __init__(self, cfg: Mapping[str, Any], fmt: Formatter | None = None) -> None:
        super().__init__(cfg, fmt)
        x0, x1, y0, y1 = cfg["x_min"], cfg["x_max"], cfg["y_min"], cfg["y_max"]
        self.region = ConvexQuad([(x0, y0), (x1, y0), (x1, y1), (x0, y1)])

    #: side → (its key, where a point beyond it lies)
    _SIDE = {"left": ("x_min", "left of"), "right": ("x_max", "right of"), "bottom": ("y_min", "below"),
             "top": ("y_max", "above")}

    def _limit(self, side: str) -> str:
        key = self._SIDE[side][0]
        return f"{key.replace('_', ' ')} {(self._x if key[0] == 'x' else self._y)(self.cfg[key])}"

    def _beyond(self, side: str, px: float, py: float) -> str:
        key = self._SIDE[side][0]
        fmt, value = (self._x, px) if key[0] == "x" else (self._y, py)
        other = f"y = {self._y(py)}" if key[0] == "x" else f"x = {self._x(px)}"
        return (f"{self._SIDE[side][1]} the window ({self._limit(side)}) to {key[0]} = {fmt(value)} at {other}, "
                f"{fmt(abs(value - self.cfg[key]))} beyond")

    def _outside(self, px: float, py: float) -> str:
        c = self.cfg
        beyond = {"left": px < c["x_min"], "right": px > c["x_max"], "bottom": py < c["y_min"], "top": py > c["y_max"]}
        parts = [f"{self._SIDE[s][1]} the window ({self._limit(s)})" for s, bad in beyond.items() if bad]
        return " and ".join(parts) or "outside the window"

    @classmethod
    def normalize(cls, cfg: Mapping[str, Any], xu: str, yu: str, where: str) -> dict[str, Any]:
        out = {k: checks.number(cfg, k, xu if k[0] == "x" else yu, where) for k in cls.keys[:4]}
        for lo, hi in (("x_min", "x_max"), ("y_min", "y_max")):
            if not out[lo] < out[hi]:
                u = xu if lo[0] == "x" else yu
                raise DigiForceError(f"{where}: {lo} {checks.written(cfg[lo], u)} must be below "
                                     f"{hi} {checks.written(cfg[hi], u)}")
        out["entry"] = checks.choice(cfg, "entry", SIDE_RULES, where, "any")
        out["exit"] = checks.choice(cfg, "exit", SIDE_RULES, where, "any")
        out["check"] = checks.choice(cfg, "check", (None,) + EXTREMES, where, None)
        return out


class Trapezoid(_Region):
    """Band along one axis: ``axis = "y"`` limits Y between ``lower`` and ``upper`` lines running from
    X = start to X = end (entered left, left right by default); ``axis = "x"`` is the same with X and Y
    swapped (limits on X, running from Y = start to Y = end; entered bottom, left top by default)."""

    kind = "trapezoid"
    keys = ("axis", "start", "end", "lower", "upper", "entry", "exit", "check")

    def __init__(self, cfg: Mapping[str, Any], fmt: Formatter | None = None) -> None:
        super().__init__(cfg, fmt)
        s, e, (l0, l1), (u0, u1) = cfg["start"], cfg["end"], cfg["lower"], cfg["upper"]
        # corners counter-clockwise: bottom-left, bottom-right, top-right, top-left
        corners = [(s, l0), (e, l1), (e, u1), (s, u0)] if cfg["axis"] == "y" else [(l0, s), (u0, s), (u1, e), (l1, e)]
        self.region = ConvexQuad(corners)

    @classmethod
    def normalize(cls, cfg: Mapping[str, Any], xu: str, yu: str, where: str) -> dict[str, Any]:
        axis = checks.choice(cfg, "axis", ("x", "y"), where, "y")
        run_u, lim_u = (xu, yu) if axis == "y" else (yu, xu)
        out = {"axis": axis, "start": checks.number(cfg, "start", run_u, where),
               "end": checks.number(cfg, "end", run_u, where)}
        if not out["start"] < out["end"]:
            raise DigiForceError(f"{where}: start {checks.written(cfg['start'], run_u)} must be below "
                                 f"end {checks.written(cfg['end'], run_u)}")
        out["lower"] = [checks.quantity(v, lim_u, f"{where}.lower") for v in _list2(cfg, "lower", where)]
        out["upper"] = [checks.quantity(v, lim_u, f"{where}.upper") for v in _list2(cfg, "upper", where)]
        if not (out["lower"][0] < out["upper"][0] and out["lower"][1] < out["upper"][1]):
            lower, upper = (", ".join(checks.written(v, lim_u) for v in cfg[k]) for k in ("lower", "upper"))
            raise DigiForceError(f"{where}: lower [{lower}] must be below upper [{upper}] at both ends")
        default_in, default_out = ("left", "right") if axis == "y" else ("bottom", "top")
        out["entry"] = checks.choice(cfg, "entry", SIDE_RULES, where, default_in)
        out["exit"] = checks.choice(cfg, "exit", SIDE_RULES, where, default_out)
        out["check"] = checks.choice(cfg, "check", (None,) + EXTREMES, where, None)
        return out


def _list2(cfg: Mapping[str, Any], key: str, where: str) -> list[Any]:
    value = cfg.get(key)
    if not isinstance(value, (list, tuple)) or len(value) != 2:
        raise DigiForceError(f"{where}.{key}: expected [value at start, value at end], got {value!r}")
    return list(value)


class Threshold(Element):
    """Line ``axis = value`` (optionally only where the other coordinate is within ``range``) that the
    curve must cross in ``direction``; reaching the value from the other side counts as crossing."""

    kind = "threshold"
    keys = ("axis", "value", "direction", "range")
    values = ("at",)

    @classmethod
    def normalize(cls, cfg: Mapping[str, Any], xu: str, yu: str, where: str) -> dict[str, Any]:
        axis = checks.choice(cfg, "axis", ("x", "y"), where, "y")
        other_u = xu if axis == "y" else yu
        rng = cfg.get("range", [None, None])
        if not isinstance(rng, (list, tuple)) or len(rng) != 2:
            raise DigiForceError(f"{where}.range: expected [low, high] (either may be null), got {rng!r}")
        lo, hi = (None if v is None else checks.quantity(v, other_u, f"{where}.range") for v in rng)
        if lo is not None and hi is not None and not lo <= hi:
            raise DigiForceError(f"{where}.range: low {checks.written(rng[0], other_u)} must be below high "
                                 f"{checks.written(rng[1], other_u)}")
        return {"axis": axis, "value": checks.number(cfg, "value", xu if axis == "x" else yu, where),
                "direction": checks.choice(cfg, "direction", ("rising", "falling", "any"), where, "rising"),
                "range": [lo, hi]}

    def check(self, x: np.ndarray, y: np.ndarray) -> Check:
        axis = self.cfg["axis"]
        a, b = (y, x) if axis == "y" else (x, y)
        v, direction = self.cfg["value"], self.cfg["direction"]
        a0, a1 = a[:-1], a[1:]
        rising, falling = (a0 < v) & (a1 >= v), (a0 > v) & (a1 <= v)
        cross = rising if direction == "rising" else falling if direction == "falling" else rising | falling
        idx = np.nonzero(cross)[0]
        at = b[idx] + (v - a0[idx]) / (a1[idx] - a0[idx]) * (b[idx + 1] - b[idx])
        lo, hi = self.cfg["range"]
        ok = np.ones(at.shape, bool)
        if lo is not None:
            ok &= at >= lo
        if hi is not None:
            ok &= at <= hi
        if ok.any():
            return Check(True, "", {"at": float(at[ok][0])})
        other = "x" if axis == "y" else "y"
        fa, fb = (self._y, self._x) if axis == "y" else (self._x, self._y)
        where = "" if (lo, hi) == (None, None) else \
            f" with {other} in [{'…' if lo is None else fb(lo)}, {'…' if hi is None else fb(hi)}]"
        reason = f"{self._subject} never crosses {axis} = {fa(v)} {direction}{where}"
        if len(at):
            point = (float(at[0]), float(v)) if axis == "y" else (float(v), float(at[0]))
            reason += f"; it crosses at {other} = {', '.join(fb(c) for c in at[:3])}, outside the range"
        else:
            below = np.maximum(lo - b, 0.0) if lo is not None else np.zeros(b.shape)
            beyond = below + (np.maximum(b - hi, 0.0) if hi is not None else 0.0)     # distance from the range
            if np.any(beyond == 0.0):
                pool = np.flatnonzero(beyond == 0.0)
                i = int(pool[np.argmin(np.abs(a[pool] - v))])
                reason += f"; closest {axis} = {fa(a[i])} at {other} = {fb(b[i])}"
            else:                       # nothing in the range: say so, and mark the curve's point nearest to it
                i = int(np.argmin(beyond))
                reason += (f"; the curve never reaches that range ({other} spans {fb(float(b.min()))} … "
                           f"{fb(float(b.max()))})")
            point = (float(x[i]), float(y[i]))
        return Check(False, reason, {"at": math.nan}, point)


class Envelope(Element):
    """Tolerance band around one or more reference curves, widened by ±dx and ±dy; every stored pair of
    the curve part must lie inside the band (edges included)."""

    kind = "envelope"
    keys = ("references", "dx", "dy")

    def __init__(self, cfg: Mapping[str, Any], fmt: Formatter | None = None) -> None:
        super().__init__(cfg, fmt)
        self.grid, self.lower, self.upper = envelope_band(
            [(np.asarray(r["x"]), np.asarray(r["y"])) for r in cfg["references"]], cfg["dx"], cfg["dy"])

    @classmethod
    def normalize(cls, cfg: Mapping[str, Any], xu: str, yu: str, where: str) -> dict[str, Any]:
        refs = cfg.get("references")
        if not isinstance(refs, (list, tuple)) or not refs:
            raise DigiForceError(f"{where}.references: expected a list of {{x: [...], y: [...]}} curves")
        out_refs = []
        for i, ref in enumerate(refs):
            w = f"{where}.references[{i}]"
            checks.known_keys(ref, ("x", "y", "x_unit", "y_unit"), w)
            rx, ry = (checks.quantities(ref, axis, si, w) for axis, si in (("x", xu), ("y", yu)))
            if rx.shape != ry.shape or rx.size < 2:
                raise DigiForceError(f"{w}: x and y must be equally long lists of at least 2 values")
            step = np.diff(rx)
            if np.all(step < 0):
                rx, ry = rx[::-1], ry[::-1]
            elif not np.all(step > 0):
                raise DigiForceError(f"{w}: x must be strictly monotonic (use the forward part of a curve)")
            out_refs.append({"x": rx.tolist(), "y": ry.tolist()})
        return {"references": out_refs, "dx": checks.number(cfg, "dx", xu, where, 0.0, minimum=0.0),
                "dy": checks.number(cfg, "dy", yu, where, 0.0, minimum=0.0)}

    def check(self, x: np.ndarray, y: np.ndarray) -> Check:
        lo = np.interp(x, self.grid, self.lower, left=np.nan, right=np.nan)
        hi = np.interp(x, self.grid, self.upper, left=np.nan, right=np.nan)
        bad = ~((y >= lo) & (y <= hi))
        if not bad.any():
            return Check(True)
        i = int(np.argmax(bad))
        at = (float(x[i]), float(y[i]))
        if np.isnan(lo[i]) or np.isnan(hi[i]):
            return Check(False, f"pair {i} at x = {self._x(x[i])} lies outside the envelope's X range", at=at)
        side = "above" if y[i] > hi[i] else "below"
        return Check(False, f"pair {i} at {self._pt(x[i], y[i])} lies {side} the envelope "
                            f"[{self._y(lo[i])}, {self._y(hi[i])}]", at=at)


def _window_extreme(values: np.ndarray, lo: np.ndarray, hi: np.ndarray, ufunc: np.ufunc, empty: float) -> np.ndarray:
    """``ufunc.reduce(values[lo:hi])`` for every pair (lo, hi); ``empty`` where lo >= hi."""
    out = np.full(lo.shape, empty)
    ok = lo < hi
    if ok.any():
        idx = np.stack([lo[ok], hi[ok]], axis=1).ravel()
        out[ok] = ufunc.reduceat(np.append(values, empty), idx)[::2]
    return out


def envelope_band(refs: list[tuple[np.ndarray, np.ndarray]], dx: float, dy: float
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Band (grid, lower, upper): at each X, the min/max of every reference over [X - dx, X + dx], -/+ dy.

    References are (x increasing, y). Between grid points the band is interpolated linearly; X where no
    reference reaches within dx get NaN (outside the band).
    """
    grid = np.unique(np.concatenate([np.concatenate([rx - dx, rx, rx + dx]) for rx, _ in refs]))
    upper = np.full(grid.shape, -np.inf)
    lower = np.full(grid.shape, np.inf)
    for rx, ry in refs:
        a, b = grid - dx, grid + dx
        reach = (b >= rx[0]) & (a <= rx[-1])
        i0, i1 = np.searchsorted(rx, a, "left"), np.searchsorted(rx, b, "right")
        ends = np.stack([np.interp(np.clip(a, rx[0], rx[-1]), rx, ry), np.interp(np.clip(b, rx[0], rx[-1]), rx, ry)])
        hi = np.maximum(_window_extreme(ry, i0, i1, np.maximum, -np.inf), ends.max(axis=0))
        lo = np.minimum(_window_extreme(ry, i0, i1, np.minimum, np.inf), ends.min(axis=0))
        upper = np.where(reach, np.maximum(upper, hi), upper)
        lower = np.where(reach, np.minimum(lower, lo), lower)
    covered = np.isfinite(upper)
    return grid, np.where(covered, lower - dy, np.nan), np.where(covered, upper + dy, np.nan)


ELEMENT_KINDS: dict[str, type[Element]] = {cls.kind: cls for cls in (Window, Trapezoid, Threshold, Envelope)}


def normalize_elements(items: Any, units: Mapping[str, str], where: str) -> list[dict[str, Any]]:
    """Validate a program's element list; names must be unique and free of dots."""
    if not isinstance(items, (list, tuple)):
        raise DigiForceError(f"{where}: expected a list of elements, got {type(items).__name__}")
    out, names = [], set()
    for i, cfg in enumerate(items):
        w = f"{where}[{i}]"
        if not isinstance(cfg, Mapping):
            raise DigiForceError(f"{w}: expected a table/dict, got {cfg!r}")
        kind = checks.choice(cfg, "kind", ELEMENT_KINDS, w)
        cls = ELEMENT_KINDS[kind]
        checks.known_keys(cfg, COMMON_KEYS + cls.keys, f"{w} ({kind})")
        name = checks.text(cfg, "name", w)
        w = f"{where}[{i}] ({kind} {name!r})"
        if "." in name or name in names:
            raise DigiForceError(f"{w}: element names must be unique and contain no '.'")
        names.add(name)
        channel = checks.choice(cfg, "channel", [c for c in units if c != "x"], w, "y")
        common = {"kind": kind, "name": name, "enabled": checks.flag(cfg, "enabled", w, True),
                  "part": checks.choice(cfg, "part", PARTS, w, "complete"), "channel": channel}
        out.append(common | cls.normalize(cfg, units["x"], units[channel], w))
    return out


def build_elements(configs: list[dict[str, Any]], fmt: Formatter | None = None) -> list[Element]:
    """Element objects for the enabled elements of a normalised list; ``fmt`` writes the numbers of their
    reasons (default: without units, see :func:`unit_format`)."""
    try:
        return [ELEMENT_KINDS[c["kind"]](c, fmt) for c in configs if c["enabled"]]
    except ValueError as exc:
        raise DigiForceError(f"elements: {exc}") from None
