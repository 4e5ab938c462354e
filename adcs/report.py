"""`adcs report`: run the design studies and write an HTML/Markdown report."""

from __future__ import annotations

import base64
import html
import importlib
import math
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Sequence, TextIO

from adcs_common.exceptions import InvalidValueError
from adcs_common.paths import output_folder
from adcs.provenance import provenance
from ocp.spacecraft import load_spacecraft

#: study key -> (module in adcs.studies, title); the order of the report.
STUDIES: dict[str, tuple[str, str]] = {
    "spacecraft": ("spacecraft", "Your spacecraft through every tool"),
    "wheels": ("wheels", "Meteor-M No. 2 wheel pyramid ([1])"),
    "accuracy": ("accuracy", "Torque accuracy under mounting and "
                 "scale-factor errors ([1])"),
    "thrusters": ("thrusters", "Six-thruster unit in pulse-cycle mode "
                  "([4])"),
    "four_wheel": ("four_wheel", "Four-wheel nonlinear model (Lagrange)"),
    "chibis": ("chibis", "Chibis-M: coil and wheel failures, gravity boom "
               "([2])"),
    "slews": ("slews", "Slews: NLPs and MPC vs eigenaxis and quaternion "
              "feedback"),
}


@dataclass
class Table:
    """A table of the report.

    Attributes
    ----------
    title : str
    columns : list of str
    rows : list of list
        Cells: str, int or float (floats are printed with ``digits``).
    note : str
        Text under the table.
    flags : list of bool
        Per row: True marks an erratum / a paper value not reproduced.
    digits : int
        Significant digits for floats.
    """

    title: str
    columns: list[str]
    rows: list[list[Any]]
    note: str = ""
    flags: list[bool] = field(default_factory=list)
    digits: int = 5

    def cell(self, value: Any) -> str:
        """Format one cell."""
        if isinstance(value, float):
            if math.isnan(value):
                return "—"
            return f"{value:.{self.digits}g}"
        return str(value)


@dataclass
class Figure:
    """A PNG figure saved in the output folder."""

    filename: str
    caption: str


@dataclass
class Section:
    """One study's part of the report."""

    key: str
    title: str
    intro: str = ""
    tables: list[Table] = field(default_factory=list)
    figures: list[Figure] = field(default_factory=list)
    summary: list[str] = field(default_factory=list)
    seconds: float = 0.0


def paper_row(quantity: str, paper: float | str, ours: float,
              note: str = "") -> list[Any]:
    """Row ``quantity | paper | ours | difference | note``."""
    diff = ours - paper if isinstance(paper, (int, float)) else float("nan")
    return [quantity, paper, ours, diff, note]


PAPER_COLUMNS = ["quantity", "reference", "ours", "ours − paper", "note"]


@dataclass(frozen=True)
class StudyContext:
    """What a study gets: figure folder, quick switch, the user's craft.

    ``spacecraft`` (a `Spacecraft`, catalogue name, TOML path or None) is
    used by the studies that apply to any craft; the paper studies stay
    on their papers' craft. ``client`` (a `distributed.Client` or None)
    is where the heavy studies' cases run, through `sweep`.
    """

    out: Path
    quick: bool
    spacecraft: Any = None
    client: Any = None

    def sweep(self, study: Callable[..., dict], params: list[dict]):
        """Run a study's cases with `adcs.sweep.run_sweep`; a Dataset.

        On ``client``, or in this process when it is None. A case that
        raises is an error of the report, not a row to skip.
        """
        from adcs.sweep import SweepError, run_sweep

        ds = run_sweep(study, params, client=self.client, progress=False)
        failed = [str(e) for e in ds["error"].values if e]
        if failed:
            raise SweepError(f"{len(failed)} of {len(params)} cases of "
                             f"{study.__name__} failed: {failed[0]}")
        return ds

    def savefig(self, fig: Any, name: str) -> str:
        """Save a matplotlib figure as ``name`` in the output folder."""
        fig.savefig(self.out / name, dpi=110, bbox_inches="tight")
        import matplotlib.pyplot as plt

        plt.close(fig)
        return name


def _md_cell(text: str) -> str:
    """Escape a Markdown table cell (``|x|`` would split the column)."""
    return text.replace("|", "\\|")


def _markdown(sections: Sequence[Section], title: str,
              made: list[tuple[str, str]]) -> str:
    out = [f"# {title}", "", "| how it was made | |", "|---|---|"]
    out += [f"| {_md_cell(k)} | {_md_cell(v)} |" for k, v in made]
    out.append("")
    for s in sections:
        out += [f"## {s.title}", "", s.intro, ""]
        for t in s.tables:
            out += [f"### {t.title}", "",
                    "| " + " | ".join(map(_md_cell, t.columns)) + " |",
                    "|" + "---|" * len(t.columns)]
            for i, row in enumerate(t.rows):
                flag = t.flags[i] if i < len(t.flags) else False
                cells = [_md_cell(t.cell(v)) for v in row]
                if flag:
                    cells[0] = "⚠ " + cells[0]
                out.append("| " + " | ".join(cells) + " |")
            out += ["", t.note, ""] if t.note else [""]
        for f in s.figures:
            out += [f"![{f.caption}]({f.filename})", "", f"*{f.caption}*", ""]
    return "\n".join(out)


_CSS = """body{font-family:sans-serif;max-width:1100px;margin:auto;padding:1em}
table{border-collapse:collapse;margin:.5em 0}td,th{border:1px solid #bbb;
padding:3px 8px;text-align:right}td:first-child,th:first-child{text-align:left}
tr.erratum{background:#fff2cc}figure{display:inline-block;margin:.5em}
img{max-width:520px}.note{color:#444;font-size:90%}"""


def _html(sections: Sequence[Section], title: str, out: Path,
          made: list[tuple[str, str]]) -> str:
    esc = html.escape
    parts = [f"<!DOCTYPE html><html><head><meta charset='utf-8'>"
             f"<title>{esc(title)}</title><style>{_CSS}</style></head><body>",
             f"<h1>{esc(title)}</h1><table>"]
    parts += [f"<tr><td>{esc(k)}</td><td>{esc(v)}</td></tr>"
              for k, v in made]
    parts.append("</table><ul>")
    parts += [f"<li><a href='#{s.key}'>{esc(s.title)}</a></li>"
              for s in sections]
    parts.append("</ul>")
    for s in sections:
        parts.append(f"<section id='{s.key}'><h2>{esc(s.title)}</h2>"
                     f"<p>{esc(s.intro)}</p>")
        for t in s.tables:
            parts.append(f"<h3>{esc(t.title)}</h3><table><tr>" + "".join(
                f"<th>{esc(c)}</th>" for c in t.columns) + "</tr>")
            for i, row in enumerate(t.rows):
                flag = t.flags[i] if i < len(t.flags) else False
                cls = " class='erratum'" if flag else ""
                cells = [esc(t.cell(v)) for v in row]
                if flag:
                    cells[0] = "⚠ " + cells[0]
                parts.append(f"<tr{cls}>" + "".join(
                    f"<td>{c}</td>" for c in cells) + "</tr>")
            parts.append("</table>")
            if t.note:
                parts.append(f"<p class='note'>{esc(t.note)}</p>")
        for f in s.figures:
            data = base64.b64encode((out / f.filename).read_bytes()).decode()
            parts.append(f"<figure><img alt='{esc(f.caption)}' "
                         f"src='data:image/png;base64,{data}'>"
                         f"<figcaption>{esc(f.caption)}</figcaption></figure>")
        parts.append(f"<p class='note'>computed in {s.seconds:.1f} s</p>"
                     "</section>")
    parts.append("</body></html>")
    return "\n".join(parts)


def run_report(out: str | Path = "adcs-report", *, quick: bool = False,
               studies: Sequence[str] | None = None,
               stream: TextIO | None = sys.stdout,
               spacecraft: Any = None, client: Any = None
               ) -> list[Section]:
    """Run the studies and write ``report.html`` and ``report.md``.

    Parameters
    ----------
    out : str or Path
        Output folder (created).
    quick : bool
        Small settings (fewer directions and samples, coarser maps).
    studies : sequence of str, optional
        Keys of `STUDIES` to run (default all, in report order).
    stream : text stream or None
        Where progress and the summary are printed.
    spacecraft : ocp.spacecraft.Spacecraft, str or pathlib.Path, optional
        The craft of the studies that apply to any craft (a catalogue
        name or a TOML file; default the built-in ``demo``).
    client : distributed.Client, optional
        Where the heavy studies' cases (accuracy Monte Carlo blocks, slews
        against angle) run, as a sweep; None runs them in this process.

    Returns
    -------
    list of Section

    Raises
    ------
    InvalidValueError
        An unknown study key.
    KeyboardInterrupt
        Ctrl-C during a study: the report of the studies finished before
        it is written first (its title says so), and the message names it.
    """
    import matplotlib

    matplotlib.use("Agg")
    keys = list(STUDIES) if not studies else list(studies)
    unknown = [k for k in keys if k not in STUDIES]
    if unknown:
        raise InvalidValueError(
            f"unknown study {unknown}; choose from {', '.join(STUDIES)}")
    if spacecraft is not None:
        spacecraft = load_spacecraft(spacecraft)
    out = output_folder(out, "out")
    ctx = StudyContext(out, quick, spacecraft, client)
    say: Callable[[str], None] = (lambda msg: print(msg, file=stream,
                                                    flush=True)) \
        if stream is not None else (lambda msg: None)
    sections = []
    t_all = time.perf_counter()
    stopped = None
    for i, key in enumerate(keys, 1):
        module, title = STUDIES[key]
        say(f"[{i}/{len(keys)}] {title} ...")
        t0 = time.perf_counter()
        try:
            study = importlib.import_module(f"adcs.studies.{module}")
            section = study.run(ctx)
        except KeyboardInterrupt:
            stopped = title
            break
        section.seconds = time.perf_counter() - t0
        sections.append(section)
        for line in section.summary:
            say(f"      {line}")
        say(f"      done in {section.seconds:.1f} s")
    title = "ADCS toolbox report" + (" (quick)" if quick else "")
    if stopped is not None:
        title += (f" (interrupted during {stopped!r}: {len(sections)} of "
                  f"{len(keys)} studies)")
    made = provenance(time.perf_counter() - t_all)
    (out / "report.md").write_text(_markdown(sections, title, made))
    (out / "report.html").write_text(_html(sections, title, out, made))
    if stopped is not None:
        raise KeyboardInterrupt(
            f"{len(sections)} of {len(keys)} studies finished, saved in "
            f"{out / 'report.html'}")
    say(f"wrote {out / 'report.html'} and {out / 'report.md'} "
        f"in {time.perf_counter() - t_all:.1f} s")
    return sections
