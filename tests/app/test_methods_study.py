"""The `methods` report study: its numbers are the comparison's."""

import numpy as np

from adcs.cli import main
from adcs.report import STUDIES, StudyContext
from adcs.studies import methods as study
from allocation import comparison_arrays, compare_methods


def test_methods_study_tables_and_figures(tmp_path):
    section = study.run(StudyContext(out=tmp_path, quick=True))
    assert section.key == "methods" and "methods" in STUDIES
    assert len(section.figures) == 3
    for f in section.figures:
        assert (tmp_path / f.filename).stat().st_size > 10_000
    cover, mom = section.tables
    arrays = comparison_arrays()
    rows = [r for r in cover.rows if r[0] == "3 + 1"]
    ref = compare_methods(arrays["3 + 1"], n_samples=300, n_directions=20)
    assert [r[1] for r in rows] == [r.method for r in ref]
    for row, r in zip(rows, ref):
        np.testing.assert_allclose(
            row[2:8], [100 * r.volume_fraction,
                       100 * r.mean_direction_fraction,
                       100 * r.min_direction_fraction, r.miss_error_p50,
                       r.miss_error_p95, 100 * r.qp_agreement],
            rtol=0, atol=1e-12)
    by = {r[1]: r for r in cover.rows if r[0] == "pyramid"}
    assert by["exact QP (scale)"][2] == 100.0
    assert by["direct allocation"][2] == 100.0
    assert 40.0 < by["pseudo-inverse"][2] < 90.0
    qp = mom.rows[0]
    assert qp[0] == "exact QP (scale)" and qp[1] == 0.0 and qp[4] == 100.0
    assert all(r[3] == 0.0 for r in mom.rows)       # boxed: never beyond
    assert any("beyond h_max" in s for s in section.summary)


def test_demand_errors_give_the_volume_share():
    """Share of errors <= 1e-3 of a clipping method = its volume share."""
    array = comparison_arrays()["pyramid"]
    errors = study.demand_errors(array, 400)
    rows = compare_methods(array, n_samples=400, n_directions=4,
                           include_qp=False)
    for r in rows:
        if r.method in ("pseudo-inverse", "daisy chain",
                        "redistributed pseudo-inverse"):
            assert np.mean(errors[r.method] <= 1e-3) == r.volume_fraction
    assert np.mean(errors["pseudo-inverse"] <= 1e-3) < 0.9


def test_report_runs_the_study_alone(tmp_path):
    assert main(["report", "--quick", "--studies", "methods", "--out",
                 str(tmp_path)]) == 0
    md = (tmp_path / "report.md").read_text()
    assert "Which allocation law should my flight software run?" in md
    assert "methods_reach.png" in md
