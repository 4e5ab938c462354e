"""The Basilisk scenarios' figures (prints the README's table).

Run from the repository root: ``python -m benchmarks.basilisk`` (needs
``pip install -e ".[basilisk]"``). Saturated 40° slew of the Meteor-M
pyramid, 400 s, nominal and with wheel 2 unavailable from 10 s.
"""

from __future__ import annotations

import numpy as np

from adcs.basilisk import INSTALL_HINT, basilisk_available


def main() -> None:
    """Print the table."""
    if not basilisk_available():
        print(f"skipped: Basilisk is not installed ({INSTALL_HINT})")
        return
    from adcs.basilisk.scenarios import compare_loops

    print("| loop | max direction error [deg] | final pointing error [deg] |")
    print("|---|---:|---:|")
    for label, kw in (("", {}), ("wheel 2 unavailable from 10 s: ",
                                 {"fail_wheel": 1, "t_fail": 10.0})):
        for name, r in compare_loops(t_final=400.0, **kw).items():
            print(f"| {label}{name} | "
                  f"{np.degrees(r.direction_error.max()):.3g} | "
                  f"{np.degrees(r.pointing_error[-1]):.4g} |")
    from adcs.basilisk.mpc_scenario import mpc_slew

    print("\nMPC slew (150° about (1, -2, 3), 60 s) in Basilisk and ours:")
    for key, value in mpc_slew(t_final=60.0).summary().items():
        print(f"  {key}: {value:.3g}")
    from adcs.basilisk.thruster_scenario import compare_reorientation

    print("\n[4]'s unit, 30° reorientation, 120 s:")
    for name, r in compare_reorientation().items():
        print(f"  {name}: " + ", ".join(
            f"{k} {v:.3g}" for k, v in r.summary().items()))


if __name__ == "__main__":
    main()
