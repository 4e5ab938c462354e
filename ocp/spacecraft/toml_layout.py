"""Write a craft's layout as the user wrote it, not as expanded numbers.

`Spacecraft.save` writes the wheels as a layout with its parameters
(``pyramid = { delta_deg = 55.0, gamma_deg = 45.0 }``,
``orthogonal_plus_skew``, ``orthogonal_pairs``) and a six-thruster unit
as ``kind = "six_thruster_unit"`` with its ``R`` and ``L``, whenever
reading that text back gives the same arrays to the last bit; otherwise
the general form (axes, custom thrusters). Angles are written in the
shortest decimal degrees that give the same radians.
"""

from __future__ import annotations

from dataclasses import fields
from typing import Any

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib  # type: ignore[no-redef]

import numpy as np

from allocation import WheelArray
from allocation.arrays import PYRAMID_SIGN_Y, PYRAMID_SIGN_Z
from thrusters import ThrusterSet

__all__ = ["degrees", "six_unit_lines", "thrust_levels", "wheel_layout"]


def _num(x: float) -> str:
    return repr(float(x))


def degrees(rad: float, ulps: int = 0) -> float:
    """Shortest decimal degrees whose ``np.deg2rad`` is ``rad``.

    Within ``ulps`` units in the last place of ``rad`` (0: exactly); the
    full ``np.rad2deg(rad)`` when no shorter decimal does.
    """
    deg = float(np.rad2deg(rad))
    tol = ulps * float(np.spacing(abs(rad)))
    for digits in range(1, 18):
        cand = float(f"{deg:.{digits}g}")
        if abs(float(np.deg2rad(cand)) - rad) <= tol:
            return cand
    return deg


def thrust_levels(t: ThrusterSet) -> np.ndarray:
    """Steady thrusts [N] to write, one per engine, that read back exactly.

    A file gives the steady thrust ``P`` at ``pressure`` and the offset
    ``b`` (eq. 1); reading gives the slope ``a = (P - b) / pressure``. For
    each engine this is the shortest decimal ``P`` whose slope is ``a`` to
    the last bit (0.5 where the user wrote 0.5, not ``a p + b`` =
    0.5000000000000001), searched within 4 ulps of ``a p + b``; ``a p +
    b`` itself when none does.
    """
    a, b, p = t.pressure_slope, t.thrust_offset, t.pressure
    steady = t.steady_thrust
    out = steady.copy()
    for i, P in enumerate(steady):
        # a p + b lies within an ulp or two of the P that gave a
        near = [P]
        for _ in range(4):
            near = [np.nextafter(near[0], -np.inf), *near,
                    np.nextafter(near[-1], np.inf)]
        found = next((c for digits in range(1, 18) for c in
                      (float(f"{x:.{digits}g}") for x in near)
                      if (c - b[i]) / p == a[i]), None)
        if found is not None:
            out[i] = found
    return out


def _read_wheels(text: str) -> WheelArray | None:
    from .toml_io import _Reader, _wheels

    try:
        return _wheels(_Reader("<save>"), tomllib.loads(text)["wheels"])
    except Exception:   # a candidate that does not read back: not used
        return None


def _same_wheels(a: WheelArray | None, b: WheelArray) -> bool:
    return a is not None and all(np.array_equal(getattr(a, k),
                                                getattr(b, k))
                                 for k in ("axes", "h_max", "m_max",
                                           "scale")) \
        and a.failed == b.failed


def _pyramid(w: WheelArray) -> list[str]:
    """Pyramid candidates: (δ, γ) recovered from wheel 1's axis."""
    if w.n_wheels != 4:
        return []
    a = w.axes[:, 0]
    d = float(np.arccos(np.clip(a[2] / PYRAMID_SIGN_Z[0], -1, 1)))
    g = float(np.arctan2(a[1] / PYRAMID_SIGN_Y[0], -a[0]))
    out = []
    for ulps in (4, 0):
        out.append(f"pyramid = {{ delta_deg = {_num(degrees(d, ulps))}, "
                   f"gamma_deg = {_num(degrees(g, ulps))} }}")
    return out


def _skew(w: WheelArray) -> list[str]:
    """Orthogonal-plus-skew candidates (the paper's angles or equal)."""
    if w.n_wheels != 4 or not np.array_equal(w.axes[:, :3], np.eye(3)):
        return []
    h = w.axes[:, 3]
    p2 = float(np.arcsin(np.clip(-h[2], -1, 1)))
    p3 = float(np.arctan2(h[1], h[0]))
    return ['orthogonal_plus_skew = { skew = "equal_angle" }'] + [
        f'orthogonal_plus_skew = {{ skew = "paper", phi2_deg = '
        f"{_num(degrees(p2, u))}, phi3_deg = {_num(degrees(p3, u))} }}"
        for u in (4, 0)]


def wheel_layout(w: WheelArray, limits: list[str]) -> list[str] | None:
    """``[wheels]`` lines with a layout that reads back as ``w``.

    ``limits``: the h_max, m_max and failed lines (kept as given). The
    names are written only where they differ from the layout's own.
    None when no layout gives ``w`` exactly.
    """
    cands = _pyramid(w) + _skew(w)
    if w.n_wheels == 6:
        cands.append("orthogonal_pairs = {}")
    for line in cands:
        lines = [line, *limits]
        back = _read_wheels("[wheels]\n" + "\n".join(lines))
        if _same_wheels(back, w):
            if back is not None and back.names != w.names:
                from .toml_io import _strings

                lines.append(f"names = {_strings(w.names)}")
            return lines
    return None


def _same_set(a: ThrusterSet | None, b: ThrusterSet) -> bool:
    if a is None:
        return False
    for f in fields(ThrusterSet):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if isinstance(x, np.ndarray) or isinstance(y, np.ndarray):
            if not np.array_equal(np.asarray(x), np.asarray(y)):
                return False
        elif x != y:
            return False
    return True


def _read_set(lines: list[str]) -> ThrusterSet | None:
    from .toml_io import _Reader, _thrusters

    try:
        return _thrusters(_Reader("<save>"), tomllib.loads(
            "[thrusters]\n" + "\n".join(lines))["thrusters"])
    except Exception:   # a candidate that does not read back: not used
        return None


def six_unit_lines(t: ThrusterSet) -> list[str] | None:
    """``[thrusters]`` lines of a six-thruster unit with its R and L.

    Only the fields that differ from what ``R``, ``L`` and ``thrust``
    give are written (``thrust_offset`` when an engine has one, so that
    ``thrust`` stays the steady thrust the user wrote). None when ``t``
    is not such a unit exactly.
    """
    from .toml_io import _same, _strings, _vec

    if t.n != 6:
        return None
    R = float(np.hypot(t.positions[0, 0], t.positions[2, 0]))
    L = float(t.positions[1, 3])
    lines = ['kind = "six_thruster_unit"', f"R = {_num(R)}   # m",
             f"L = {_num(L)}   # m",
             f"thrust = {_same(thrust_levels(t))}   # N"]
    base = _read_set(lines)
    if base is None:
        return None
    extra: dict[str, Any] = {
        "thrust_offset": f"{_same(t.thrust_offset)}   # N",
        "pressure": _num(t.pressure),
        "center_of_mass": _vec(t.center_of_mass),
        "correction": _same(t.correction),
        "names": _strings(t.names)}
    for k in ("min_on_time", "open_delay", "close_delay", "rise_time",
              "tail_time", "isp"):
        extra[k] = _num(getattr(t, k))
    for k, text in extra.items():
        if not np.array_equal(np.asarray(getattr(base, k)),
                              np.asarray(getattr(t, k))):
            lines.append(f"{k} = {text}")
    return lines if _same_set(_read_set(lines), t) else None
