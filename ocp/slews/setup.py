"""A slew problem checked and set up: target, limits, cones, guesses."""

from __future__ import annotations

from dataclasses import dataclass
import numpy as np
from numpy.typing import ArrayLike
from adcs_common.exceptions import (
    InvalidValueError,
)
from adcs_common.validation import as_finite_scalar, as_vector
from allocation import min_norm_gains
from ocp.spacecraft.definition import slew_parts
from adcs_common.quaternion import (
    quat_mul,
    quat_to_dcm,
    rotation_between,
)
from ocp.guidance import _unit_quat, eigenaxis_slew
from ocp.models.rigid import (
    SpacecraftModel,
    check_inertia,
    rigid_spacecraft,
)
from .transcription import TRANSCRIPTIONS


@dataclass(frozen=True)
class KeepOut:
    """A keep-out cone: a body axis must stay away from a fixed direction.

    The boresight ``b`` (body frame, e.g. a star tracker's or a
    telescope's) keeps an angle of at least ``half_angle`` from the
    direction ``s`` (reference frame, e.g. the Sun):
    :math:`s^T R(q)\\, b \\le \\cos(\\text{half\\_angle})`, with R(q)
    body to reference. The slews impose it at every node of the grid and
    check the continuous path (`ocp.slews.keepout`): a path entering the
    cone between nodes is solved again with the cone widened at the
    nodes; ``extras["keep_out_path_margin"]`` is the path's smallest
    margin [rad], >= 0 on every successful slew.

    Attributes
    ----------
    boresight : array_like (3,)
        Body axis (normalised here, stored as a tuple of 3 float).
    direction : array_like (3,)
        Reference-frame direction to avoid (normalised here, stored as a
        tuple of 3 float).
    half_angle : float
        Cone half-angle [rad], in (0, π).
    """

    boresight: ArrayLike       # a tuple of 3 float after __post_init__
    direction: ArrayLike
    half_angle: float

    def __post_init__(self) -> None:
        """Normalise the axes and check the angle."""
        for name in ("boresight", "direction"):
            v = as_vector(getattr(self, name), 3, name)
            n = np.linalg.norm(v)
            if n < 1e-12:
                raise InvalidValueError(f"{name} must be a non-zero vector")
            object.__setattr__(self, name, tuple(v / n))
        a = as_finite_scalar(self.half_angle, "half_angle")
        if not 0.0 < a < np.pi:
            raise InvalidValueError(
                f"half_angle must lie in (0, π) rad, got {a}")
        object.__setattr__(self, "half_angle", a)

    def margin(self, q: ArrayLike) -> float | np.ndarray:
        """Angle of the boresight from the direction minus the half-angle.

        ``q`` (4,) or (K, 4) scalar-first; returns radians, (K,) or a
        float; negative inside the cone.
        """
        q = np.atleast_2d(np.asarray(q, dtype=float))
        b, d = np.array(self.boresight), np.array(self.direction)
        c = np.array([d @ quat_to_dcm(qk / np.linalg.norm(qk)) @ b
                      for qk in q])
        out = np.arccos(np.clip(c, -1.0, 1.0)) - self.half_angle
        return out if out.size > 1 else float(out[0])


def keep_outs(keep_out, q0, qf) -> tuple[KeepOut, ...]:
    """Check the cones; the end attitudes must lie outside them."""
    if keep_out is None:
        return ()
    if isinstance(keep_out, KeepOut):
        keep_out = (keep_out,)
    out = tuple(keep_out)
    for i, k in enumerate(out):
        if not isinstance(k, KeepOut):
            raise InvalidValueError(
                f"keep_out[{i}] must be a KeepOut, got {type(k).__name__}")
        for name, q in (("q0", q0), ("qf", qf)):
            if k.margin(q) < 0:
                raise InvalidValueError(
                    f"{name} lies inside keep_out[{i}] (boresight "
                    f"{np.rad2deg(k.margin(q) + k.half_angle):.2f}° from the "
                    f"direction, cone {np.rad2deg(k.half_angle):.2f}°)")
    return out


@dataclass(frozen=True, eq=False)
class SlewSetup:
    """A checked slew: model, end attitudes, limits, scales, cones."""

    model: SpacecraftModel
    q0: np.ndarray
    qf: np.ndarray
    h0: np.ndarray
    u_max: np.ndarray
    h_max: np.ndarray | None
    w_scale: float
    rate_max: float | None
    T_eig: float
    eig_axis: np.ndarray
    keep_out: tuple = ()


def setup_slew(inertia, q0, qf, wheels, torque_max, h0, rate_max,
               keep_out=None) -> SlewSetup:
    """Check a slew's data and set it up (eigenaxis time and axis)."""
    inertia, wheels, rate_max = slew_parts(inertia, wheels, rate_max)
    J = check_inertia(inertia)
    q0 = _unit_quat(q0, "q0")
    qf = _unit_quat(qf, "qf")
    if np.dot(q0, qf) < 0:
        qf = -qf
    model = rigid_spacecraft(J, wheels, torque_max=torque_max)
    if rate_max is not None:
        rate_max = as_finite_scalar(rate_max, "rate_max")
        if not 1e-9 <= rate_max <= 1e3:
            raise InvalidValueError(
                f"rate_max must lie in [1e-9, 1e3] rad/s, got {rate_max!r}")
    eig = eigenaxis_slew(J, q0, qf, wheels=wheels, torque_max=torque_max,
                         rate_max=rate_max)
    if wheels is not None:
        h0 = (np.zeros(wheels.n_wheels) if h0 is None
              else as_vector(h0, wheels.n_wheels, "h0"))
        u_max = np.array(wheels.m_max)
        h_max = np.array(wheels.h_max)
        if np.any(np.abs(h0) > h_max):
            raise InvalidValueError(
                f"h0 must lie within ±h_max = {h_max}, got {h0}")
    else:
        if h0 is not None:
            raise InvalidValueError("h0 is only for a model with wheels")
        h0 = np.zeros(0)
        u_max = np.array(model.torque_max)
        h_max = None
    w_scale = max(eig.peak_rate, 1e-12) if eig.T > 0 else 1.0
    return SlewSetup(model, q0, qf, h0, u_max, h_max, w_scale, rate_max,
                  max(eig.T, 1e-9), eig.axis, keep_outs(keep_out, q0, qf))


def check_common(N: int, transcription: str, substeps: int) -> None:
    """Check the discretisation arguments shared by both slews."""
    if not isinstance(N, (int, np.integer)) or N < 2:
        raise InvalidValueError(f"N must be an integer >= 2, got {N!r}")
    if transcription not in TRANSCRIPTIONS:
        raise InvalidValueError(
            f"transcription must be one of {TRANSCRIPTIONS}, got "
            f"{transcription!r}")
    if not isinstance(substeps, (int, np.integer)) or substeps < 1:
        raise InvalidValueError(
            f"substeps must be an integer >= 1, got {substeps!r}")


def initial_guess_states(s: SlewSetup, N: int, T: float, kind: str,
                         perturbation: float, seed: int
                         ) -> tuple[np.ndarray, np.ndarray]:
    """Return the initial guess (X (nx, N+1), U (nu, N)), physical units."""
    model = s.model
    J = model.inertia
    t = np.linspace(0.0, T, N + 1)
    tm = 0.5 * (t[:-1] + t[1:])
    e, theta = rotation_between(s.q0, s.qf)
    if kind == "eigenaxis":
        eig = eigenaxis_slew(J, s.q0, s.qf, wheels=model.wheels,
                             torque_max=model.torque_max,
                             rate_max=s.rate_max)
        scale = eig.T / T
        th, rate, _ = eig.profile(t * scale)
        rate = rate * scale
        acc = eig.profile(tm * scale)[2] * scale ** 2
    else:  # smooth cubic rest-to-rest profile over T
        sg = t / T
        th = theta * (3 * sg ** 2 - 2 * sg ** 3)
        rate = theta * (6 * sg - 6 * sg ** 2) / T
        sm = tm / T
        acc = theta * (6 - 12 * sm) / T ** 2
    rng = np.random.default_rng(seed)
    if perturbation > 0:
        # smooth off-axis rate, consistent torque: breaks the symmetry
        d = rng.normal(size=3)
        d -= (d @ e) * e
        d /= np.linalg.norm(d)
        amp = perturbation * max(np.max(np.abs(rate)), 1e-12)
        d_rate = amp * np.sin(np.pi * t / T)[:, None] * d
        d_acc = (amp * np.pi / T * np.cos(np.pi * tm / T))[:, None] * d
    else:
        d_rate = np.zeros((N + 1, 3))
        d_acc = np.zeros((N, 3))
    w = np.outer(rate, e) + d_rate
    wdot = np.outer(acc, e) + d_acc
    dq = np.column_stack([np.cos(th / 2), np.outer(np.sin(th / 2), e)])
    q = np.array([quat_mul(s.q0, d) for d in dq])
    body = (J @ wdot.T).T  # body torque needed, gyroscopic part ignored
    if model.wheels is None:
        U = np.clip(body, -s.u_max, s.u_max)
        X = np.column_stack([q, w])
    else:
        G = min_norm_gains(model.wheels)
        m = -(G @ body.T).T  # -A m = J ω̇
        U = np.clip(m, -s.u_max, s.u_max)
        h = s.h0 + np.vstack([np.zeros(model.n_wheels),
                              np.cumsum(U * (T / N), axis=0)])
        assert s.h_max is not None     # set with the wheels
        h = np.clip(h, -s.h_max, s.h_max)
        X = np.column_stack([q, w, h])
    return X.T, U.T
