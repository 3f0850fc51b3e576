"""Evaluation elements: graphical criteria, each a pass/fail with a reason and its process values.

Elements are data: a dict with ``kind`` (a key of :data:`ELEMENT_KINDS`), ``name``, ``enabled``,
``part`` (forward / return / complete), ``channel`` (y or y2) and kind-specific keys. The registry
turns them into element objects whose ``evaluate(x, y)`` is vectorised over the curve part.
Edge semantics (closed regions, touching, corners, wrong side) are documented in docs/digiforce.md.
"""
from __future__ import annotations

import math
from typing import Any, ClassVar, Mapping

import numpy as np

from . import checks
from .errors import DigiForceError
from .geometry import SIDES, ConvexQuad

PARTS = ("forward", "return", "complete")
SIDE_RULES = SIDES + ("any", "none", "ignore")
EXTREMES = ("x_max", "x_min", "y_max", "y_min")
COMMON_KEYS = ("kind", "name", "enabled", "part", "channel")
Verdict = tuple[bool, str, dict[str, float]]


class Element:
    """Base of all elements: holds the normalised config; subclasses implement ``evaluate``."""

    kind: ClassVar[str]
    keys: ClassVar[tuple[str, ...]]
    values: ClassVar[tuple[str, ...]] = ()

    def __init__(self, cfg: Mapping[str, Any]) -> None:
        self.cfg = cfg
        self.name: str = cfg["name"]
        self.part: str = cfg["part"]
        self.channel: str = cfg["channel"]

    @classmethod
    def normalize(cls, cfg: Mapping[str, Any], xu: str, yu: str, where: str) -> dict[str, Any]:
        raise NotImplementedError

    def evaluate(self, x: np.ndarray, y: np.ndarray) -> Verdict:
        raise NotImplementedError


def _side_reason(rule: str, entering: bool, inside_at_end: bool, sides: np.ndarray) -> str | None:
    """Why the entry (``entering``) or exit violates ``rule``; None if it complies."""
    verb, end, n = ("enters", "starts", len(sides)) if entering else ("leaves", "ends", len(sides))
    if rule == "ignore":
        return None
    if rule == "none":
        if not inside_at_end:
            return f"curve must {end[:-1]} inside the window but {end} outside"
        return None if n == 0 else f"curve {verb} the window although it must {end[:-1]} inside"
    if inside_at_end:
        return f"curve {end} inside the window; it must {verb[:-1]} through {rule}"
    if n == 0:
        return f"curve never {verb} the window"
    if n > 1:
        return f"curve {verb} the window {n} times (exactly once allowed)"
    if rule != "any" and not sides[0][SIDES.index(rule)]:
        through = "/".join(s for s, hit in zip(SIDES, sides[0]) if hit)
        return f"curve {verb} through the {through} side, not through {rule}"
    return None


class _Region(Element):
    """Shared evaluation of windows and trapezoids: entry/exit sides, optional extreme-in-region check."""

    values = ("x_entry", "y_entry", "x_exit", "y_exit")
    region: ConvexQuad

    def evaluate(self, x: np.ndarray, y: np.ndarray) -> Verdict:
        c = self.region.crossings(x, y)
        nan = math.nan
        vals = {"x_entry": float(c.entry_points[0, 0]) if len(c.entry_points) else nan,
                "y_entry": float(c.entry_points[0, 1]) if len(c.entry_points) else nan,
                "x_exit": float(c.exit_points[-1, 0]) if len(c.exit_points) else nan,
                "y_exit": float(c.exit_points[-1, 1]) if len(c.exit_points) else nan}
        entry, exit_, check = self.cfg["entry"], self.cfg["exit"], self.cfg.get("check")
        reason = (_side_reason(entry, True, c.starts_inside, c.entry_sides)
                  or _side_reason(exit_, False, c.ends_inside, c.exit_sides))
        if reason is None and check is not None:
            axis = x if check[0] == "x" else y
            i = int(np.argmax(axis) if check.endswith("max") else np.argmin(axis))
            if not self.region.contains(x[i], y[i])[0]:
                reason = f"{check} at (x={x[i]:.6g}, y={y[i]:.6g}) lies outside the {self.kind}"
        if reason is None and entry == exit_ == "ignore" and check is None and not c.touched:
            reason = f"curve does not pass through the {self.kind}"
        return reason is None, reason or "", vals


class Window(_Region):
    """Rectangle [x_min, x_max] x [y_min, y_max]; entry/exit side rules; optional extreme check."""

    kind = "window"
    keys = ("x_min", "x_max", "y_min", "y_max", "entry", "exit", "check")

    def __init__(self, cfg: Mapping[str, Any]) -> None:
        super().__init__(cfg)
        x0, x1, y0, y1 = cfg["x_min"], cfg["x_max"], cfg["y_min"], cfg["y_max"]
        self.region = ConvexQuad([(x0, y0), (x1, y0), (x1, y1), (x0, y1)])

    @classmethod
    def normalize(cls, cfg: Mapping[str, Any], xu: str, yu: str, where: str) -> dict[str, Any]:
        out = {k: checks.number(cfg, k, xu if k[0] == "x" else yu, where) for k in cls.keys[:4]}
        for lo, hi in (("x_min", "x_max"), ("y_min", "y_max")):
            if not out[lo] < out[hi]:
                raise DigiForceError(f"{where}: {lo} ({out[lo]:g}) must be below {hi} ({out[hi]:g})")
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

    def __init__(self, cfg: Mapping[str, Any]) -> None:
        super().__init__(cfg)
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
            raise DigiForceError(f"{where}: start ({out['start']:g}) must be below end ({out['end']:g})")
        out["lower"] = [checks.quantity(v, lim_u, f"{where}.lower") for v in _list2(cfg, "lower", where)]
        out["upper"] = [checks.quantity(v, lim_u, f"{where}.upper") for v in _list2(cfg, "upper", where)]
        if not (out["lower"][0] < out["upper"][0] and out["lower"][1] < out["upper"][1]):
            raise DigiForceError(f"{where}: lower {out['lower']} must be below upper {out['upper']} at both ends")
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
            raise DigiForceError(f"{where}.range: low {lo:g} above high {hi:g}")
        return {"axis": axis, "value": checks.number(cfg, "value", xu if axis == "x" else yu, where),
                "direction": checks.choice(cfg, "direction", ("rising", "falling", "any"), where, "rising"),
                "range": [lo, hi]}

    def evaluate(self, x: np.ndarray, y: np.ndarray) -> Verdict:
        a, b = (y, x) if self.cfg["axis"] == "y" else (x, y)
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
            return True, "", {"at": float(at[ok][0])}
        other = "x" if self.cfg["axis"] == "y" else "y"
        where = "" if (lo, hi) == (None, None) else f" with {other} in [{lo}, {hi}]"
        found = f"; crossings at {np.round(at, 9).tolist()[:3]} are outside the range" if len(at) else ""
        return False, f"curve never crosses {self.cfg['axis']} = {v:g} {direction}{where}{found}", {"at": math.nan}


class Envelope(Element):
    """Tolerance band around one or more reference curves, widened by ±dx and ±dy; every stored pair of
    the curve part must lie inside the band (edges included)."""

    kind = "envelope"
    keys = ("references", "dx", "dy")

    def __init__(self, cfg: Mapping[str, Any]) -> None:
        super().__init__(cfg)
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
            checks.known_keys(ref, ("x", "y"), w)
            try:
                rx, ry = np.asarray(ref.get("x"), dtype=float), np.asarray(ref.get("y"), dtype=float)
            except (TypeError, ValueError):
                raise DigiForceError(f"{w}: x and y must be lists of numbers (SI)") from None
            if rx.ndim != 1 or rx.shape != ry.shape or rx.size < 2 or not np.all(np.isfinite(rx) & np.isfinite(ry)):
                raise DigiForceError(f"{w}: x and y must be equally long finite lists of at least 2 numbers")
            step = np.diff(rx)
            if np.all(step < 0):
                rx, ry = rx[::-1], ry[::-1]
            elif not np.all(step > 0):
                raise DigiForceError(f"{w}: x must be strictly monotonic (use the forward part of a curve)")
            out_refs.append({"x": rx.tolist(), "y": ry.tolist()})
        return {"references": out_refs, "dx": checks.number(cfg, "dx", xu, where, 0.0, minimum=0.0),
                "dy": checks.number(cfg, "dy", yu, where, 0.0, minimum=0.0)}

    def evaluate(self, x: np.ndarray, y: np.ndarray) -> Verdict:
        lo = np.interp(x, self.grid, self.lower, left=np.nan, right=np.nan)
        hi = np.interp(x, self.grid, self.upper, left=np.nan, right=np.nan)
        bad = ~((y >= lo) & (y <= hi))
        if not bad.any():
            return True, "", {}
        i = int(np.argmax(bad))
        if np.isnan(lo[i]) or np.isnan(hi[i]):
            return False, f"pair {i} (x={x[i]:.6g}) lies outside the envelope's X range", {}
        side = "above" if y[i] > hi[i] else "below"
        return False, f"pair {i} (x={x[i]:.6g}, y={y[i]:.6g}) lies {side} the envelope [{lo[i]:.6g}, {hi[i]:.6g}]", {}


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


def build_elements(configs: list[dict[str, Any]]) -> list[Element]:
    """Element objects for the enabled elements of a normalised list."""
    try:
        return [ELEMENT_KINDS[c["kind"]](c) for c in configs if c["enabled"]]
    except ValueError as exc:
        raise DigiForceError(f"elements: {exc}") from None
