"""Sweeps on Dask: loopback-only cluster, same answers, faults, resume."""

import json
import warnings

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


# -- saved chunks: keyed by content and code, verified, recomputed -------

def _craft_file(path, scale=1.0):
    """meteor-m as a user's TOML file, its inertia times ``scale``."""
    from ocp.spacecraft import spacecraft_toml

    text = spacecraft_toml("meteor-m")
    old = "inertia = [3000.0, 2700.0, 2000.0]"
    assert old in text
    path.write_text(text.replace(old, "inertia = [{}, {}, {}]".format(
        *(scale * np.array([3000.0, 2700.0, 2000.0])))))
    return path


def test_an_edited_craft_file_is_computed_not_resumed(tmp_path, capsys):
    craft = _craft_file(tmp_path / "craft.toml")
    argv = ["sweep", "agility", "--quick", "--sync", "--spacecraft",
            str(craft), "--out", str(tmp_path / "o"), "--no-progress"]
    assert main(argv) == 0
    light = xr.load_dataset(tmp_path / "o" / "agility.nc")
    _craft_file(craft, scale=10.0)          # the same path, 10x the inertia
    assert main(argv) == 0
    heavy = xr.load_dataset(tmp_path / "o" / "agility.nc")
    assert (heavy["error"].values == "").all()
    # a heavier craft is slower (the stale chunks gave the light times)
    assert (heavy["eigenaxis_T"].values
            > 2.0 * light["eigenaxis_T"].values).all()
    assert "(0 of 4 chunks resumed)" in capsys.readouterr().out
    fresh = tmp_path / "fresh"
    assert main(argv[:-3] + ["--out", str(fresh), "--no-progress"]) == 0
    np.testing.assert_allclose(
        heavy["eigenaxis_T"].values,
        xr.load_dataset(fresh / "agility.nc")["eigenaxis_T"].values,
        rtol=1e-12)
    # unchanged since: resumed
    assert main(argv) == 0
    assert "(4 of 4 chunks resumed)" in capsys.readouterr().out


STUDY_SOURCE = '''
FACTOR = {factor}
CALLS = []


def study(x):
    CALLS.append(x)
    return {{"y": FACTOR * x}}
'''


def test_an_edited_study_is_computed_not_resumed(tmp_path, monkeypatch):
    import importlib
    import sys

    monkeypatch.syspath_prepend(str(tmp_path))
    module = tmp_path / "edited_study.py"
    params = [{"x": 1.0}, {"x": 2.0}]
    runs = []
    for factor in (2.0, 3.0, 3.0):
        module.write_text(STUDY_SOURCE.format(factor=factor))
        sys.modules.pop("edited_study", None)
        importlib.invalidate_caches()
        mod = importlib.import_module("edited_study")
        ds = run_sweep(mod.study, params, out=tmp_path / "o",
                       progress=False)
        runs.append((list(ds["y"].values), list(mod.CALLS)))
    sys.modules.pop("edited_study", None)
    assert runs[0] == ([2.0, 4.0], [1.0, 2.0])
    assert runs[1] == ([3.0, 6.0], [1.0, 2.0])       # new source: computed
    assert runs[2] == ([3.0, 6.0], [])               # same source: resumed


def versioned(x: float) -> dict:
    CALLS.append(x)
    return {"y": x}


def test_a_study_version_bump_is_computed_not_resumed(tmp_path,
                                                      monkeypatch):
    CALLS.clear()
    run_sweep(versioned, [{"x": 1.0}], out=tmp_path, progress=False)
    run_sweep(versioned, [{"x": 1.0}], out=tmp_path, progress=False)
    assert CALLS == [1.0]
    monkeypatch.setattr(versioned, "sweep_version", "2", raising=False)
    run_sweep(versioned, [{"x": 1.0}], out=tmp_path, progress=False)
    assert CALLS == [1.0, 1.0]


def _edit_rows(edit):
    """Tamper with a saved chunk's rows, keeping it valid JSON."""
    def tamper(text):
        data = json.loads(text)
        edit(data["rows"])
        return json.dumps(data)
    return tamper


TAMPERS = {
    "empty list": lambda text: "[]",
    "empty object": lambda text: "{}",
    "truncated": lambda text: text[:len(text) // 2],
    "garbage text": lambda text: "not json at all {",
    "garbage bytes": lambda text: b"\xff\xfe\x00\x81PK\x03\x04",
    "empty file": lambda text: "",
    "row removed": _edit_rows(lambda rows: rows.pop()),
    "value changed": _edit_rows(lambda rows: rows[0].update(square=99.0)),
    "NaN written": _edit_rows(
        lambda rows: rows[1].update(square=float("nan"))),
    "error cleared": _edit_rows(lambda rows: rows[0].update(error="x")),
    "parameter changed": _edit_rows(lambda rows: rows[0].update(x=7.0)),
    "digest removed": lambda text: text.replace('"digest"', '"digestx"'),
}


@pytest.mark.parametrize("how", list(TAMPERS))
def test_a_tampered_chunk_is_detected_and_recomputed(how, tmp_path):
    from adcs.sweep import SweepCacheWarning

    CALLS.clear()
    params = [{"x": float(x)} for x in (0, 1, 3, 4)]
    first = run_sweep(flaky, params, chunk_size=2, out=tmp_path,
                      progress=False)
    assert first.attrs["chunks_computed"] == 2
    chunk = sorted((tmp_path / "chunks").glob("*.json"),
                   key=lambda p: p.read_text())[0]
    rows = json.loads(chunk.read_text())["rows"]
    new = TAMPERS[how](chunk.read_text())
    if isinstance(new, bytes):
        chunk.write_bytes(new)
    else:
        chunk.write_text(new)
    CALLS.clear()
    with pytest.warns(SweepCacheWarning,
                      match="1 saved chunk failed verification, "
                      f"recomputed .*{chunk.name}"):
        again = run_sweep(flaky, params, chunk_size=2, out=tmp_path,
                          progress=False)
    assert CALLS == [r["x"] for r in rows]             # that chunk only
    assert again.attrs["chunks_failed_verification"] == 1
    assert again.attrs["chunks_loaded"] == 1
    for name in ("x", "square", "error"):
        np.testing.assert_array_equal(again[name].values,
                                      first[name].values)
    # rewritten: the next run resumes everything
    CALLS.clear()
    third = run_sweep(flaky, params, chunk_size=2, out=tmp_path,
                      progress=False)
    assert CALLS == [] and third.attrs["chunks_loaded"] == 2
    assert third.attrs["chunks_failed_verification"] == 0


def test_a_chunk_that_cannot_be_saved_is_one_error(tmp_path, capsys):
    from adcs.sweep import SweepError

    run_sweep(versioned, [{"x": 1.0}], out=tmp_path, progress=False)
    (chunk,) = (tmp_path / "chunks").glob("*.json")
    chunk.unlink()
    chunk.mkdir()                  # a folder where the chunk was: unusable
    with pytest.warns(match="unreadable"), \
            pytest.raises(SweepError, match="cannot save the chunk"):
        run_sweep(versioned, [{"x": 1.0}], out=tmp_path, progress=False)


def test_a_study_nan_is_saved_and_resumed(tmp_path):
    def nan_study(x):
        return {"y": float("nan") if x else 1.0}

    params = [{"x": 0}, {"x": 1}]
    run_sweep(nan_study, params, chunk_size=1, out=tmp_path,
              progress=False)
    with warnings.catch_warnings():           # a NaN of the study verifies
        warnings.simplefilter("error")
        again = run_sweep(nan_study, params, chunk_size=1, out=tmp_path,
                          progress=False)
    assert again.attrs["chunks_loaded"] == 2
    assert again["y"].values[0] == 1.0 and np.isnan(again["y"].values[1])


def test_cli_says_which_chunks_failed_verification(tmp_path, capsys):
    argv = ["sweep", "accuracy", "--quick", "--sync", "--samples",
            "200000", "--out", str(tmp_path), "--no-progress"]
    assert main(argv) == 0
    before = xr.load_dataset(tmp_path / "accuracy.nc")
    first, second = sorted((tmp_path / "chunks").glob("*.json"))
    first.write_text("[]")
    second.write_text(second.read_text()[:50])
    capsys.readouterr()
    assert main(argv) == 0
    out, err = capsys.readouterr()
    assert "2 saved chunks failed verification, recomputed" in out
    assert "2 cases, 0 failed (0 of 2 chunks resumed)" in out
    assert "Traceback" not in out + err
    after = xr.load_dataset(tmp_path / "accuracy.nc")
    np.testing.assert_array_equal(after["angle_p95_deg"].values,
                                  before["angle_p95_deg"].values)


# -- #26: the dataset says what it holds; the plot tells its axes apart ---
def test_a_sweep_dataset_has_units_craft_and_version(tmp_path):
    from adcs import __version__
    from adcs.sweep.builtin import fibonacci_axes

    assert main(["sweep", "agility", "--quick", "--sync", "--out",
                 str(tmp_path), "--no-progress"]) == 0
    ds = xr.load_dataset(tmp_path / "agility.nc")
    assert ds.attrs["adcs_toolbox_version"] == __version__
    assert ds.attrs["sweep"] == "agility"
    assert ds.attrs["spacecraft"] == "demo"
    assert ds.attrs["spacecraft_name"] == "demo"
    assert ds.attrs["created_utc"].endswith("Z")
    for var, units in (("eigenaxis_T", "s"), ("time_optimal_T", "s"),
                       ("angle_deg", "deg"), ("saving", "1")):
        assert ds[var].attrs["units"] == units, var
    assert "0-based" in ds["axis"].attrs["long_name"]
    # each case carries its axis's direction
    for a, x, y, z in zip(ds["axis"].values, ds["axis_x"].values,
                          ds["axis_y"].values, ds["axis_z"].values):
        np.testing.assert_allclose([x, y, z], fibonacci_axes()[a],
                                   rtol=0, atol=1e-15)


def test_the_agility_legend_numbers_axes_from_1_in_distinct_styles():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from adcs.sweep.builtin import fibonacci_axes
    from adcs.sweep.plots import sweep_figure

    dirs = fibonacci_axes()
    axis = np.repeat(np.arange(12), 2)
    ds = xr.Dataset({
        "axis": ("case", axis), "angle_deg": ("case", np.tile([30.0, 90.0],
                                                              12)),
        "time_optimal_T": ("case", 10.0 + axis + np.tile([0.0, 5.0], 12)),
        "axis_x": ("case", dirs[axis, 0]), "axis_y": ("case", dirs[axis, 1]),
        "axis_z": ("case", dirs[axis, 2]), "error": ("case", [""] * 24)})
    fig = sweep_figure("agility", ds)
    ax = fig.axes[0]
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert labels[0].startswith("axis 1 (") and labels[-1].startswith(
        "axis 12 (")
    x, y, z = dirs[0]
    assert labels[0] == f"axis 1 ({x:+.2f}, {y:+.2f}, {z:+.2f})"
    lines = ax.get_lines()
    colours = {tuple(np.round(line.get_color(), 6)) for line in lines}
    looks = {(tuple(np.round(line.get_color(), 6)), line.get_linestyle(),
              line.get_marker()) for line in lines}
    assert len(lines) == 12 and len(colours) == 12 and len(looks) == 12
    plt.close(fig)
