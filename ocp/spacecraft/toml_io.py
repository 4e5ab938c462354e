"""Spacecraft TOML files: read (stdlib ``tomllib``) and write.

The schema (``docs/spacecraft.md``): angles in degrees (keys ending in
``_deg``, a human writes the file), SI units otherwise, wheels numbered
1..N. Every problem raises one `SpacecraftFileError` naming the file, the
key and what is wrong.
"""

from __future__ import annotations

import math
import os
from functools import partial
from pathlib import Path
from typing import Any

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib  # type: ignore[no-redef]

import numpy as np

from adcs_common.exceptions import AdcsError, InvalidValueError
from allocation import WheelArray
from thrusters import ThrusterSet, six_thruster_unit

from .definition import Spacecraft, SpacecraftFileError

__all__ = ["MAX_FILE_BYTES", "spacecraft_from_toml", "spacecraft_to_toml",
           "write_text"]

#: Largest spacecraft file read [bytes] (the catalogue's are ~1-2 kB;
#: 64 wheels written out take ~10 kB).
MAX_FILE_BYTES = 1 << 20

_TOP = {"name", "description", "inertia", "rate_max_deg", "wheels",
        "thrusters"}
_WHEEL_LAYOUTS = ("pyramid", "axes", "orthogonal_plus_skew",
                  "orthogonal_pairs")
_WHEELS = set(_WHEEL_LAYOUTS) | {"h_max", "m_max", "failed", "names"}
_THRUSTER_KINDS = ("six_thruster_unit", "custom")
#: ThrusterSet fields a file may set for either kind
_THRUSTER_COMMON = ("center_of_mass", "pressure", "correction",
                    "thrust_offset",
                    "min_on_time", "open_delay", "close_delay", "rise_time",
                    "tail_time", "isp", "names")
_THRUSTERS = {"six_thruster_unit": {"kind", "R", "L", "thrust",
                                    *_THRUSTER_COMMON},
              "custom": {"kind", "positions", "directions", "thrust",
                         "pairs", *_THRUSTER_COMMON}}


def _short(value: Any) -> str:
    """``repr(value)`` cut to 80 characters (a huge integer has no repr:
    Python refuses to print more than 4300 digits)."""
    if isinstance(value, int) and not isinstance(value, bool) and \
            value.bit_length() > 256:
        return f"an integer of {value.bit_length()} bits"
    text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


class _Reader:
    """Checks of one file's tables; every failure names source and key."""

    def __init__(self, source: str) -> None:
        self.source = source

    def fail(self, key: str, problem: str) -> SpacecraftFileError:
        return SpacecraftFileError(self.source, key, problem)

    def known(self, table: dict, allowed: set, where: str) -> None:
        unknown = sorted(set(table) - allowed)
        if unknown:
            raise self.fail(where, f"unknown key(s) {unknown}; allowed: "
                            f"{sorted(allowed)}")

    def number(self, value: Any, key: str) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail(key, f"must be a finite number, got "
                            f"{_short(value)}")
        try:
            out = float(value)        # an integer past 1e308 overflows
        except OverflowError:
            out = math.inf
        if not math.isfinite(out):
            raise self.fail(key, f"must be a finite number, got "
                            f"{_short(value)}")
        return out

    def numbers(self, value: Any, key: str, depth: int = 0) -> np.ndarray:
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            return np.array(self.number(value, key))
        if not isinstance(value, list) or not value:
            raise self.fail(key, f"must be a number or a list of numbers, "
                            f"got {_short(value)}")
        if depth >= 2:
            raise self.fail(key, "lists nest at most two deep (a matrix)")
        rows = [self.numbers(v, key, depth + 1) if isinstance(v, list)
                else self.number(v, key) for v in value]
        try:
            return np.array(rows, dtype=float)
        except ValueError:
            raise self.fail(key, "rows of unequal length") from None

    def build(self, key: str, make):
        """Call ``make()``; a toolbox error becomes one naming ``key``."""
        try:
            return make()
        except SpacecraftFileError:
            raise
        except (AdcsError, TypeError) as exc:
            raise self.fail(key, str(exc)) from None


def _wheels(r: _Reader, t: Any) -> WheelArray:
    if not isinstance(t, dict):
        raise r.fail("wheels", "must be a table ([wheels])")
    r.known(t, _WHEELS, "wheels")
    layouts = [k for k in _WHEEL_LAYOUTS if k in t]
    if len(layouts) != 1:
        raise r.fail("wheels", "give exactly one layout of "
                     f"{list(_WHEEL_LAYOUTS)}, got {layouts or 'none'}")
    layout = layouts[0]
    for k in ("h_max", "m_max"):
        if k not in t:
            raise r.fail(f"wheels.{k}", "missing (N·m·s for h_max, N·m "
                         "for m_max; one value or one per wheel)")
    h_max = r.numbers(t["h_max"], "wheels.h_max")
    m_max = r.numbers(t["m_max"], "wheels.m_max")
    spec = t[layout]
    key = f"wheels.{layout}"
    if layout == "axes":
        axes = r.numbers(spec, key)
        if axes.ndim != 2 or axes.shape[1] != 3:
            raise r.fail(key, "must be a list of [x, y, z] spin axes, got "
                         f"shape {axes.shape}")
        norms = np.linalg.norm(axes, axis=1)
        if np.any(norms < 1e-9 * max(norms.max(), 1e-300)) or \
                np.any(norms == 0):
            bad = [int(i) + 1 for i in np.flatnonzero(
                norms < 1e-9 * max(norms.max(), 1e-300))]
            raise r.fail(key, f"wheel(s) {bad} have a zero spin axis")
        make = partial(WheelArray.from_axes, axes.T, h_max=h_max,
                       m_max=m_max, normalize=True)
    else:
        if not isinstance(spec, dict):
            raise r.fail(key, "must be an inline table, e.g. "
                         "{ delta_deg = 55.0, gamma_deg = 45.0 }")
        if layout == "pyramid":
            r.known(spec, {"delta_deg", "gamma_deg"}, key)
            d = np.deg2rad(r.number(spec.get("delta_deg", 55.0),
                                    key + ".delta_deg"))
            g = np.deg2rad(r.number(spec.get("gamma_deg", 45.0),
                                    key + ".gamma_deg"))
            make = partial(WheelArray.pyramid, d, g, h_max=h_max,
                           m_max=m_max)
        elif layout == "orthogonal_plus_skew":
            r.known(spec, {"skew", "phi2_deg", "phi3_deg"}, key)
            kw = {"skew": spec.get("skew", "paper")}
            for k in ("phi2", "phi3"):
                if f"{k}_deg" in spec:
                    kw[k] = np.deg2rad(r.number(spec[f"{k}_deg"],
                                                f"{key}.{k}_deg"))
            make = partial(WheelArray.orthogonal_plus_skew, h_max=h_max,
                           m_max=m_max, **kw)
        else:
            r.known(spec, set(), key)
            make = partial(WheelArray.orthogonal_pairs, h_max=h_max,
                           m_max=m_max)
    arr = r.build("wheels", make)
    if "names" in t:
        names = t["names"]
        if not isinstance(names, list) or not all(isinstance(n, str)
                                                  for n in names):
            raise r.fail("wheels.names", "must be a list of strings")
        arr = r.build("wheels.names", partial(
            WheelArray, arr.axes, arr.h_max, arr.m_max, names=tuple(names)))
    failed = t.get("failed", [])
    if not isinstance(failed, list) or not all(
            isinstance(i, int) and not isinstance(i, bool) for i in failed):
        raise r.fail("wheels.failed", "must be a list of wheel numbers "
                     f"1..{arr.n_wheels}, got {failed!r}")
    bad = [i for i in failed if not 1 <= i <= arr.n_wheels]
    if bad:
        raise r.fail("wheels.failed", f"wheel number(s) {bad} out of range "
                     f"1..{arr.n_wheels} (wheels are numbered from 1)")
    return arr.with_failed(*[i - 1 for i in failed]) if failed else arr


def _thrusters(r: _Reader, t: Any) -> ThrusterSet:
    if not isinstance(t, dict):
        raise r.fail("thrusters", "must be a table ([thrusters])")
    kind = t.get("kind")
    if kind not in _THRUSTER_KINDS:
        raise r.fail("thrusters.kind", f"unknown thruster kind {kind!r}; "
                     f"choose from {list(_THRUSTER_KINDS)}")
    r.known(t, _THRUSTERS[kind], "thrusters")
    kw: dict[str, Any] = {}
    for k in _THRUSTER_COMMON:
        if k not in t:
            continue
        if k == "names":
            if not isinstance(t[k], list) or not all(
                    isinstance(n, str) for n in t[k]):
                raise r.fail("thrusters.names", "must be a list of strings")
            kw[k] = tuple(t[k])
        elif k in ("center_of_mass", "correction", "thrust_offset"):
            kw[k] = r.numbers(t[k], f"thrusters.{k}")
        else:
            kw[k] = r.number(t[k], f"thrusters.{k}")
    if "thrust" not in t:
        raise r.fail("thrusters.thrust", "missing (steady thrust [N], one "
                     "value or one per thruster)")
    thrust = r.numbers(t["thrust"], "thrusters.thrust")
    if kind == "six_thruster_unit":
        for k in ("R", "L"):
            if k not in t:
                raise r.fail(f"thrusters.{k}", "missing [m]")
        R, L = (r.number(t[k], f"thrusters.{k}") for k in ("R", "L"))
        return r.build("thrusters", partial(six_thruster_unit, R=R, L=L,
                                            thrust=thrust, **kw))
    pos = r.numbers(t.get("positions", []) or [[]], "thrusters.positions")
    dirs = r.numbers(t.get("directions", []) or [[]],
                     "thrusters.directions")
    if pos.ndim != 2 or pos.shape[1] != 3 or dirs.shape != pos.shape:
        raise r.fail("thrusters", "positions and directions must be lists "
                     "of [x, y, z], one per thruster, of equal length")
    n = pos.shape[0]
    pairs = t.get("pairs", [])
    if not isinstance(pairs, list) or not all(
            isinstance(p, list) and len(p) == 2 and all(
                isinstance(i, int) and 1 <= i <= n for i in p)
            for p in pairs):
        raise r.fail("thrusters.pairs", "must be a list of [i, j] thruster "
                     f"numbers 1..{n}")
    pressure = kw.pop("pressure", 9.0 * 98066.5)
    offset = kw.pop("thrust_offset", np.zeros(n))
    if offset.ndim == 0:
        offset = offset * np.ones(n)
    P = thrust * np.ones(n) if thrust.ndim == 0 else thrust
    if P.shape != (n,) or offset.shape != (n,):
        raise r.fail("thrusters.thrust" if P.shape != (n,) else
                     "thrusters.thrust_offset", f"must be one value or "
                     f"one per thruster ({n})")
    norms = np.linalg.norm(dirs, axis=1)
    if np.any(norms == 0):
        raise r.fail("thrusters.directions", "a zero direction")
    return r.build("thrusters", partial(
        ThrusterSet, positions=pos.T, directions=(dirs / norms[:, None]).T,
        pressure_slope=(P - offset) / pressure, thrust_offset=offset,
        pressure=pressure, pairs=tuple((i - 1, j - 1) for i, j in pairs),
        **kw))


def spacecraft_from_toml(text: str, source: str = "<string>") -> Spacecraft:
    """Build a `Spacecraft` from TOML text.

    Raises
    ------
    SpacecraftFileError
        Syntax error, missing or unknown key, or a value the toolbox
        rejects; the message names ``source`` and the key.
    """
    r = _Reader(source)
    if len(text) > MAX_FILE_BYTES:
        raise r.fail("", f"is {len(text)} characters long; a spacecraft "
                     f"file holds at most {MAX_FILE_BYTES} bytes")
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise r.fail("", f"not valid TOML: {exc}") from None
    except RecursionError:
        raise r.fail("", "not valid here: arrays or tables nested too "
                     "deeply") from None
    r.known(data, _TOP, "")
    for key in ("name", "inertia", "wheels"):
        if key not in data:
            raise r.fail(key, "missing")
    name = data["name"]
    if not isinstance(name, str) or not name.strip():
        raise r.fail("name", "must be a non-empty string")
    desc = data.get("description", "")
    if not isinstance(desc, str):
        raise r.fail("description", "must be a string")
    J = r.numbers(data["inertia"], "inertia")
    rate = data.get("rate_max_deg")
    rate = None if rate is None else np.deg2rad(r.number(rate,
                                                         "rate_max_deg"))
    wheels = _wheels(r, data["wheels"])
    thr = _thrusters(r, data["thrusters"]) if "thrusters" in data else None
    try:
        return Spacecraft(name, J, wheels, thr, rate, desc)
    except AdcsError as exc:
        key = "inertia" if "inertia" in str(exc) else (
            "rate_max_deg" if "rate_max" in str(exc) else "")
        raise r.fail(key, str(exc)) from None


# ------------------------------------------------------------------ writing
def _num(x: float | np.ndarray) -> str:
    return repr(float(x))


def _vec(v) -> str:
    v = np.asarray(v, dtype=float)
    if v.ndim == 0:
        return _num(v)
    return "[" + ", ".join(_vec(x) for x in v) + "]"


def _string(text: str) -> str:
    """Quote ``text`` as a TOML basic string that reads back the same.

    ``\\`` and ``"`` are escaped, and every control character (U+0000 to
    U+001F, U+007F, which TOML forbids raw) as ``\\uXXXX``; a lone
    surrogate (no Unicode scalar value, not writable as UTF-8) raises
    `InvalidValueError`.
    """
    out = []
    for ch in text:
        code = ord(ch)
        if ch in '"\\':
            out.append("\\" + ch)
        elif code < 0x20 or code == 0x7F:
            out.append(f"\\u{code:04X}")
        elif 0xD800 <= code <= 0xDFFF:
            raise InvalidValueError(
                f"cannot write {text!r}: it holds a lone surrogate "
                f"(U+{code:04X}), which no UTF-8 file can hold")
        else:
            out.append(ch)
    return '"' + "".join(out) + '"'


def _strings(names) -> str:
    return "[" + ", ".join(_string(n) for n in names) + "]"


def _same(v) -> str:
    v = np.asarray(v, dtype=float)
    return _num(v[0]) if np.all(v == v[0]) else _vec(v)


def spacecraft_to_toml(sc: Spacecraft) -> str:
    """TOML of ``sc``: its layouts with their parameters where they fit.

    The wheels as a layout (``pyramid = { delta_deg = 55.0, ... }``) and
    a six-thruster unit with its ``R`` and ``L`` when reading that back
    gives the same arrays exactly (`toml_layout`); otherwise the general
    form (axes, custom thrusters). Numbers are written with ``repr``, the
    thrust as the shortest decimals that give the same pressure slope,
    and the per-engine ``thrust_offset`` (eq. 1) when there is one:
    reading the text back gives the same craft to the last bit.
    """
    from .toml_layout import (degrees, six_unit_lines, thrust_levels,
                              wheel_layout)

    w = sc.wheels
    lines = [f"name = {_string(sc.name)}"]
    if sc.description:
        lines.append(f"description = {_string(sc.description)}")
    J = sc.inertia
    diagonal = np.array_equal(J, np.diag(np.diag(J)))
    lines.append(f"inertia = {_vec(np.diag(J) if diagonal else J)}   "
                 f"# kg·m²{', diagonal' if diagonal else ''}")
    if sc.rate_max is not None:
        lines.append(f"rate_max_deg = {_num(degrees(sc.rate_max))}")
    limits = [f"h_max = {_same(w.h_max)}   # N·m·s",
              f"m_max = {_same(w.m_max)}   # N·m"]
    if w.failed:
        limits.append(f"failed = [{', '.join(str(i + 1) for i in w.failed)}]")
    layout = wheel_layout(w, limits)
    lines += ["", "[wheels]"] + (layout or [
        f"axes = {_vec(w.axes.T)}", *limits,
        f"names = {_strings(w.names)}"])
    t = sc.thrusters
    unit = None if t is None else six_unit_lines(t)
    if unit is not None:
        lines += ["", "[thrusters]", *unit]
    elif t is not None:
        lines += ["", "[thrusters]", 'kind = "custom"',
                  f"positions = {_vec(t.positions.T)}   # m",
                  f"directions = {_vec(t.directions.T)}",
                  f"thrust = {_same(thrust_levels(t))}   # N",
                  f"pressure = {_num(t.pressure)}   # Pa",
                  f"center_of_mass = {_vec(t.center_of_mass)}",
                  f"correction = {_vec(t.correction)}",
                  f"names = {_strings(t.names)}"]
        for k in ("min_on_time", "open_delay", "close_delay", "rise_time",
                  "tail_time", "isp"):
            lines.append(f"{k} = {_num(getattr(t, k))}")
        if np.any(t.thrust_offset != 0):
            lines.append(f"thrust_offset = {_same(t.thrust_offset)}   # N")
        if t.pairs:
            lines.append("pairs = [" + ", ".join(
                f"[{i + 1}, {j + 1}]" for i, j in t.pairs) + "]")
    return "\n".join(lines) + "\n"


def write_text(path, text: str) -> Path:
    """Write ``text`` to ``path``; a toolbox error if it cannot."""
    p = Path(path)
    if p.is_dir():
        raise SpacecraftFileError(str(p), "", "is a folder, not a file")
    if not p.parent.is_dir():
        raise SpacecraftFileError(str(p), "", "its folder does not exist")
    if not os.access(p.parent, os.W_OK):
        raise SpacecraftFileError(str(p), "", "its folder is not writable")
    try:
        p.write_text(text, encoding="utf-8")
    except OSError as exc:
        raise SpacecraftFileError(str(p), "", f"cannot be written "
                                  f"({exc.strerror or exc})") from None
    return p
