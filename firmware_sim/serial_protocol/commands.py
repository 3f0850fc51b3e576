"""The command set of the serial protocol (docs/serial-protocol.md, section 4) executed on a DigiForce.

``Commands.execute(command, data)`` returns the response data field: a 2-digit status followed by
the payload (status ``00``) or an error message. JSON payloads are strict RFC 8259: a non-finite number
travels as ``null``, listed in the payload's ``non_finite`` object (JSON Pointer → ``"NaN"``,
``"Infinity"`` or ``"-Infinity"``).
"""
from __future__ import annotations

import base64
import json
import math
import re
import threading
from typing import Any, Callable

import numpy as np

from firmware_sim.digiforce.description import CHANNELS
from firmware_sim.serial_protocol.framing import MAX_DATA

OK, UNKNOWN, SYNTAX, REJECTED, NO_DATA, STATE, INTERNAL = 0, 1, 2, 3, 4, 5, 9
BLOCK_PAIRS = 128          # value pairs per curve block (CB); CT blocks hold as many times
MAX_MESSAGE = 200          # characters of an error message
MAX_DEPTH = 8              # JSON nesting a request may carry (a program nests at most 6: PG of a program with every feature)


class CommandError(Exception):
    """A request the device answers with status ``code``."""

    def __init__(self, code: int, message: str) -> None:
        super().__init__(message)
        self.code = code


def _finite(obj: Any, pointer: str, found: dict[str, str]) -> Any:
    """``obj`` as plain JSON values with every non-finite float replaced by None and recorded in ``found``
    under its JSON Pointer (RFC 6901)."""
    if hasattr(obj, "tolist"):                # numpy arrays and scalars
        obj = obj.tolist()
    if isinstance(obj, dict):
        return {str(k): _finite(v, f"{pointer}/{str(k).replace('~', '~0').replace('/', '~1')}", found)
                for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite(v, f"{pointer}/{i}", found) for i, v in enumerate(obj)]
    if isinstance(obj, float) and not math.isfinite(obj):
        found[pointer] = "NaN" if math.isnan(obj) else "Infinity" if obj > 0 else "-Infinity"
        return None
    return obj


def _json(obj: dict[str, Any]) -> str:
    """Compact, ASCII-only, strict JSON of a payload object; non-finite numbers become null, listed in
    ``non_finite`` (present only when there are any)."""
    found: dict[str, str] = {}
    clean = _finite(obj, "", found)
    if found:
        clean["non_finite"] = found
    try:
        return json.dumps(clean, separators=(",", ":"), ensure_ascii=True, allow_nan=False)
    except TypeError as e:                    # a device value JSON cannot carry: the device's fault
        raise CommandError(INTERNAL, f"payload is not JSON-serialisable: {e}") from None


def _int(text: str, what: str) -> int:
    """A decimal integer as the protocol writes it: digits, an optional minus, nothing else (Python's int() also
    takes spaces, '+' and '_')."""
    if not re.fullmatch(r"-?[0-9]+", text):
        raise CommandError(SYNTAX, f"{what} must be a decimal integer, got {text!r}")
    return int(text, 10)


def _bare(command: str, run: Callable[[], Any]) -> Callable[[str], Any]:
    """The handler of a command that takes no request data: some is refused (``02``), not ignored."""
    def handler(data: str) -> Any:
        if data:
            raise CommandError(SYNTAX, f"{command} takes no request data, got {_printable(data[:40])!r}")
        return run()
    return handler


def _not_json(token: str) -> Any:
    raise ValueError(f"{token} is not a JSON number (strict RFC 8259: no NaN or Infinity)")


def _unique_keys(pairs: list[tuple[str, Any]]) -> dict:
    """A JSON object whose keys are unique: RFC 8259 leaves duplicates to the reader, and a last-wins reader would
    silently drop the first value of a key the host sent twice."""
    out: dict = {}
    for key, value in pairs:
        if key in out:
            raise ValueError(f"the key {key!r} appears twice in one object")
        out[key] = value
    return out


def _depth(value: Any) -> int:
    """Nesting depth of parsed JSON (a scalar 0, ``{}`` 1, ``{"a": []}`` 2), without recursion."""
    deepest, stack = 0, [(value, 0)]
    while stack:
        item, level = stack.pop()
        if isinstance(item, (dict, list)):
            level += 1
            deepest = max(deepest, level)
            stack.extend((v, level) for v in (item.values() if isinstance(item, dict) else item))
    return deepest


def _finite_float(text: str) -> float:
    """A JSON number as a float; one beyond the float range (1e999) would be infinity: refused as NaN/Infinity are."""
    value = float(text)
    if not math.isfinite(value):
        raise ValueError(f"{text} is beyond the float range (it would be read as infinity: no NaN or Infinity)")
    return value


def _printable(text: str) -> str:
    clean = "".join(c if c.isascii() and c.isprintable() else "?" for c in text)
    return clean[:MAX_MESSAGE]


def _b64(values: np.ndarray) -> str:
    return base64.b64encode(np.ascontiguousarray(values, dtype="<f8").tobytes()).decode("ascii")


class Commands:
    """Dispatch requests to ``device`` (a DigiForce) under ``lock``; ``clock()`` gives the start/stop
    times (s) handed to the device, ``None`` = "now" for the device (its next / latest sample)."""

    def __init__(self, device: Any, clock: Callable[[], float] | None, lock: threading.Lock) -> None:
        self._device, self._lock = device, lock
        self._clock = clock or (lambda: None)
        self._latched: dict[str, np.ndarray] = {}
        # handlers return the payload; commands without one return whatever the device method returns
        self._table: dict[str, Callable[[str], Any]] = {
            "ID": _bare("ID", lambda: _printable(str(self._device.identify()))),
            "PS": self._select, "PG": self._get_program, "PW": self._set_program,
            "ST": _bare("ST", lambda: self._device.start(self._clock())),
            "SP": _bare("SP", lambda: self._device.stop(self._clock())),
            "TA": self._tare, "CH": _bare("CH", self._latch),
            "CB": lambda d: self._block(d, "xy"), "CT": lambda d: self._block(d, "t"),
            "CY": lambda d: self._block(d, "y2"),
            "RR": _bare("RR", self._result),
            "RS": lambda d: _json(self._device.statistics(self._program(d))),
            "RZ": lambda d: self._device.reset_statistics(self._program(d)),
            "SS": _bare("SS", lambda: _json(self._device.status())),
        }

    def execute(self, command: str, data: str) -> str:
        """Response data field for one request: ``"00" + payload`` or ``"NN" + error message``."""
        handler = self._table.get(command)
        try:
            if handler is None:
                raise CommandError(UNKNOWN, f"unknown command {command!r}")
            with self._lock:
                payload = handler(data)
            payload = payload if isinstance(payload, str) else ""
            if len(payload) > MAX_DATA - 2:
                raise CommandError(INTERNAL, f"{command} response of {len(payload)} bytes exceeds the frame limit")
            return f"{OK:02d}{payload}"
        except CommandError as e:
            code, message = e.code, str(e)
        except (ValueError, KeyError, IndexError, TypeError) as e:
            code, message = REJECTED, f"{type(e).__name__}: {e}"
        except RecursionError as e:             # a RuntimeError, but the unit's fault, not a state: internal
            code, message = INTERNAL, f"{type(e).__name__}: {e}"
        except RuntimeError as e:
            code, message = STATE, str(e)
        except Exception as e:  # the device must answer, never die: report the fault to the host
            code, message = INTERNAL, f"{type(e).__name__}: {e}"
        return f"{code:02d}{_printable(message)}"

    def _program(self, data: str) -> int:
        return _int(data, "program number") if data else int(self._device.active_program)

    def _select(self, data: str) -> str:
        if data:
            self._device.select_program(_int(data, "program number"))
        return f"{int(self._device.active_program)},{int(self._device.n_programs)}"

    def _get_program(self, data: str) -> str:
        return _json(self._device.get_program(self._program(data)))

    def _set_program(self, data: str) -> None:
        number, sep, text = data.partition(",")
        if not sep:
            raise CommandError(SYNTAX, "PW data must be '<program>,<JSON object>'")
        try:
            config = json.loads(text, parse_constant=_not_json, parse_float=_finite_float, object_pairs_hook=_unique_keys)
            depth = _depth(config)
        except ValueError as e:                  # JSONDecodeError, a NaN/Infinity token or a repeated key
            raise CommandError(SYNTAX, f"PW configuration is not valid JSON: {e}") from None
        except RecursionError:                   # nested deeper than the parser's stack
            depth = math.inf
        if depth > MAX_DEPTH:                    # the merge and checks would recurse past the stack
            raise CommandError(SYNTAX, f"PW configuration is not valid JSON: nested too deeply (more than "
                                       f"{MAX_DEPTH} levels; a program nests at most 6)")
        if not isinstance(config, dict):
            raise CommandError(SYNTAX, f"PW configuration must be a JSON object, got {type(config).__name__}")
        self._device.set_program(self._program(number), config, fits=_readable)   # empty: the active one

    def _tare(self, data: str) -> None:
        if data and data not in CHANNELS:         # not a channel name: malformed data (02), not a value out of range
            raise CommandError(SYNTAX, f"TA takes a channel name ({', '.join(CHANNELS)}) or nothing, got {data[:40]!r}")
        self._device.tare(data or None)

    def _latch(self) -> str:
        curve = self._device.last_curve
        if curve is None:
            raise CommandError(NO_DATA, "no curve recorded yet")
        t, x, y = (np.array(a, dtype=float) for a in (curve.t, curve.x, curve.y))
        y2 = None if curve.y2 is None else np.array(curve.y2, dtype=float)
        if not len(t) == len(x) == len(y) == (len(t) if y2 is None else len(y2)):
            raise CommandError(INTERNAL, f"curve arrays differ in length: t {len(t)}, x {len(x)}, y {len(y)}")
        self._latched = {"t": t, "xy": np.column_stack([x, y]), "y2": y2}
        return _json({"n": len(t), "block_pairs": BLOCK_PAIRS, "n_blocks": -(-len(t) // BLOCK_PAIRS),
                      "y2": y2 is not None, "turning_index": curve.turning_index, "x_reference": curve.x_reference,
                      "sampling": curve.sampling, **curve.flags})

    def _block(self, data: str, name: str) -> str:
        if not self._latched:
            raise CommandError(NO_DATA, "no curve latched: send CH first")
        values = self._latched[name]
        if values is None:
            raise CommandError(NO_DATA, "the latched curve has no y2 channel")
        n_blocks = -(-len(values) // BLOCK_PAIRS)
        i = _int(data, "block index")
        if not 0 <= i < n_blocks:
            raise CommandError(REJECTED, f"block index {i} outside 0..{n_blocks - 1}")
        block = values[i * BLOCK_PAIRS:(i + 1) * BLOCK_PAIRS]
        return f"{i},{n_blocks},{len(block)},{_b64(block)}"

    def _result(self) -> str:
        result = self._device.last_result
        if result is None:
            raise CommandError(NO_DATA, "no result yet")
        return _json(result.to_dict(include_curve=False))     # the curve itself: CH/CB/CT


def _readable(program: dict[str, Any]) -> str | None:
    """Why ``PG`` could not return ``program`` (its JSON beyond a response's data field), else None: ``PW`` refuses
    it then."""
    size = len(_json(program))
    return (f"the program's JSON would be {size} bytes, more than a PG response carries ({MAX_DATA - 2}): PG could "
            f"not read it back") if size > MAX_DATA - 2 else None
