"""`adcs report`: the quick run writes every section and paper table."""

import re

import pytest

from adcs.cli import main
from adcs.report import STUDIES


@pytest.fixture(scope="module")
def quick_report(tmp_path_factory):
    out = tmp_path_factory.mktemp("report")
    assert main(["report", "--quick", "--out", str(out)]) == 0
    return out


def test_report_writes_html_markdown_and_figures(quick_report):
    assert (quick_report / "report.html").stat().st_size > 10_000
    assert (quick_report / "report.md").exists()
    assert list(quick_report.glob("*.png"))


def test_report_has_every_section(quick_report):
    html = (quick_report / "report.html").read_text()
    for key in STUDIES:
        assert f'<section id="{key}">' in html


def test_report_tables_set_paper_beside_ours(quick_report):
    md = (quick_report / "report.md").read_text()
    header = ("| quantity | paper | bound or tolerance | ours | ours − "
              "paper | verdict |")
    assert md.count(header) >= 3
    # theory §1.2 inscribed radius, computed, judged by its tolerance,
    # which the bound-or-tolerance column states
    assert re.search(r"inscribed sphere radius r \| 1.63 \| ±0.01 \| "
                     r"1.6303 \| [0-9.e-]+ \| within tolerance \(±0.01\)",
                     md)
    # the errata are flagged, with the erratum named
    assert "⚠ m2" in md and "erratum: the printed m2 row repeats m1" in md
    assert "⚠ case (a) ΔMx/Mx, formula as printed" in md


def test_every_comparison_row_has_a_verdict_and_bounds_apart(quick_report):
    """Verdict column: met / within tolerance / not met (why) / erratum."""
    md = (quick_report / "report.md").read_text().splitlines()
    split = re.compile(r"(?<!\\)\|")
    verdicts, header = [], None
    for line in md:
        if not line.startswith("|"):
            header = None
            continue
        cells = [c.strip() for c in split.split(line)[1:-1]]
        if header is None:
            header = cells
            continue
        if "verdict" in header and not set(line) <= set("|-"):
            row = dict(zip(header, cells))
            verdicts.append(row)
            paper = next((v for k, v in row.items()
                          if k.startswith(("paper", "reference"))), "—")
            if row["verdict"] == "—":        # a row without a paper figure
                assert paper == "—", row
                continue
            assert row["verdict"].startswith((
                "within tolerance", "bound met", "not met", "erratum",
                "no tolerance stated")), row
            missed = row["verdict"].startswith(("not met", "erratum"))
            assert cells[0].startswith("⚠") == missed, row
            limit = row.get("bound or tolerance", row.get("tolerance [deg]"))
            if limit is not None:       # tables with a limit column
                _check_limit(row["verdict"], limit)
    assert len(verdicts) > 60
    # the burn's momentum excursion: a bound not met, with its reason
    burn = [v for v in verdicts if v.get("quantity", "").startswith(
        "⚠ max \\|H_X\\|, \\|H_Z\\| during")]
    assert burn and burn[0]["bound or tolerance"] == "≤ 0.012"
    assert burn[0]["verdict"].startswith("not met") and "cycle" in \
        burn[0]["verdict"]


def _check_limit(verdict: str, limit: str) -> None:
    """The bound-or-tolerance cell states the limit the verdict used."""
    verdict = verdict.replace("\\|", "|")          # Markdown escapes
    if verdict.startswith("not met: no value computed"):
        return
    if verdict.startswith("bound met") or (
            verdict.startswith("not met") and "|Δ|" not in verdict
            and limit.startswith("≤")):
        assert limit.startswith("≤ "), (verdict, limit)
    elif verdict.startswith("within tolerance"):
        used = re.match(r"within tolerance \(±([^)]+)\)", verdict)[1]
        assert limit == f"±{used}" or limit.endswith(f"(±{used})"), \
            (verdict, limit)
    elif verdict.startswith("not met: |Δ|"):
        used = re.match(r"not met: \|Δ\| = \S+ > (\S+)", verdict)[1]
        assert limit == f"±{used}" or limit.endswith(f"(±{used})"), \
            (verdict, limit)
    else:                   # erratum, no tolerance stated, no value
        assert limit in ("—", "") or limit.startswith("≤"), (verdict, limit)


def test_html_is_templated_with_full_size_figures(quick_report):
    html = (quick_report / "report.html").read_text()
    assert "520px" not in html and "`" not in html
    assert html.count('title="open full size"') >= 3
    assert "<code>allocation</code>" in html
    assert '<section id="references">' in html
    assert "Meteor-M No. 2" in html.split('id="references"')[1]
    assert 'class="text verdict-miss"' in html


def test_report_images_are_embedded(quick_report):
    html = (quick_report / "report.html").read_text()
    assert html.count("data:image/png;base64,") >= 3


def test_unknown_study_is_a_clear_error(tmp_path, capsys):
    assert main(["report", "--studies", "wheels,nosuch", "--out",
                 str(tmp_path)]) == 2
    assert "unknown study ['nosuch']" in capsys.readouterr().err


def test_report_workers_must_be_positive(tmp_path, capsys):
    assert main(["report", "--workers", "0", "--studies", "wheels",
                 "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "--workers must be >= 1" in err and len(err.splitlines()) == 1


def test_list_studies(capsys):
    assert main(["report", "--list"]) == 0
    out = capsys.readouterr().out
    assert all(key in out for key in STUDIES)


@pytest.mark.parametrize("argv, prog", [
    (["report", "--quik"], "adcs report"),
    (["report", "--workers", "x"], "adcs report"),
    (["bench", "--quik"], "adcs bench"),
    (["sweep", "agility", "--quik"], "adcs sweep"),
    (["spacecraft", "demo", "extra"], "adcs spacecraft"),
    (["--quik", "report"], "adcs"),
    (["reprt"], "adcs"),
])
def test_a_usage_mistake_is_one_line_with_its_commands_usage(argv, prog,
                                                             capsys):
    """The subcommand's usage, not the top level's; one line, exit 2."""
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1, err
    assert err[0].startswith(f"{prog}: error: ")
    assert f"; usage: {prog} [-h]" in err[0]
    if argv[:2] == ["report", "--quik"]:
        assert "unrecognized arguments: --quik;" in err[0]
        assert "[--quick] [--studies STUDIES]" in err[0]


def test_markdown_tables_keep_their_columns(quick_report):
    """Every row of every table has as many cells as its header."""
    import re

    md = (quick_report / "report.md").read_text().splitlines()
    split = re.compile(r"(?<!\\)\|")
    header = None
    for line in md:
        if not line.startswith("|"):
            header = None
            continue
        n = len(split.split(line)) - 2
        if header is None:
            header = n
        assert n == header, line


def test_report_records_how_it_was_made(tmp_path):
    from adcs import __version__

    assert main(["report", "--quick", "--studies", "spacecraft", "--out",
                 str(tmp_path)]) == 0
    md = (tmp_path / "report.md").read_text()
    for item in ("date (UTC)", "adcs-toolbox", "casadi", "git commit",
                 "machine", "run time"):
        assert f"| {item} |" in md
    assert f"| adcs-toolbox | {__version__} |" in md
    assert "how it was made" in (tmp_path / "report.html").read_text() \
        or "run time" in (tmp_path / "report.html").read_text()


def test_version_flag(capsys):
    import pytest

    from adcs import __version__

    with pytest.raises(SystemExit) as info:
        main(["--version"])
    assert info.value.code == 0
    assert capsys.readouterr().out.strip() == f"adcs-toolbox {__version__}"


def test_ctrl_c_keeps_the_finished_studies_and_exits_130(tmp_path, capsys,
                                                         monkeypatch):
    import adcs.studies.spacecraft as first
    import adcs.studies.wheels as second
    from adcs.report import Section, Table

    def done(ctx):
        return Section("spacecraft", "first", tables=[
            Table("t", ["a", "b"], [["x", 1.0]])])

    def stop(ctx):
        raise KeyboardInterrupt

    monkeypatch.setattr(first, "run", done)
    monkeypatch.setattr(second, "run", stop)
    code = main(["report", "--out", str(tmp_path), "--studies",
                 "spacecraft,wheels"])
    assert code == 130
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("adcs: interrupted: 1 of 2")
    md = (tmp_path / "report.md").read_text()
    assert "interrupted during" in md and "## first" in md
    assert (tmp_path / "report.html").exists()


# -- #26, the report: verdicts, limits, notes, labels, settling ----------
def _md_table(md: str, title: str) -> list[dict]:
    """Rows of the Markdown table under ``### title`` (cells unescaped)."""
    lines = md.split(f"### {title}", 1)[1].split("\n\n", 2)[1].splitlines()
    split = re.compile(r"(?<!\\)\|")
    cells = [[c.strip().replace("\\|", "|") for c in split.split(x)[1:-1]]
             for x in lines if x.startswith("|")]
    return [dict(zip(cells[0], row)) for row in cells[2:]]


def test_chibis_paper_figures_get_verdicts(quick_report):
    md = (quick_report / "report.md").read_text()
    pitch = {r["dipole scale"]: r for r in _md_table(
        md, "Pitch offset with the boom")}
    row = pitch["k = 0.1 A·m²"]
    assert row["paper [deg]"] == "6" and row["tolerance [deg]"] == "±0.5"
    assert abs(float(row["simulation, mean α [deg]"]) - 6.0) <= 0.5
    assert row["verdict"] == "within tolerance (±0.5)"
    spin = {r["quantity"]: r for r in _md_table(md, "Pitch-wheel spin-up")}
    time = spin["time to reach it [s]"]
    assert time["paper"] == "227.3" and time["bound or tolerance"] == \
        "±1 % (±2.273)"
    # 0.05 N·m·s at 2.2e-4 N·m: 227.27 s, not the output sample after it
    assert abs(float(time["ours"]) - 0.05 / 2.2e-4) < 0.5
    assert time["verdict"] == "within tolerance (±2.273)"
    assert spin["wheel momentum reached [N·m·s]"]["verdict"].startswith(
        "within tolerance")


def test_reach_time_is_read_off_the_ramp_not_the_grid():
    import numpy as np

    from adcs.studies.chibis import _reach_time

    t = np.linspace(0.0, 1000.0, 11)                  # samples every 100 s
    h = np.minimum(2.2e-4 * t, 0.05)
    assert _reach_time(t, h, 0.05) == pytest.approx(227.2727, rel=1e-6)
    assert np.isnan(_reach_time(t, 0.5 * h, 0.05))


def test_a_reason_of_many_rows_is_stated_once(quick_report):
    md = (quick_report / "report.md").read_text()
    rows = _md_table(md, "Reorientation: the paper's Table 5")
    noted = [r for r in rows if r["verdict"].endswith("(see note a)")]
    assert len(noted) >= 20
    assert md.count("20x the torque impulse the slew needs") == 1
    table = md.split("### Reorientation: the paper's Table 5", 1)[1]
    note = table.split("\n\n", 3)[2]
    assert "Note a: [4]'s groups each spent 8.6 N·s" in note


def test_shared_reasons_and_limit_text():
    from adcs.report import limit_text, shared_reasons

    rows, note = shared_reasons(["long why", "", "other", "long why",
                                 "twice", "twice"])
    assert rows == ["see note a", "", "other", "see note a", "see note b",
                    "see note b"]
    assert note == "Note a: long why. Note b: twice."
    assert limit_text(1.63, tol=0.01) == "±0.01"
    assert limit_text(0.35, rel=0.05) == "±5 % (±0.0175)"
    assert limit_text(None, bound=0.4) == "≤ 0.4"
    assert limit_text(2.0, erratum="misprint") == "—"
    assert limit_text("→ 0") == "—"


def test_failure_labels_name_every_failed_wheel():
    from allocation import WheelArray

    from adcs.studies.spacecraft import failed_label, failure_cases

    arr = WheelArray.pyramid().with_failed(2)               # wheel 3 out
    labels = [label for label, _ in failure_cases(arr)]
    assert labels == ["as given (wheel 3 failed)", "wheels 1 and 3 failed",
                      "wheels 2 and 3 failed", "wheels 3 and 4 failed"]
    assert [a.failed for _, a in failure_cases(arr)][1] == (0, 2)
    assert failed_label((4, 0, 2)) == "wheels 1, 3 and 5 failed"
    assert [lb for lb, _ in failure_cases(WheelArray.pyramid())][:2] == [
        "as given", "wheel 1 failed"]


def _result(**kw):
    """A `ClosedLoopResult` with the given metrics (no trajectory)."""
    from ocp.mpc import ClosedLoopResult

    base = dict(name="MPC test", trajectory=None, settle_time=0.0,
                settle_angle=0.0, energy=0.0, peak_torque=0.0,
                peak_momentum=0.0, torque_violation=0.0,
                momentum_violation=0.0, final_error=0.0, hold_error=0.0)
    return ClosedLoopResult(**{**base, **kw})


def test_mpc_settles_only_when_it_stays_within_the_band():
    import math

    import numpy as np

    from adcs.studies.spacecraft import mpc_row

    band = np.deg2rad(0.1)
    dipped = _result(settle_time=300.38, settle_angle=band,
                     hold_error=np.deg2rad(0.22), peak_torque=0.2)
    row, phrase = mpc_row(dipped, 10.0, 300.38)
    assert math.isnan(row[1]) and row[2] == "not settled to 0.1° in 300.4 s"
    assert "hold error 0.22° (band 0.1°)" in row[3]
    assert phrase == "MPC not settled to 0.1° in 300.4 s (hold error 0.22°)"
    held = _result(settle_time=21.83, settle_angle=band,
                   hold_error=np.deg2rad(0.03), peak_torque=0.05)
    row, phrase = mpc_row(held, 0.5, 30.0)
    assert row[1] == 21.83 and row[2] == "settled to 0.1°"
    assert phrase == "MPC settles to 0.1° in 21.83 s"


def test_a_craft_that_cannot_steer_gets_the_rank_message(tmp_path, capsys):
    """Two working wheels: the bench's 'rank 2 < 3', not a HiGHS message."""
    craft = tmp_path / "two.toml"
    craft.write_text('name = "two"\ninertia = [30.0, 27.0, 20.0]\n'
                     '[wheels]\npyramid = { delta_deg = 55.0, gamma_deg = '
                     '45.0 }\nh_max = 2.0\nm_max = 0.2\nfailed = [1, 3]\n')
    assert main(["report", "--quick", "--studies", "spacecraft",
                 "--spacecraft", str(craft), "--out",
                 str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["adcs: error: array: the working wheels span rank 2 < 3 "
                   "(failed wheels [1, 3]); no law can produce an arbitrary "
                   "torque"]
    assert "linprog" not in err[0] and "HiGHS" not in err[0]
