"""Compiling CasADi-generated C: one compiler lookup, one build, one cache.

Every package that turns a ``casadi.Function`` into a shared library goes
through here: `find_compiler` (``$CC``, then ``cc``, ``gcc``, ``clang``),
`generate_c` (writes into a folder, never changes the working directory,
so it is safe from threads), `compile_c` (one error type,
`CompileError`, with the compiler's output) and `cached_library`, which
keeps libraries in a folder only the user can write and checks each
library's SHA-256 before it is loaded.
"""

from __future__ import annotations

import contextlib
import threading

import hashlib
import os
import re
import shutil
import stat
import subprocess
import tempfile
from pathlib import Path
from typing import Callable, Sequence

import casadi as ca

from .exceptions import AdcsError, InvalidValueError

__all__ = [
    "CompileError",
    "CompilerNotFound",
    "UnsafeCacheError",
    "cached_library",
    "compile_c",
    "find_compiler",
    "generate_c",
    "private_folder",
    "solver_dependencies",
]


class CompilerNotFound(AdcsError, RuntimeError):
    """No C compiler to build generated code with.

    Attributes
    ----------
    cc : str
        The compiler asked for (or the ones tried).
    """

    def __init__(self, cc: str) -> None:
        super().__init__(
            f"C compiler {cc!r} not found on PATH; install one (e.g. "
            "apt-get install gcc) or name another with cc= / $CC")
        self.cc = cc


class CompileError(AdcsError, RuntimeError):
    """The C compiler failed; the message ends with its output."""


class UnsafeCacheError(AdcsError, PermissionError):
    """A cache folder others could write to: its code will not be run."""


def find_compiler(cc: str | None = None) -> str:
    """Return the C compiler ``cc``, else ``$CC``, ``cc``, ``gcc``, ``clang``.

    Raises
    ------
    CompilerNotFound
        None of them is on PATH.
    """
    names = [cc] if cc else [os.environ.get("CC"), "cc", "gcc", "clang"]
    for name in filter(None, names):
        path = shutil.which(name)
        if path:
            return path
    raise CompilerNotFound(cc or "cc/gcc/clang")


def solver_dependencies(solver: ca.Function) -> list[ca.Function]:
    """List the Functions ``solver.generate_dependencies`` writes, in order.

    An nlpsol built on an oracle loads them back from a library
    (``ca.nlpsol(name, plugin, library, opts)``).
    """
    return [solver.oracle()] + [solver.get_function(n)
                                for n in solver.get_function()]


def generate_c(functions: Sequence[ca.Function], folder, name: str,
               options: dict | None = None) -> Path:
    """Write the C of ``functions`` to ``folder/name.c`` (no ``chdir``)."""
    cg = ca.CodeGenerator(f"{name}.c", dict(options or {}))
    for f in functions:
        cg.add(f)
    cg.generate(f"{Path(folder)}/")
    return Path(folder) / f"{name}.c"


def compile_c(sources: Sequence, output, *, cc: str | None = None,
              opt: str = "-O2", shared: bool = True,
              flags: Sequence[str] = (), libs: Sequence[str] = ("-lm",),
              timeout: float = 900.0,
              log: list[str] | None = None) -> Path:
    """Compile C ``sources`` to ``output`` (a shared library by default).

    Parameters
    ----------
    sources : sequence of path
        C files (or objects) to build.
    output : path
        The library or executable to write.
    cc : str, optional
        Compiler (default: `find_compiler`).
    opt : str
        Optimisation flag, e.g. ``"-O1"`` (quick to build), ``"-O3"``.
    shared : bool
        Build a shared library (``-shared -fPIC``); else an executable.
    flags, libs : sequence of str
        Extra compiler flags (before the sources) and libraries (after).
    log : list of str, optional
        Receives the compiler's messages (warnings) of a successful build.
    timeout : float
        Seconds the compilation may take; beyond them it is stopped with
        every process it started, and `CompileError` says so.

    Raises
    ------
    CompilerNotFound, CompileError
    """
    cmd = [find_compiler(cc), opt, *(["-shared", "-fPIC"] if shared
                                     else []), *flags,
           *[str(s) for s in sources], "-o", str(output), *libs]
    # its own process group: on a timeout the compiler proper (cc1), not
    # only the gcc driver, is stopped
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    try:
        _, stderr = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        _kill_group(proc)
        raise CompileError(
            f"compilation took longer than {timeout:g} s and was stopped "
            f"(every process of it): {' '.join(cmd)[:300]}") from None
    except BaseException:          # Ctrl-C: no compiler left running
        _kill_group(proc)
        raise
    if proc.returncode != 0:
        raise CompileError(f"compilation failed: {' '.join(cmd)}\n"
                           f"{stderr.strip()[-2000:]}")
    if log is not None and stderr.strip():
        log.append(stderr)
    return Path(output)


def _kill_group(proc: subprocess.Popen) -> None:
    """Stop ``proc`` and every process of its group, and reap it."""
    import signal

    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError, AttributeError):
        proc.kill()
    proc.communicate()


def private_folder(path) -> Path:
    """Create (mode 0700) or check a folder only the user can write.

    Raises
    ------
    UnsafeCacheError
        The folder belongs to someone else or its group or others may
        write to it (a library planted there would run with the user's
        rights).
    """
    p = Path(path).expanduser()
    p.mkdir(mode=0o700, parents=True, exist_ok=True)
    st = p.stat()
    if hasattr(os, "getuid") and st.st_uid != os.getuid():
        raise UnsafeCacheError(
            f"cache folder {p} belongs to uid {st.st_uid}, not to you: "
            "its libraries will not be loaded")
    if st.st_mode & (stat.S_IWGRP | stat.S_IWOTH):
        raise UnsafeCacheError(
            f"cache folder {p} is writable by others (mode "
            f"{stat.filemode(st.st_mode)}): chmod go-w it, or choose "
            "another folder")
    return p


def _digest(path: Path) -> str:
    """SHA-256 of a regular file, opened without following a link
    (a FIFO or device gives '', and is never read)."""
    fh = _open_regular(path)
    if fh is None:
        return ""
    with fh:
        h = hashlib.sha256()
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
        return h.hexdigest()


def _open_regular(path: Path):
    """``path`` opened for reading if it is a regular file, else None.

    Opened without following a link and without blocking, and checked on
    the open file, so a FIFO or a device is never read.
    """
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0)
                     | getattr(os, "O_NONBLOCK", 0))
    except OSError:
        return None
    fh = os.fdopen(fd, "rb")
    if not stat.S_ISREG(os.fstat(fd).st_mode):
        fh.close()
        return None
    return fh


#: A cache stem: letters, digits, ``_``, ``-``, ``.``; no leading dot.
_STEM = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.-]{0,127}")


def _regular(path: Path) -> bool:
    """True for a regular file that is no link (never opens ``path``)."""
    try:
        return stat.S_ISREG(os.lstat(path).st_mode)
    except OSError:
        return False


def _recorded_digest(record: Path) -> str:
    """The digest in ``record`` (at most 128 bytes read), else ''."""
    fh = _open_regular(record)
    if fh is None:
        return ""
    with fh:
        return fh.read(128).decode("ascii", "replace").strip()


def cached_library(folder, stem: str,
                   build: Callable[[Path], None]) -> Path:
    """Return a shared library of a private cache, checked before use.

    ``folder/stem.so`` is used when its SHA-256 equals the one recorded
    in ``folder/stem.sha256`` when it was built; otherwise (missing,
    changed or tampered with) ``build(path)`` writes a new one into a
    temporary file of the cache, which is made owner-only and moved into
    place atomically, with its digest.

    Only regular files are read: a library or record that is a link, a
    FIFO or a device is never opened, and is replaced by a new build.

    Raises
    ------
    UnsafeCacheError
        ``folder`` is not private to the user (`private_folder`).
    InvalidValueError
        ``stem`` is not a plain file name (letters, digits, ``_ - .``, no
        leading dot, at most 128 characters): ``../x`` would write
        outside the cache.
    """
    if not isinstance(stem, str) or not _STEM.fullmatch(stem):
        raise InvalidValueError(
            f"cache stem must be a plain file name (letters, digits, _ - ."
            f", no leading dot, at most 128 characters), got {stem!r}")
    cache = private_folder(folder)
    lib = cache / f"{stem}.so"
    record = cache / f"{stem}.sha256"
    if _regular(lib) and _regular(record):
        digest = _recorded_digest(record)
        if digest and digest == _digest(lib):
            return lib
    fd, tmp = tempfile.mkstemp(suffix=".so", dir=cache)
    os.close(fd)
    try:
        build(Path(tmp))
        os.chmod(tmp, 0o600)
        digest = _digest(Path(tmp))
        fd, tmp_rec = tempfile.mkstemp(suffix=".sha256", dir=cache)
        with os.fdopen(fd, "w") as fh:
            fh.write(digest + "\n")
        os.replace(tmp, lib)   # atomic: concurrent builds are safe
        os.replace(tmp_rec, record)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)
    return lib


@contextlib.contextmanager
def compile_progress(desc: str):
    """Show ``desc`` and the elapsed time while a compile runs.

    A tqdm line on a terminal only (not in logs or pipes), refreshed
    twice a second from a helper thread while the compiler blocks.
    """
    from tqdm.auto import tqdm

    bar = tqdm(total=None, desc=desc, disable=None,
               bar_format="{desc} [{elapsed}]")
    done = threading.Event()

    def tick() -> None:
        while not done.wait(0.5):
            bar.refresh()

    thread = threading.Thread(target=tick, daemon=True)
    thread.start()
    try:
        yield bar
    finally:
        done.set()
        thread.join()
        bar.close()
