"""The `robust` report study: its table is the Monte Carlo's summary."""

import pytest

pytest.importorskip("distributed", reason="the study runs on the sweep "
                    "engine ([sweep] extra)")

from adcs.report import STUDIES, StudyContext  # noqa: E402
from adcs.robust_mc import (robust_mc_case,  # noqa: E402
                            robust_mc_params, run_robust_mc,
                            summarise)
from adcs.studies import robust as study  # noqa: E402


def test_robust_study_table_is_the_monte_carlo(tmp_path, monkeypatch):
    """The study's tables summarise its two Monte Carlos (2 draws each,
    quick), whose cases are `run_robust_mc`'s: its first draw, run again
    through `run_robust_mc`, is the study's to the last digit."""
    swept = []
    sweep = StudyContext.sweep

    def spy(self, case, params):
        swept.append((case, params, sweep(self, case, params)))
        return swept[-1][2]

    monkeypatch.setattr(StudyContext, "sweep", spy)
    section = study.run(StudyContext(out=tmp_path, quick=True))
    assert section.key == "robust" and "robust" in STUDIES
    assert (tmp_path / section.figures[0].filename).stat().st_size > 10_000
    (case, params, ds), (_, params_r, ds_r) = swept
    assert case is robust_mc_case
    assert params == robust_mc_params(2, t_final=30.0, rate_max=0.0)
    assert params_r == robust_mc_params(2, t_final=30.0,
                                        rate_max=study.RATE_BOUND,
                                        keep_out_deg=study.KEEP_OUT_DEG)
    one = run_robust_mc(1, t_final=30.0, rate_max=0.0)
    for ctrl in ("nominal", "robust"):
        for what in ("energy", "settle_time", "final_error", "failed"):
            name = f"{ctrl}_{what}"
            assert one[name].values[0] == ds[name].values[0], name
    table, rated = section.tables
    rows = {r[0]: r[1:] for r in table.rows}
    nom, rob = summarise(ds)
    assert rows["loops broken"][:2] == [nom.failed, rob.failed] == [0, 0]
    assert rows["settled (0.1°)"][:2] == [2, 2]
    assert rows["energy, median [N²·m²·s]"][:2] == [nom.energy_median,
                                                    rob.energy_median]
    assert rows["settling time, worst [s]"][:2] == [nom.settle_worst,
                                                    rob.settle_worst]
    assert rows["energy, median [N²·m²·s]"][2] == pytest.approx(
        rob.energy_median / nom.energy_median, rel=1e-15)
    assert 20.0 < nom.settle_median < 30.0            # a 90° slew, 30 s
    assert 0 < rows["final error, largest [deg]"][0] < 0.1    # settled
    assert "robust / nominal: energy" in section.summary[1]
    # the second Monte Carlo bounds the rate: its overshoot rows are the
    # summary's, in percent of the bound
    # and both hold a keep-out cone across the slew
    nom_r, rob_r = summarise(ds_r)
    rows = {r[0]: r[1:] for r in rated.rows}
    assert rows["rate overshoot, largest [% of bound]"][:2] == [
        100.0 * nom_r.rate_over_max, 100.0 * rob_r.rate_over_max]
    assert nom_r.rate_over_max > rob_r.rate_over_max
    assert rows["keep-out violations"][:2] == [0, 0]
    assert "rate bound 0.04 rad/s" in section.summary[2]
    assert "keep-out cone 0 / 0" in section.summary[2]
