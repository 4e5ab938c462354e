"""Run the toolbox's allocators inside Basilisk and compare with its FSW.

Needs the optional extra ``pip install -e ".[basilisk]"`` (the ``bsk``
package, Basilisk 2.12). Conventions at the boundary:

* Basilisk's ``CmdTorqueBodyMsg`` carries the control torque ``L_r`` the
  body should receive; its wheel motor torques ``u_s`` act on the body as
  ``-G_s u_s`` (`rwMotorTorque` computes ``u_s = -G_sᵀ(G_s G_sᵀ)⁻¹ L_r``).
  The toolbox's allocators take the array torque ``M = A m`` (the body
  receives ``-A m``), so ``M = -L_r`` and ``u_s = m`` with ``A = G_s``.
* Basilisk's attitudes are MRPs σ, the toolbox's scalar-first
  quaternions (`mrp_to_quaternion`, `quaternion_to_mrp`).
* Wheel momenta are ``J_s Ω`` from the wheel speeds message.
"""

from __future__ import annotations

from adcs_common.exceptions import AdcsError

#: How to get Basilisk.
INSTALL_HINT = ('pip install -e ".[basilisk]" (the bsk package, Basilisk '
                "2.12; about 75 MB)")


def basilisk_available() -> bool:
    """Return True when Basilisk (the ``bsk`` package) can be imported."""
    try:
        import Basilisk  # noqa: F401
    except ImportError:
        return False
    return True


def require_basilisk() -> None:
    """Raise `AdcsError` naming the install command unless Basilisk is here."""
    if not basilisk_available():
        raise AdcsError(f"Basilisk is not installed: {INSTALL_HINT}")


__all__ = ["INSTALL_HINT", "basilisk_available", "require_basilisk"]
