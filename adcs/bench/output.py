"""The bench's table, plot and JSON file."""

from __future__ import annotations

import json
from dataclasses import asdict
from pathlib import Path
from typing import Any, Sequence, TYPE_CHECKING

import numpy as np

from .core import PROBLEMS, TOL, BenchRow

if TYPE_CHECKING:
    import pandas as pd



def format_table(rows: Sequence[BenchRow]) -> str:
    """Markdown table: median/p99 time, error, KKT, failures, wrong, note."""
    lines = ["| problem | backend | median [µs] | p99 [µs] | max error | "
             "max KKT | failed | wrong | note |", "|" + "---|" * 9]
    for r in rows:
        kkt = "–" if np.isnan(r.max_kkt) else f"{r.max_kkt:.1e}"
        lines.append(
            f"| {r.problem} | {r.backend} | {1e6 * r.median_s:.1f} | "
            f"{1e6 * r.p99_s:.1f} | {r.max_error:.1e} | {kkt} | "
            f"{r.failures}/{r.n} | {r.wrong}/{r.n} | {r.note} |")
    return "\n".join(lines)


def to_frame(rows: Sequence[BenchRow]) -> pd.DataFrame:
    """Rows as a `pandas.DataFrame` (one row per problem and backend)."""
    import pandas as pd

    frame = pd.DataFrame([asdict(r) for r in rows])
    if len(frame):
        frame["ok"] = [r.ok for r in rows]
        frame["too_slow"] = [r.too_slow for r in rows]
    return frame


def write_json(path: Path, rows: Sequence[BenchRow], meta: dict[str, Any]
               ) -> None:
    """Write ``bench.json``: ``meta`` (settings, provenance) and the rows."""
    path.write_text(json.dumps({**meta, "tolerance": TOL,
                                "rows": [asdict(r) for r in rows]},
                               indent=2))


def plot(rows: Sequence[BenchRow], path: Path) -> None:
    """Bar chart of median solve times, one panel per problem.

    Green: every answer checked; red: failed or wrong answers (the bar
    is their median time where any solve returned, else a label);
    hatched: cut short by the time budget. Log axis from a decade below
    the fastest bar.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Patch

    problems = [p for p in PROBLEMS if any(r.problem == p for r in rows)]
    fig, axes = plt.subplots(len(problems), 1, squeeze=False,
                             figsize=(8, 2.4 + 0.38 * len(rows)))
    for ax, prob in zip(axes[:, 0], problems):
        sub = [r for r in rows if r.problem == prob]
        y = np.arange(len(sub))
        t = np.array([1e6 * r.median_s for r in sub])
        finite = t[np.isfinite(t)]
        lo = 10 ** np.floor(np.log10(finite.min())) / 10 if finite.size \
            else 1.0
        for k, r in enumerate(sub):
            color = "tab:green" if r.ok else "tab:red"
            if np.isfinite(t[k]):
                ax.barh(k, t[k] - lo, left=lo, color=color,
                        hatch="//" if r.too_slow else None,
                        edgecolor="black" if r.too_slow else color)
            else:
                ax.text(lo * 1.2, k, "failed: no answer", va="center",
                        color="tab:red")
        ax.set_xscale("log")
        ax.set_xlim(left=lo)
        ax.set_yticks(y, [r.backend for r in sub])
        ax.invert_yaxis()
        ax.set_title(prob)
        ax.set_xlabel("median time per solve [µs]")
    axes[0, 0].legend(handles=[
        Patch(color="tab:green", label="every answer checked"),
        Patch(color="tab:red", label="failed or wrong answers"),
        Patch(facecolor="white", edgecolor="black", hatch="//",
              label="too slow (budget spent)")],
        loc="lower right", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
