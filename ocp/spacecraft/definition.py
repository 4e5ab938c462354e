"""`Spacecraft`: one definition of a craft that every tool accepts."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from adcs_common.exceptions import AdcsError, InvalidValueError
from adcs_common.rigid_body import check_inertia
from adcs_common.validation import as_finite_scalar
from allocation import WheelArray
from thrusters import ThrusterSet

if TYPE_CHECKING:  # the model module imports this one
    from ocp.models.rigid import SpacecraftModel

__all__ = ["Spacecraft", "SpacecraftFileError", "slew_parts",
           "spacecraft_parts"]


class SpacecraftFileError(AdcsError, ValueError):
    """A spacecraft file or catalogue name that cannot be used.

    Attributes
    ----------
    source : str
        The file (or catalogue name) read.
    key : str
        The TOML key at fault ("" for the whole file).
    """

    def __init__(self, source: str, key: str, problem: str) -> None:
        where = f"{source}: " + (f"[{key}] " if key else "")
        super().__init__(where + problem)
        self.source = source
        self.key = key


def _inertia(value) -> np.ndarray:
    J = check_inertia(value)
    J.setflags(write=False)
    return J


@dataclass(frozen=True, eq=False)
class Spacecraft:
    """A spacecraft as the tools see it: body, wheels, optional thrusters.

    Build one in Python, load it from a TOML file (`load_spacecraft`,
    schema in ``docs/spacecraft.md``) or take a built-in from the
    catalogue (`list_spacecraft`). Every tool accepts it: `model`,
    ``ocp.rigid_spacecraft``, the slews, ``ocp.mpc.AttitudeMPC``,
    ``ocp.codegen.export_c``, the report, the bench and ``adcs export``.

    Attributes
    ----------
    name : str
        Short name (used in reports and file names).
    inertia : numpy.ndarray, shape (3, 3)
        Inertia J [kg·m²], symmetric positive definite (a (3,) diagonal
        is accepted).
    wheels : allocation.WheelArray
        The reaction-wheel array (axes, h_max [N·m·s], m_max [N·m],
        failed wheels).
    thrusters : thrusters.ThrusterSet or None
        Optional thruster set (e.g. ``thrusters.six_thruster_unit()``).
    rate_max : float or None
        Body-rate limit [rad/s] the slews and the MPC respect, if any.
    description : str
        One line for listings.
    """

    name: str
    inertia: np.ndarray
    wheels: WheelArray
    thrusters: ThrusterSet | None = None
    rate_max: float | None = None
    description: str = ""

    def __post_init__(self) -> None:
        """Check every field."""
        if not isinstance(self.name, str) or not self.name.strip():
            raise InvalidValueError(
                f"name must be a non-empty string, got {self.name!r}")
        object.__setattr__(self, "inertia", _inertia(self.inertia))
        if not isinstance(self.wheels, WheelArray):
            raise InvalidValueError(
                "wheels must be an allocation.WheelArray, got "
                f"{type(self.wheels).__name__}")
        if self.thrusters is not None and not isinstance(self.thrusters,
                                                         ThrusterSet):
            raise InvalidValueError(
                "thrusters must be a thrusters.ThrusterSet or None, got "
                f"{type(self.thrusters).__name__}")
        if self.rate_max is not None:
            rate = as_finite_scalar(self.rate_max, "rate_max")
            if rate <= 0:
                raise InvalidValueError(
                    f"rate_max must be positive [rad/s], got {rate}")
            object.__setattr__(self, "rate_max", rate)
        if not isinstance(self.description, str):
            raise InvalidValueError("description must be a string")

    def model(self) -> "SpacecraftModel":
        """Build the CasADi model of this craft (``ocp.rigid_spacecraft``)."""
        from ocp.models.rigid import rigid_spacecraft

        return rigid_spacecraft(self.inertia, self.wheels,
                                thrusters=self.thrusters)

    def with_wheels(self, wheels: WheelArray) -> "Spacecraft":
        """Return the same craft with another wheel array (e.g. a failure)."""
        return Spacecraft(self.name, self.inertia, wheels, self.thrusters,
                          self.rate_max, self.description)

    def summary(self) -> str:
        """One line: wheels, failures, thrusters, inertia diagonal."""
        w = self.wheels
        failed = (f", failed {', '.join(str(i + 1) for i in w.failed)}"
                  if w.failed else "")
        thr = (f", {self.thrusters.n} thrusters" if self.thrusters
               is not None else "")
        diag = ", ".join(f"{v:g}" for v in np.diag(self.inertia))
        return (f"{w.n_wheels} wheels{failed}{thr}; J diag ({diag}) kg·m²")

    def to_toml(self) -> str:
        """Write the craft as a TOML document (`load_spacecraft` reads it)."""
        from .toml_io import spacecraft_to_toml

        return spacecraft_to_toml(self)

    def save(self, path) -> None:
        """Write `to_toml` to ``path`` (its folder must exist)."""
        from .toml_io import write_text

        write_text(path, self.to_toml())


def spacecraft_parts(inertia, wheels, thrusters=None, name: str = "inertia"):
    """``(J, wheels, thrusters)`` of a `Spacecraft` or of separate parts.

    The tools take either a `Spacecraft` in place of the inertia or the
    inertia with its actuators; giving a `Spacecraft` *and* ``wheels`` or
    ``thrusters`` is ambiguous and rejected.
    """
    if isinstance(inertia, Spacecraft):
        if wheels is not None or thrusters is not None:
            raise InvalidValueError(
                f"{name} is a Spacecraft: do not pass wheels= or "
                "thrusters= as well (use spacecraft.with_wheels(...))")
        return inertia.inertia, inertia.wheels, inertia.thrusters
    return inertia, wheels, thrusters


def slew_parts(inertia, wheels, rate_max):
    """``(J, wheels, rate_max)`` of a slew given a `Spacecraft` or parts.

    A `Spacecraft` brings its wheels and, unless ``rate_max`` is given,
    its own rate limit.
    """
    if isinstance(inertia, Spacecraft) and rate_max is None:
        rate_max = inertia.rate_max
    inertia, wheels, _ = spacecraft_parts(inertia, wheels)
    return inertia, wheels, rate_max
