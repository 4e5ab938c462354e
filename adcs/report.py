"""`adcs report`: run the design studies and write an HTML/Markdown report."""

from __future__ import annotations

import base64
import importlib
import math
import re
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Sequence, TextIO

from jinja2 import Environment, PackageLoader, select_autoescape
from markupsafe import Markup, escape

from adcs_common.exceptions import InvalidValueError
from adcs_common.interrupts import check as check_interrupt
from adcs_common.interrupts import interrupted
from adcs_common.paths import output_folder
from adcs.provenance import provenance
from ocp.spacecraft import load_spacecraft

#: study key -> (module in adcs.studies, title); the order of the report.
STUDIES: dict[str, tuple[str, str]] = {
    "spacecraft": ("spacecraft", "Your spacecraft through every tool"),
    "wheels": ("wheels", "Meteor-M No. 2 wheel pyramid ([1])"),
    "design": ("design", "Which array should I fly? Nominal against "
               "single-failure radius"),
    "methods": ("methods", "Which allocation law should my flight "
                "software run? The literature's methods beside the exact "
                "QP"),
    "accuracy": ("accuracy", "Torque accuracy under mounting and "
                 "scale-factor errors ([1])"),
    "thrusters": ("thrusters", "Six-thruster unit in pulse-cycle mode "
                  "([4])"),
    "four_wheel": ("four_wheel", "Four-wheel nonlinear model (Lagrange)"),
    "chibis": ("chibis", "Chibis-M: coil and wheel failures, gravity boom "
               "([2])"),
    "slews": ("slews", "Slews: NLPs and MPC vs eigenaxis and quaternion "
              "feedback"),
    "robust": ("robust", "What does robustness cost, and what does it "
               "buy? Nominal against robust MPC over a Monte Carlo"),
    "basilisk": ("basilisk", "In Basilisk: rwMotorTorque vs the bounded QP "
                 "(optional extra)"),
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
        Per row: True marks an erratum / a paper value not reproduced
        (derived from a "verdict" column when not given).
    digits : int
        Significant digits for floats.
    """

    title: str
    columns: list[str]
    rows: list[list[Any]]
    note: str = ""
    flags: list[bool] = field(default_factory=list)
    digits: int = 5

    def __post_init__(self) -> None:
        """Flag the rows whose verdict is a miss or an erratum."""
        if not self.flags and "verdict" in self.columns:
            k = self.columns.index("verdict")
            self.flags = [str(r[k]).startswith(("not met", "erratum"))
                          for r in self.rows]

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


def _num(v: float) -> str:
    return f"{v:.4g}"


def verdict(paper: float | str | None, ours: float, *,
            tol: float | None = None, rel: float | None = None,
            bound: float | None = None, erratum: str = "",
            reason: str = "") -> str:
    """Judge ``ours`` against a paper's figure; a short sentence.

    ``bound``: ours must not exceed it; ``tol``/``rel``: absolute or
    relative tolerance around ``paper``; ``erratum``: the paper's value is
    a misprint (the text says which). ``reason`` explains a miss. The
    verdict starts with "within tolerance", "bound met", "not met",
    "erratum" or "no tolerance stated".
    """
    why = f" ({reason})" if reason else ""
    if erratum:
        return f"erratum: {erratum}"
    if not isinstance(ours, (int, float)) or math.isnan(float(ours)):
        return "not met: no value computed" + why
    if bound is not None:
        if ours <= bound * (1.0 + 1e-12) + 1e-300:
            return "bound met"
        return f"not met: {_num(ours)} > {_num(bound)}" + why
    if not isinstance(paper, (int, float)):
        return "no tolerance stated" + why
    diff = abs(float(ours) - float(paper))
    limit = tol if tol is not None else (
        None if rel is None else rel * abs(float(paper)))
    if limit is None:
        return "no tolerance stated" + why
    if diff <= limit:
        return f"within tolerance (±{_num(limit)})"
    return f"not met: |Δ| = {_num(diff)} > {_num(limit)}" + why


def limit_text(paper: float | str | None, *, tol: float | None = None,
               rel: float | None = None, bound: float | None = None,
               erratum: str = "") -> str:
    """The bound or tolerance a row is judged by, as the table prints it.

    ``≤ b`` for a bound; ``±t`` for an absolute tolerance; ``±r %
    (±t)`` for a relative one (``t`` in the quantity's unit); ``—`` when
    the row has none (an erratum, or no tolerance stated).
    """
    if erratum:
        return "—"
    if bound is not None:
        return f"≤ {_num(bound)}"
    if not isinstance(paper, (int, float)):
        return "—"
    if tol is not None:
        return f"±{_num(tol)}"
    if rel is not None:
        return f"±{100 * rel:g} % (±{_num(rel * abs(float(paper)))})"
    return "—"


def paper_row(quantity: str, paper: float | str | None, ours: float,
              note: str = "", *, tol: float | None = None,
              rel: float | None = None, bound: float | None = None,
              erratum: str = "", reason: str = "") -> list[Any]:
    """Row of `PAPER_COLUMNS`: the figures, the bound and a verdict.

    The bound or tolerance used goes in its own column (`limit_text`:
    ``≤ b``, ``±t`` or ``±r % (±t)``); the verdict is `verdict`'s.
    """
    diff = (ours - paper if isinstance(paper, (int, float))
            and isinstance(ours, (int, float)) else float("nan"))
    return [quantity, "—" if paper is None else paper,
            limit_text(paper, tol=tol, rel=rel, bound=bound,
                       erratum=erratum), ours, diff,
            verdict(paper, ours, tol=tol, rel=rel, bound=bound,
                    erratum=erratum, reason=reason), note]


PAPER_COLUMNS = ["quantity", "paper", "bound or tolerance", "ours",
                 "ours − paper", "verdict", "note"]


def shared_reasons(reasons: Sequence[str], *, at_least: int = 2
                   ) -> tuple[list[str], str]:
    """State a reason given for several rows once, under the table.

    Returns ``(per_row, note)``: each reason given for ``at_least`` rows
    or more becomes ``"see note a"`` (b, c, ... for the next ones) in
    ``per_row``, and ``note`` holds ``"Note a: <reason>."`` once each;
    the other reasons are kept as they are.
    """
    counts: dict[str, int] = {}
    for r in reasons:
        if r:
            counts[r] = counts.get(r, 0) + 1
    letters: dict[str, str] = {}
    for r in reasons:
        if r and counts[r] >= at_least and r not in letters \
                and len(letters) < 26:
            letters[r] = "abcdefghijklmnopqrstuvwxyz"[len(letters)]
    per_row = [f"see note {letters[r]}" if r in letters else r
               for r in reasons]
    note = " ".join(f"Note {k}: {r.rstrip('.')}." for r, k in
                    letters.items())
    return per_row, note


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
    out += ["## References", ""]
    out += [f"{i}. {ref}" for i, ref in enumerate(REFERENCES, 1)]
    return "\n".join(out) + "\n"


#: The source papers, as the report's References list them (the full
#: entries, with what is and is not known of each, are docs/references.md).
REFERENCES = (
    "A. D. Belenky, V. N. Vasiliev, A. S. Semenov, M. E. Semenov. A control "
    "algorithm for the four reaction-wheel system of the Meteor-M No. 2 "
    "series spacecraft. OAO Corporation VNIIEM, 2013.",
    "M. Ovchinnikov, S. Tkachev, D. Roldugin. Attitude control system "
    "failure cases response using operational actuators (Chibis-M). "
    "Preprint No. 83, 2013.",
    "A. S. Kulik, A. G. Gordin, O. V. Reznikova. Nonlinear model of the "
    "spacecraft with four reaction wheels (venue and year not stated in "
    "the copy used).",
    "The pulse-cycle mode of a six-thruster propulsion unit for "
    "translation with wheel unloading and for reorientation (authors, "
    "title, venue and year not stated in the copy used).",
)

_CODE = re.compile(r"`([^`]+)`")


def _inline(text: Any) -> Markup:
    """Escape ``text`` for HTML and show its `code` spans as code."""
    return Markup(_CODE.sub(lambda m: f"<code>{m.group(1)}</code>",
                            str(escape(str(text)))))


def _cell_class(column: str, value: Any) -> str:
    if column == "verdict":
        miss = str(value).startswith(("not met", "erratum"))
        return "text verdict-miss" if miss else "text verdict-met"
    return "" if isinstance(value, (int, float)) else "text"


def _html(sections: Sequence[Section], title: str, out: Path,
          made: list[tuple[str, str]]) -> str:
    """Render ``report.html`` from its Jinja2 template (figures inline)."""
    env = Environment(loader=PackageLoader("adcs", "templates"),
                      autoescape=select_autoescape(["html", "j2"]),
                      trim_blocks=True, lstrip_blocks=True)
    env.filters["inline"] = _inline
    images = {f.filename: base64.b64encode(
        (out / f.filename).read_bytes()).decode()
        for s in sections for f in s.figures}
    return env.get_template("report.html.j2").render(
        title=title, made=made, sections=sections, images=images,
        references=REFERENCES, cell_class=_cell_class)


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
    from tqdm.auto import tqdm

    # a bar with ETA on a terminal (tqdm's test: None), beside the lines
    bar = tqdm(total=len(keys), unit="study", file=sys.stderr,
               disable=None if stream is not None else True)
    stopped = None
    for i, key in enumerate(keys, 1):
        module, title = STUDIES[key]
        say(f"[{i}/{len(keys)}] {title} ...")
        t0 = time.perf_counter()
        try:
            study = importlib.import_module(f"adcs.studies.{module}")
            check_interrupt()
            section = study.run(ctx)
            check_interrupt()          # a solver that swallowed Ctrl-C
        except BaseException as exc:
            if not interrupted(exc):       # CasADi wraps Ctrl-C
                raise
            stopped = title
            break
        section.seconds = time.perf_counter() - t0
        sections.append(section)
        for line in section.summary:
            say(f"      {line}")
        say(f"      done in {section.seconds:.1f} s")
        bar.update(1)
    bar.close()
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
