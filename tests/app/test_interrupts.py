"""Ctrl-C as a user presses it: a real SIGINT, delivered to a running
`adcs` process while CasADi is solving, ends it with one line and exit
status 130 and keeps every finished row and study."""

import json
import subprocess
import sys
import textwrap

import pytest

#: Runs ``adcs`` in a child process; the first call of ``TARGET`` arms a
#: timer that sends the process a real SIGINT ``DELAY`` s later, while
#: the call is inside CasADi.
_CHILD = textwrap.dedent("""
    import os, signal, sys, threading
    import importlib
    mod_name, attr, delay = sys.argv[1], sys.argv[2], float(sys.argv[3])
    cls_name, _, meth = attr.rpartition(".")
    mod = importlib.import_module(mod_name)
    owner = getattr(mod, cls_name) if cls_name else mod
    orig = getattr(owner, meth)
    armed = []

    def patched(*a, **k):
        if not armed:
            armed.append(1)
            threading.Timer(delay, os.kill,
                            (os.getpid(), signal.SIGINT)).start()
        return orig(*a, **k)

    setattr(owner, meth, patched)
    from adcs.cli import main
    sys.exit(main(sys.argv[4:]))
""")


def run_interrupted(target: str, delay: float, argv: list[str]):
    mod, _, attr = target.partition(":")
    return subprocess.run(
        [sys.executable, "-c", _CHILD, mod, attr, str(delay), *argv],
        capture_output=True, text=True, timeout=300)


def test_ctrl_c_inside_a_casadi_solve_keeps_the_bench_rows(tmp_path):
    """SIGINT while IPOPT solves the slew problem: the wheels rows that
    finished are in bench.json, one line on stderr, exit 130."""
    pytest.importorskip("casadi")
    out = tmp_path / "bench"
    run = run_interrupted(
        "ocp.mpc.controller:AttitudeMPC.step", 0.02,
        ["bench", "--quick", "--problems", "wheels,slew", "--backends",
         "daqp,ipopt", "--out", str(out), "--no-progress"])
    assert run.returncode == 130, run.stderr[-2000:]
    err = [line for line in run.stderr.splitlines() if line.strip()]
    assert len(err) == 1 and err[0].startswith("adcs: interrupted"), err
    saved = json.loads((out / "bench.json").read_text())
    assert saved["interrupted_during"] == "slew"
    rows = saved["rows"] if isinstance(saved, dict) and "rows" in saved \
        else saved
    assert any(r["problem"] == "wheels" for r in rows), saved


def test_ctrl_c_inside_a_study_keeps_the_finished_studies(tmp_path):
    """SIGINT while the slews study solves an NLP: the report of the
    studies before it is written, one line on stderr, exit 130."""
    out = tmp_path / "report"
    run = run_interrupted(
        "ocp.slews.nlp:solve_clear_of_cones", 0.02,
        ["report", "--quick", "--studies", "wheels,slews", "--out",
         str(out)])
    assert run.returncode == 130, run.stderr[-2000:]
    last = [line for line in run.stderr.splitlines() if line.strip()][-1]
    assert last.startswith("adcs: interrupted") and "1 of 2" in last
    html = (out / "report.html").read_text()
    assert "interrupted during" in html
