"""Compiling generated C: one path, a private cache, checked libraries."""

import os
from pathlib import Path
import shutil
import threading

import casadi as ca
import numpy as np
import pytest

from adcs_common.codegen import (
    CompileError,
    CompilerNotFound,
    UnsafeCacheError,
    cached_library,
    compile_c,
    find_compiler,
    generate_c,
    solver_dependencies,
)

pytestmark = pytest.mark.skipif(
    not any(shutil.which(c) for c in ("cc", "gcc", "clang")),
    reason="needs a C compiler")

X = ca.SX.sym("x", 3)
F = ca.Function("f", [X], [ca.sin(X) * 2.0])


def _build(folder):
    src = generate_c([F], folder, "f")
    return lambda out: compile_c([src], out, opt="-O1")


def test_generated_library_equals_the_function(tmp_path):
    lib = cached_library(tmp_path / "cache", "f", _build(tmp_path))
    ext = ca.external("f", str(lib))
    x = np.array([0.1, -0.7, 2.0])
    np.testing.assert_array_equal(np.asarray(ext(x)).ravel(),
                                  np.asarray(F(x)).ravel())
    assert (tmp_path / "cache").stat().st_mode & 0o777 == 0o700
    assert lib.stat().st_mode & 0o777 == 0o600


def test_generation_never_changes_the_working_directory(tmp_path):
    cwd = os.getcwd()
    seen = []

    def watch():
        for _ in range(200):
            seen.append(os.getcwd())

    t = threading.Thread(target=watch)
    t.start()
    x = ca.SX.sym("x", 2)
    S = ca.nlpsol("s", "ipopt", {"x": x, "f": ca.sumsqr(x - 1)},
                  {"print_time": False, "ipopt": {"print_level": 0}})
    src = generate_c(solver_dependencies(S), tmp_path, "s_nlp")
    t.join()
    assert set(seen) == {cwd} and src.exists()
    lib = compile_c([src], tmp_path / "s_nlp.so")
    S2 = ca.nlpsol("s", "ipopt", str(lib),
                   {"print_time": False, "ipopt": {"print_level": 0}})
    np.testing.assert_allclose(np.asarray(S2(x0=0)["x"]).ravel(), [1, 1],
                               atol=1e-8)


def test_a_cache_others_can_write_to_is_refused(tmp_path):
    cache = tmp_path / "shared"
    cache.mkdir()
    cache.chmod(0o777)
    with pytest.raises(UnsafeCacheError, match="writable by others"):
        cached_library(cache, "f", _build(tmp_path))
    assert not (cache / "f.so").exists()


def test_a_tampered_library_is_rebuilt_not_loaded(tmp_path):
    cache = tmp_path / "cache"
    lib = cached_library(cache, "f", _build(tmp_path))
    good = lib.read_bytes()
    lib.write_bytes(b"\x7fELF planted by someone else")
    again = cached_library(cache, "f", _build(tmp_path))
    assert again == lib and again.read_bytes() == good


def test_compiler_errors_are_the_toolboxs_own(tmp_path):
    bad = tmp_path / "bad.c"
    bad.write_text("int main( {")
    with pytest.raises(CompileError, match="compilation failed"):
        compile_c([bad], tmp_path / "bad.so")
    with pytest.raises(CompilerNotFound, match="no-such-cc"):
        find_compiler("no-such-cc")


def test_compile_progress_wraps_a_blocking_build():
    import time

    from adcs_common.codegen import compile_progress

    with compile_progress("compiling") as bar:
        time.sleep(0.6)          # the helper thread refreshes meanwhile
    assert bar.disable or bar.n == 0


def _fake_build(out):
    """A stand-in build (no compiler): the cache logic only."""
    Path(out).write_bytes(b"library bytes")


@pytest.mark.parametrize("kind", ["fifo", "devzero", "link"])
def test_a_library_that_is_no_regular_file_is_never_read(tmp_path, kind):
    """Issue #23 item 15: the cache followed a FIFO (hang) or a link to
    /dev/zero (memory exhausted) when hashing it."""
    cache = tmp_path / "cache"
    cached_library(cache, "f", _fake_build)
    lib = cache / "f.so"
    lib.unlink()
    if kind == "fifo":
        os.mkfifo(lib)
    elif kind == "devzero":
        lib.symlink_to("/dev/zero")
    else:
        (tmp_path / "elsewhere.so").write_bytes(b"library bytes")
        lib.symlink_to(tmp_path / "elsewhere.so")
    again = cached_library(cache, "f", _fake_build)
    assert again == lib and not lib.is_symlink()
    assert lib.read_bytes() == b"library bytes"


def test_a_record_that_is_a_fifo_is_never_read(tmp_path):
    cache = tmp_path / "cache"
    cached_library(cache, "f", _fake_build)
    (cache / "f.sha256").unlink()
    os.mkfifo(cache / "f.sha256")
    assert cached_library(cache, "f", _fake_build).read_bytes() \
        == b"library bytes"


@pytest.mark.parametrize("stem", ["../evil", "a/b", ".hidden", "", "x" * 200,
                                  None, "a\nb"])
def test_a_stem_that_leaves_the_cache_is_refused(tmp_path, stem):
    from adcs_common.exceptions import InvalidValueError

    with pytest.raises(InvalidValueError, match="plain file name"):
        cached_library(tmp_path / "cache", stem, _fake_build)
    assert not (tmp_path / "evil.so").exists()
    assert list(tmp_path.rglob("*.so")) == []


def test_a_compilation_past_its_timeout_is_stopped_with_its_children(
        tmp_path):
    """#27: the export's compile timeout raised an uncaught TimeoutExpired
    and left the compiler proper running. Now: CompileError, and no
    process of the build survives."""
    import os
    import stat as st_mod
    import subprocess
    import time

    from adcs_common.codegen import CompileError, compile_c

    # a "compiler" that starts a long-lived child, as gcc starts cc1
    cc = tmp_path / "slowcc"
    marker = tmp_path / "child.pid"
    cc.write_text("#!/bin/sh\nsleep 60 &\necho $! > " + str(marker)
                  + "\nwait\n")
    cc.chmod(cc.stat().st_mode | st_mod.S_IEXEC)
    src = tmp_path / "a.c"
    src.write_text("int f(void) { return 1; }\n")
    t0 = time.perf_counter()
    with pytest.raises(CompileError, match="longer than 0.5 s"):
        compile_c([src], tmp_path / "a.so", cc=str(cc), timeout=0.5)
    assert time.perf_counter() - t0 < 10.0
    pid = int(marker.read_text())
    time.sleep(0.2)
    try:
        os.kill(pid, 0)
        # a zombie is dead: only a running child would be a leak
        state = subprocess.run(["ps", "-o", "stat=", "-p", str(pid)],
                               capture_output=True, text=True).stdout
        assert state.strip().startswith("Z") or not state.strip()
    except ProcessLookupError:
        pass
