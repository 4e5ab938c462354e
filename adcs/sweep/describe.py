"""Attributes of a built-in sweep's dataset: units, craft, version.

`describe` fills ``ds.attrs`` (what the sweep is, the craft, the toolbox
version and commit, when it was made) and each variable's ``units`` and
``long_name`` (CF conventions), so ``<name>.nc`` says what it holds.
"""

from __future__ import annotations

import datetime as _dt
from typing import Any

__all__ = ["VARIABLES", "describe"]

#: variable -> (units, long name) of the built-in sweeps' datasets
VARIABLES: dict[str, tuple[str, str]] = {
    # geometry
    "delta_deg": ("deg", "pyramid elevation angle δ"),
    "gamma_deg": ("deg", "pyramid azimuth angle γ"),
    "failed": ("1", "failed wheel, numbered 1..4 (0: none)"),
    "inscribed_radius": ("N·m", "inscribed radius of the torque "
                         "envelope, wheels of m_max = 1 N·m"),
    "utilisation": ("1", "inscribed radius over the sum of the working "
                    "wheels' m_max"),
    "min_norm_mean_reach": ("1", "minimum-norm law: mean fraction of the "
                            "envelope reached over 200 directions"),
    "min_norm_worst_reach": ("1", "minimum-norm law: worst-direction "
                             "fraction of the envelope reached"),
    # accuracy
    "seed": ("1", "Monte Carlo block (random seed)"),
    "n_samples": ("1", "samples in the block"),
    "samples": ("1", "samples in the block"),
    "mount_tol_deg": ("deg", "mounting error bound (uniform) of δ and γ"),
    "scale_tol": ("1", "scale-factor error bound (uniform)"),
    "angle_mean_deg": ("deg", "mean torque direction error"),
    "angle_p95_deg": ("deg", "95th percentile torque direction error"),
    "angle_max_deg": ("deg", "largest torque direction error"),
    "magnitude_p95": ("1", "95th percentile relative torque magnitude "
                      "error"),
    # agility
    "spacecraft": ("", "spacecraft: a built-in name or a TOML file"),
    "axis": ("1", "slew axis: index of fibonacci_axes(12), 0-based (the "
             "plot names it axis + 1, with its direction)"),
    "axis_x": ("1", "slew axis, body x component (unit vector)"),
    "axis_y": ("1", "slew axis, body y component (unit vector)"),
    "axis_z": ("1", "slew axis, body z component (unit vector)"),
    "angle_deg": ("deg", "slew angle"),
    "N": ("1", "control intervals of the time-optimal NLP"),
    "eigenaxis_T": ("s", "eigenaxis (bang-coast-bang) slew time"),
    "time_optimal_T": ("s", "time-optimal slew time"),
    "saving": ("1", "1 - time-optimal / eigenaxis slew time"),
    "success": ("1", "1 when the time-optimal NLP solved, else 0"),
    # failures
    "wheel": ("1", "wheel that fails, numbered 1..N"),
    "t_fail": ("s", "time the wheel fails"),
    "settle_time": ("s", "time to settle within 0.1° of the target"),
    "final_error_deg": ("deg", "attitude error at the end"),
    "peak_torque": ("N·m", "largest wheel torque"),
    "momentum_violation": ("N·m·s", "largest excess of |H_i| over h_max"),
    # robust (adcs.robust_mc); per controller in _robust_variables
    "draw": ("1", "Monte Carlo draw (its random stream: seed, draw)"),
    "rate_max": ("rad/s", "body-rate bound of both MPCs (0: none)"),
    "rate_margin": ("1", "both MPCs plan rate_max·(1 − rate_margin)"),
    "tree_products": ("1", "robust MPC's tree also spans these products "
                      "of inertia (± of the largest moment; 0: none)"),
    "keep_out_deg": ("deg", "half-angle of the keep-out cone across the "
                     "slew, held by both MPCs (0: none)"),
    "spread": ("1", "robust MPC's inertia corners 1 ± spread"),
    "horizon": ("1", "MPC horizon (stages)"),
    "dt": ("s", "MPC sample time"),
    "factor_1": ("1", "drawn scale of the principal moment 1 "
                 "(ascending order)"),
    "factor_2": ("1", "drawn scale of the principal moment 2 "
                 "(ascending order)"),
    "factor_3": ("1", "drawn scale of the principal moment 3 "
                 "(ascending order)"),
    "product_xy": ("1", "drawn J_xy over the largest moment"),
    "product_xz": ("1", "drawn J_xz over the largest moment"),
    "product_yz": ("1", "drawn J_yz over the largest moment"),
    "tilt_max": ("rad", "largest drawn wheel-axis tilt"),
    "error": ("", "why the case failed (empty: it did not)"),
}
for _c in ("nominal", "robust"):
    VARIABLES.update({
        f"{_c}_failed": ("1", f"{_c} MPC: 1 when the loop broke (the "
                         "MPC raised)"),
        f"{_c}_momentum_violation": ("N·m·s", f"{_c} MPC: largest excess "
                                     "of |H_i| over h_max"),
        f"{_c}_torque_violation": ("N·m", f"{_c} MPC: largest excess of "
                                   "|m_i| over m_max"),
        f"{_c}_rate_violation": ("rad/s", f"{_c} MPC: largest excess of "
                                 "|ω_i| over rate_max"),
        f"{_c}_keep_out_violation": ("rad", f"{_c} MPC: how deep the "
                                     "path entered the keep-out cone"),
        f"{_c}_settle_time": ("s", f"{_c} MPC: time to settle within "
                              "0.1°"),
        f"{_c}_final_error": ("rad", f"{_c} MPC: attitude error at the "
                              "end"),
        f"{_c}_energy": ("N²·m²·s", f"{_c} MPC: sum of ∫ m_i² dt"),
        f"{_c}_step_time": ("s", f"{_c} MPC: median step time"),
        f"{_c}_faults": ("1", f"{_c} MPC in Basilisk: steps the module "
                         "refused (zero torques)"),
    })


def describe(name: str, ds: Any, spacecraft: str | None = None,
             description: str = "") -> Any:
    """Set ``ds``'s attributes (in place) and return it.

    Parameters
    ----------
    name : str
        The built-in sweep (``adcs sweep NAME``).
    ds : xarray.Dataset
        Its result (`run_sweep`).
    spacecraft : str, optional
        The craft given (a built-in name or a TOML file): recorded with
        the craft's own name, for the sweeps that take one.
    description : str
        One line: what the sweep shows.
    """
    from adcs.provenance import provenance, version

    made = dict(provenance())
    ds.attrs.update({
        "title": f"adcs sweep {name}",
        "sweep": name,
        "description": description,
        "adcs_toolbox_version": version(),
        "git_commit": made.get("git commit", ""),
        "python": made.get("python", ""),
        "created_utc": _dt.datetime.now(_dt.timezone.utc).strftime(
            "%Y-%m-%dT%H:%M:%SZ"),
        "conventions": "units in SI (angles in deg where the name ends "
                       "in _deg); wheels numbered 1..N",
    })
    if spacecraft is not None:
        from ocp.spacecraft import load_spacecraft

        sc = load_spacecraft(spacecraft)
        ds.attrs.update(spacecraft=str(spacecraft), spacecraft_name=sc.name,
                        spacecraft_summary=sc.summary())
    for var in list(ds.variables):
        if var in VARIABLES:
            units, long_name = VARIABLES[var]
            if units:
                ds[var].attrs["units"] = units
            ds[var].attrs["long_name"] = long_name
    return ds
