"""Sweeps on Dask: loopback-only cluster, same answers, faults, resume."""

import numpy as np
import pytest

distributed = pytest.importorskip(
    "distributed", reason="sweeps need the [sweep] extra (Dask)")
xr = pytest.importorskip("xarray")

from adcs.cli import main  # noqa: E402
from adcs.sweep import SWEEPS, connect, local_cluster, run_sweep  # noqa: E402
from adcs.sweep.builtin import geometry_case  # noqa: E402

CALLS = []


def flaky(x: float) -> dict:
    """Fail on one case; count the calls."""
    CALLS.append(x)
    if x == 2.0:
        raise ValueError("no good")
    return {"square": x * x}


@pytest.fixture(scope="module")
def client():
    client, cluster = connect(workers=2)
    yield client
    client.close()
    cluster.close()


def test_the_default_cluster_listens_on_loopback_only():
    cluster = local_cluster(1)
    try:
        assert cluster.scheduler_address.startswith("tcp://127.0.0.1:")
        assert "127.0.0.1" in cluster.dashboard_link
        for w in cluster.workers.values():
            assert "127.0.0.1" in w.address
    finally:
        cluster.close()


def test_workers_equal_the_in_process_run(client):
    params = SWEEPS["geometry"][1](True)[:12]
    here = run_sweep(geometry_case, params, progress=False)
    there = run_sweep(geometry_case, params, client=client, chunk_size=3,
                      progress=False)
    for name in ("inscribed_radius", "utilisation", "min_norm_mean_reach"):
        np.testing.assert_array_equal(there[name].values, here[name].values)
    assert here.sizes["case"] == 12


def samples(n: int) -> dict:
    """Return an array (like a Monte Carlo block's samples) and a number."""
    if n == 0:
        raise ValueError("empty block")
    return {"draws": np.arange(3.0) * n, "total": 3.0 * n}


def test_array_outputs_gain_their_own_dimension(tmp_path):
    ds = run_sweep(samples, [{"n": 1}, {"n": 0}, {"n": 2}], chunk_size=1,
                   out=tmp_path, progress=False)
    assert ds["draws"].dims == ("case", "draws_index")
    np.testing.assert_array_equal(ds["draws"].values[[0, 2]],
                                  [[0.0, 1.0, 2.0], [0.0, 2.0, 4.0]])
    assert np.isnan(ds["draws"].values[1]).all()
    assert ds["error"].values[1] == "ValueError: empty block"
    # resumed from the saved chunks: the same arrays back
    again = run_sweep(samples, [{"n": 1}, {"n": 0}, {"n": 2}], chunk_size=1,
                      out=tmp_path, progress=False)
    np.testing.assert_array_equal(again["draws"].values[[0, 2]],
                                  ds["draws"].values[[0, 2]])


def ragged(n: int) -> dict:
    return {"draws": list(range(n))}


def test_array_outputs_of_different_lengths_are_refused():
    from adcs.sweep import SweepError

    with pytest.raises(SweepError, match="different lengths"):
        run_sweep(ragged, [{"n": 1}, {"n": 2}], progress=False)


def test_report_heavy_studies_on_workers_equal_the_in_process_run(
        client, tmp_path):
    from adcs.report import StudyContext
    from adcs.studies.accuracy import monte_carlo_samples
    from adcs.studies.slews import slew_rows

    here = StudyContext(tmp_path, True)
    there = StudyContext(tmp_path, True, client=client)
    a, b = (slew_rows(ctx, (45.0,), 20) for ctx in (here, there))
    for case in a:
        assert [r.method for r in a[case]] == [r.method for r in b[case]]
        for r, s in zip(a[case], b[case]):
            assert r.success and s.success
            np.testing.assert_allclose(
                [r.T, r.energy, r.peak_wheel_momentum],
                [s.T, s.energy, s.peak_wheel_momentum], rtol=1e-9)
    mc_here = monte_carlo_samples(here, 2_000, 2)
    mc_there = monte_carlo_samples(there, 2_000, 2)
    for scale, pooled in mc_here.items():
        assert pooled["nominal_angle"].shape == (2_000,)
        for key, values in pooled.items():
            np.testing.assert_array_equal(mc_there[scale][key], values)


def test_a_failing_case_is_recorded_and_the_sweep_goes_on(tmp_path):
    CALLS.clear()
    params = [{"x": float(x)} for x in range(5)]
    ds = run_sweep(flaky, params, chunk_size=2, out=tmp_path,
                   progress=False)
    errors = ds["error"].values
    assert errors[2] == "ValueError: no good"
    assert list(errors[[0, 1, 3, 4]]) == [""] * 4
    np.testing.assert_array_equal(ds["square"].values[[0, 1, 3, 4]],
                                  [0.0, 1.0, 9.0, 16.0])
    assert np.isnan(ds["square"].values[2])
    # a rerun loads the finished chunks instead of recomputing them
    CALLS.clear()
    again = run_sweep(flaky, params, chunk_size=2, out=tmp_path,
                      progress=False)
    assert CALLS == []
    np.testing.assert_array_equal(again["error"].values, errors)
    # a sweep with one more case computes only the new chunk
    run_sweep(flaky, params + [{"x": 5.0}], chunk_size=2, out=tmp_path,
              progress=False)
    assert CALLS == [4.0, 5.0]


def test_cli_sweep_writes_dataset_and_plot(tmp_path, capsys):
    assert main(["sweep", "accuracy", "--quick", "--sync", "--samples",
                 "20000", "--out", str(tmp_path), "--no-progress"]) == 0
    ds = xr.load_dataset(tmp_path / "accuracy.nc")
    assert ds.sizes["case"] == 1 and ds["samples"].values[0] == 20000
    assert 0.0 < ds["angle_p95_deg"].values[0] < 2.0
    assert (tmp_path / "accuracy.png").stat().st_size > 5000
    assert "1 cases, 0 failed" in capsys.readouterr().out


def test_cli_sweep_mistakes_are_one_line(capsys, tmp_path):
    assert main(["sweep", "accuracy", "--tls-ca", "ca.pem",
                 "--scheduler", "tls://127.0.0.1:1", "--out",
                 str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "TLS needs" in err and err.count("\n") == 1


def test_a_running_scheduler_is_reached_by_its_address(tmp_path, capsys):
    # the multi-node path: a cluster started apart, addressed by its
    # scheduler address, as a remote one would be
    cluster = local_cluster(2)
    try:
        assert main(["sweep", "geometry", "--quick", "--scheduler",
                     cluster.scheduler_address, "--out", str(tmp_path),
                     "--no-progress"]) == 0
    finally:
        cluster.close()
    ds = xr.load_dataset(tmp_path / "geometry.nc")
    assert ds.sizes["case"] == len(SWEEPS["geometry"][1](True))
    assert (ds["error"].values == "").all()
    ref = geometry_case(55.0, 45.0, 0)
    sel = ((ds["delta_deg"] == 50.0) & (ds["gamma_deg"] == 45.0)
           & (ds["failed"] == 0)).values
    assert sel.sum() == 1
    r = geometry_case(50.0, 45.0, 0)
    assert ds["utilisation"].values[sel][0] == r["utilisation"]
    assert 0.0 < ref["utilisation"] < 1.0


@pytest.mark.parametrize("argv, message", [
    (["sweep", "accuracy", "--sync", "--samples", "0"], "--samples"),
    (["sweep", "failures", "--sync", "--t-fail", "-1"], "--t-fail"),
    (["sweep", "agility", "--sync", "--spacecraft", "nope"],
     "no built-in spacecraft"),
])
def test_sweep_argument_mistakes(argv, message, capsys, tmp_path):
    assert main(argv + ["--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1
