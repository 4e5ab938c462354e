"""Ctrl-C during ``adcs sweep``, as a terminal delivers it: a real SIGINT
to the whole process group (the command and its Dask workers) once a
chunk is saved. The sweep ends with one line and exit status 130, and
the next run resumes every chunk saved before the Ctrl-C."""

import re
import subprocess
import sys
import textwrap

import pytest

pytest.importorskip("distributed")

#: Runs ``adcs`` in a child process (its own session: the group is the
#: command and its workers); the first saved chunk arms a timer that
#: sends the group SIGINT ``DELAY`` s later, while the next chunks run.
_CHILD = textwrap.dedent("""
    import os, signal, sys, threading
    import adcs.sweep.engine as engine
    delay = float(sys.argv[1])
    orig = engine._keep
    armed = []

    def patched(*a, **k):
        rows = orig(*a, **k)
        if not armed:
            armed.append(1)
            threading.Timer(delay, os.killpg,
                            (os.getpgid(0), signal.SIGINT)).start()
        return rows

    engine._keep = patched
    from adcs.cli import main
    sys.exit(main(sys.argv[2:]))
""")


def _sweep(argv, delay=None):
    cmd = ([sys.executable, "-c", _CHILD, str(delay), *argv]
           if delay is not None else
           [sys.executable, "-m", "adcs.cli", *argv])
    return subprocess.run(cmd, capture_output=True, text=True, timeout=300,
                          start_new_session=True)


@pytest.mark.parametrize("name, where, delay", [
    ("agility", ["--quick", "--sync"], 0.05),       # inside CasADi here
    ("geometry", ["--workers", "2"], 0.3),         # on a LocalCluster
], ids=["in-process", "local-cluster"])
def test_ctrl_c_during_a_sweep_keeps_the_saved_chunks(tmp_path, name,
                                                       where, delay):
    out = tmp_path / "sweep"
    argv = ["sweep", name, *where, "--out", str(out), "--no-progress"]
    run = _sweep(argv, delay)
    assert run.returncode == 130, run.stderr[-3000:]
    err = [line for line in run.stderr.splitlines() if line.strip()]
    assert len(err) == 1, run.stderr[-3000:]
    match = re.fullmatch(r"adcs: interrupted: (\d+) of (\d+) chunks saved "
                         r"in .*: rerun to resume", err[0])
    assert match, err
    saved, total = int(match[1]), int(match[2])
    assert 1 <= saved < total
    assert len(list((out / "chunks").glob("*.json"))) == saved
    assert not (out / f"{name}.nc").exists()

    again = _sweep(argv)
    assert again.returncode == 0, again.stderr[-3000:]
    assert f"({saved} of {total} chunks resumed)" in again.stdout
