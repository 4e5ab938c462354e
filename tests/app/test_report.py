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
    header = "| quantity | paper | bound | ours | ours − paper | verdict |"
    assert md.count(header) >= 3
    # theory §1.2 inscribed radius, computed, judged by its tolerance
    assert re.search(r"inscribed sphere radius r \| 1.63 \|  \| 1.6303 \| "
                     r"[0-9.e-]+ \| within tolerance \(±0.01\)", md)
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
            assert row["verdict"].startswith((
                "within tolerance", "bound met", "not met", "erratum",
                "no tolerance stated")), row
            missed = row["verdict"].startswith(("not met", "erratum"))
            assert cells[0].startswith("⚠") == missed, row
            if row.get("bound"):
                assert row["bound"].startswith("≤ ")
    assert len(verdicts) > 60
    # the burn's momentum excursion: a bound not met, with its reason
    burn = [v for v in verdicts if v.get("quantity", "").startswith(
        "⚠ max \\|H_X\\|, \\|H_Z\\| during")]
    assert burn and burn[0]["bound"] == "≤ 0.012"
    assert burn[0]["verdict"].startswith("not met") and "cycle" in \
        burn[0]["verdict"]


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


def test_bad_option_exits_with_usage(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["report", "--fast"])
    assert exc.value.code == 2


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
