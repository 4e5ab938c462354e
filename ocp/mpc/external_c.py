"""Build a CasADi external Function from C text, once per text.

The toolbox's own QP solvers in C (`ocp.mpc.primal_qp`,
`ocp.mpc.riccati_qp`) enter the MPC steps' graphs as external Functions:
a wrapper in CasADi's calling convention compiled with the solver into a
shared library in the user's temporary folder. Each process and thread
compiles into files of its own, renamed into place, so that several
controllers may be built at once (tested).
"""

from __future__ import annotations

import hashlib
import os
import re
import shutil
import tempfile
import threading
from pathlib import Path
from typing import Callable, Mapping, Sequence

import casadi as ca

from adcs_common.codegen import compile_c


def shared_external(name: str, text: str, sources: Sequence[Path],
                    flags: Sequence[str], kind: str,
                    included: Sequence[Path] = ()) -> ca.Function:
    """The external Function ``name`` of the wrapper ``text`` compiled
    with ``sources`` and ``flags``, in ``<tmp>/adcs_<kind>_<uid>/<key>``;
    the key hashes the text of the wrapper, the sources, the files the
    wrapper ``included`` and the flags.

    Raises
    ------
    CompilerNotFound
        No C compiler.
    """
    key_text = text + "".join(Path(s).read_text() for s in
                              [*sources, *included]) + " ".join(flags)
    key = hashlib.sha256(key_text.encode()).hexdigest()[:16]
    folder = Path(tempfile.gettempdir()) / f"adcs_{kind}_{os.getuid()}" / key
    lib = folder / f"lib{name}.so"
    if not lib.is_file():
        folder.mkdir(parents=True, exist_ok=True)
        # private names per process and thread (the source too: another
        # thread rewriting it mid-compile gave a library without the
        # symbols), then one atomic rename
        me = f"{os.getpid()}.{threading.get_ident()}"
        src = folder / f"wrapper.{me}.c"
        src.write_text(text)
        part = folder / f"{lib.name}.{me}"
        try:
            compile_c([src, *sources], part, flags=["-std=c99", *flags])
            os.replace(part, lib)
        finally:
            src.unlink(missing_ok=True)
    return ca.external(name, str(lib))


def copy_solver(dst: Path, sources: Path, files: Sequence[str],
                compiled: Sequence[str], pattern: re.Pattern,
                source_text: str, built: Mapping[str, tuple],
                wrapper: Callable[..., str]) -> list[Path]:
    """Write a solver's ``files`` (from the folder ``sources``) and the
    wrapper of every external whose name ``pattern`` finds called in the
    generated ``source_text`` into ``dst`` (its C text
    ``wrapper(*built[name])``: the arguments it was built with in this
    process); a stale ``dst`` of an earlier export is removed when none
    is called.

    Raises
    ------
    RuntimeError
        The source calls an external this process did not build.

    Returns
    -------
    list of pathlib.Path
        The C sources to compile beside the generated source: those of
        ``files`` named in ``compiled``, then the wrappers.
    """
    names = sorted(set(pattern.findall(source_text)))
    if not names:
        if dst.is_dir():
            shutil.rmtree(dst)
        return []
    dst.mkdir(exist_ok=True)
    for name in files:
        shutil.copyfile(sources / name, dst / name)
    written = [dst / name for name in compiled]
    for name in names:
        if name not in built:
            raise RuntimeError(f"{name} was not built in this process")
        path = dst / f"{name}.c"
        path.write_text(wrapper(*built[name]))
        written.append(path)
    return written
