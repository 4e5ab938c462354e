"""Sweeps on Dask: split a parameter table into tasks, run, gather, resume.

A *study* is any picklable function ``study(**params) -> dict`` of
numbers (a toolbox function or the user's own). `run_sweep` cuts the
parameter table (one row per case) into chunks, runs each chunk as one
Dask task (`distributed`, processes: CasADi holds the GIL), and gathers
one `xarray.Dataset` along the dimension ``case``: the parameters as
coordinates, the study's outputs as variables, and ``error`` (empty, or
the exception a case raised: the sweep goes on). With ``out`` each
finished chunk is saved at once and a rerun loads it (resume) when it
passes verification: chunks are keyed by the study's code, the content
its cases read (a spacecraft file) and the parameters, and saved with a
digest (`adcs.sweep.chunks`); one that fails is recomputed, with a
`SweepCacheWarning`.

Where it runs: `local_cluster` starts workers on this machine, listening
on the loopback address only (a Dask scheduler runs whatever a client
sends it); `connect` reaches an existing scheduler, with TLS when given
certificates. A scheduler without TLS must never be reachable from an
untrusted network.
"""

from __future__ import annotations

import contextlib
import logging
import signal
import threading
import warnings
from pathlib import Path
from typing import Any, Callable, TYPE_CHECKING

import numpy as np

from adcs_common.exceptions import AdcsError, InvalidValueError
from adcs_common.interrupts import Interrupted, check, interrupted
from adcs_common.paths import output_folder

from .chunks import (SweepCacheWarning, chunk_inputs, chunk_key,
                     chunk_path, code_version, load_chunk, plain,
                     save_chunk, study_name)

if TYPE_CHECKING:
    import xarray as xr


__all__ = ["SweepCacheWarning", "SweepError", "close", "connect",
           "local_cluster", "run_chunk", "run_sweep"]

#: Where a local cluster and its dashboard listen unless told otherwise.
LOOPBACK = "127.0.0.1"


class SweepError(AdcsError, RuntimeError):
    """A sweep could not run (no Dask, a bad scheduler address, ...)."""


def _distributed():
    try:
        import distributed
    except ImportError as exc:
        raise SweepError(
            "sweeps need Dask: pip install \"adcs-toolbox[sweep]\"") from exc
    return distributed


def local_cluster(workers: int | None = None, host: str = LOOPBACK) -> Any:
    """Start a `distributed.LocalCluster` of worker processes here.

    One thread per worker process; scheduler and dashboard listen on
    ``host`` (the loopback address by default: nothing outside this
    machine can reach them).
    """
    distributed = _distributed()
    if workers is not None and (isinstance(workers, bool) or not isinstance(
            workers, int) or workers < 1):
        raise InvalidValueError(
            f"workers must be a positive integer, got {workers!r}")
    with _workers_ignore_ctrl_c():
        return distributed.LocalCluster(
            n_workers=workers, threads_per_worker=1, processes=True,
            host=host, dashboard_address=f"{host}:0", silence_logs=50)


@contextlib.contextmanager
def _workers_ignore_ctrl_c():
    """Start worker processes that ignore SIGINT.

    A Ctrl-C in a terminal reaches every process of the foreground group,
    the local workers too, each of which would print its own traceback.
    A process inherits an ignored SIGINT (and Python keeps it ignored),
    so the workers spawned here leave the Ctrl-C to this process, which
    cancels their tasks and closes the cluster (`close`).
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def close(client: Any, cluster: Any = None, *, quiet: bool = False) -> None:
    """Close a client and its local cluster (``quiet``: after a Ctrl-C).

    ``quiet`` silences `distributed`'s loggers (a worker killed while it
    runs a task, a connection closed under a pending call) and any error
    of the shutdown itself: the command's one line says it was
    interrupted.
    """
    if quiet:
        for name in ("distributed", "tornado", "asyncio"):
            logging.getLogger(name).setLevel(logging.CRITICAL + 1)
    for closing in (client, cluster):
        if closing is None:
            continue
        try:
            closing.close(timeout=5) if quiet else closing.close()
        except (Exception, KeyboardInterrupt):   # noqa: BLE001
            if not quiet:
                raise


def connect(scheduler: str | None = None, *, workers: int | None = None,
            tls_ca: str | None = None, tls_cert: str | None = None,
            tls_key: str | None = None) -> tuple[Any, Any]:
    """``(client, cluster)``: a new local cluster, or an existing scheduler.

    Parameters
    ----------
    scheduler : str, optional
        Address of a running scheduler (``tls://host:port`` with TLS);
        None starts `local_cluster` (``cluster`` is then returned so the
        caller can close it).
    tls_ca, tls_cert, tls_key : str, optional
        Certificate files of a TLS connection (all three).
    """
    distributed = _distributed()
    security = None
    if any((tls_ca, tls_cert, tls_key)):
        if not all((tls_ca, tls_cert, tls_key)):
            raise InvalidValueError(
                "TLS needs tls_ca, tls_cert and tls_key together")
        security = distributed.security.Security(
            tls_ca_file=tls_ca, tls_client_cert=tls_cert,
            tls_client_key=tls_key, require_encryption=True)
    if scheduler is None:
        cluster = local_cluster(workers)
        return distributed.Client(cluster), cluster
    try:
        client = distributed.Client(scheduler, security=security,
                                    timeout="10s")
    except (OSError, TimeoutError, ValueError) as exc:
        raise SweepError(f"cannot reach the scheduler {scheduler!r}: "
                         f"{exc}") from None
    return client, None


def run_chunk(study: Callable[..., dict], rows: list[dict]) -> list[dict]:
    """Run ``study`` on each parameter row; an exception is recorded."""
    out = []
    for row in rows:
        check()                    # a Ctrl-C recorded between cases
        try:
            result = dict(study(**row))
            error = ""
        except Exception as exc:  # noqa: BLE001 (recorded, sweep goes on)
            if interrupted(exc):   # CasADi's wrapping of a Ctrl-C
                raise
            result, error = {}, f"{type(exc).__name__}: {exc}"
        out.append({**row, **result, "error": error})
    return out


def _chunks(rows: list[dict], size: int) -> list[list[dict]]:
    return [rows[i:i + size] for i in range(0, len(rows), size)]


def run_sweep(study: Callable[..., dict], params: list[dict], *,
              client: Any = None, chunk_size: int | None = None,
              out: str | Path | None = None, retries: int = 2,
              progress: bool = True) -> xr.Dataset:
    """Run ``study`` on every parameter row; return an `xarray.Dataset`.

    Parameters
    ----------
    study : callable
        ``study(**row) -> dict`` of numbers; picklable (a module-level
        function) to run on workers. Optional attributes, read for the
        chunk keys: ``sweep_inputs(row) -> dict`` (JSON-able: digests of
        content a case reads beyond its parameters, e.g. a spacecraft
        file's text) and ``sweep_version`` (bump it when code outside the
        study's module changes its numbers).
    params : list of dict
        One dict of parameters per case.
    client : distributed.Client, optional
        Where the tasks run; None runs them in this process, in order
        (for debugging).
    chunk_size : int, optional
        Cases per task (default: about 4 tasks per worker).
    out : path, optional
        Folder for the finished chunks (``chunks/``, JSON with a
        SHA-256 digest); a rerun with the same study code, inputs and
        parameters loads them instead of recomputing. A saved chunk that
        fails verification (truncated, edited, not JSON) is recomputed
        and rewritten, and a `SweepCacheWarning` says how many.
    retries : int
        Times Dask retries a task whose worker died.
    progress : bool
        A progress bar with ETA (tqdm) on stderr.

    Returns
    -------
    xarray.Dataset
        Dimension ``case``; parameters and outputs as variables,
        ``error`` the exception text of a failed case ("" otherwise). An
        output that is a 1-D array (the same length in every case, e.g.
        the samples of a Monte Carlo block) becomes a variable of
        dimensions ``(case, <name>_index)``. ``attrs``: ``chunks``,
        ``chunks_loaded`` (verified, from ``out``), ``chunks_computed``
        and ``chunks_failed_verification`` (counts).

    Raises
    ------
    InvalidValueError
        ``study`` or ``params`` malformed, ``out`` not a writable folder.
    SweepError
        A finished chunk cannot be saved in ``out`` (e.g. a folder in
        its place), or array outputs of different lengths.
    """
    import pandas as pd
    import xarray as xr
    from tqdm.auto import tqdm

    if not callable(study):
        raise InvalidValueError("study must be a callable")
    if not isinstance(params, list) or not params or not all(
            isinstance(r, dict) for r in params):
        raise InvalidValueError(
            "params must be a non-empty list of dicts (one case each)")
    n_workers = 1 if client is None else max(
        len(client.scheduler_info().get("workers", {})), 1)
    size = chunk_size or max(1, -(-len(params) // (4 * n_workers)))
    chunks = _chunks(params, int(size))
    folder = None if out is None else output_folder(
        Path(out) / "chunks", "out")
    done, todo, failed = _saved(study, chunks, folder)
    if failed:
        warnings.warn(f"{_failed_text(len(failed))} ({'; '.join(failed)})",
                      SweepCacheWarning, stacklevel=2)
    loaded = len(done)
    bar = tqdm(total=len(chunks), initial=loaded, disable=not progress,
               desc=getattr(study, "__name__", "sweep"), unit="task")
    try:
        _compute(study, todo, done, client, retries, bar)
    except BaseException as exc:
        if not interrupted(exc):
            raise
        bar.close()
        saved = "saved" if folder is not None else "finished"
        raise Interrupted(
            f"{len(done)} of {len(chunks)} chunks {saved}"
            + (f" in {folder}: rerun to resume" if folder is not None
               else ""), partial=dict(done)) from None
    bar.close()
    ds = _dataset([r for i in sorted(done) for r in done[i]], pd, xr)
    ds.attrs.update(chunks=len(chunks), chunks_loaded=loaded,
                    chunks_computed=len(todo),
                    chunks_failed_verification=len(failed))
    return ds


def _compute(study: Callable, todo: list, done: dict[int, list[dict]],
             client: Any, retries: int, bar: Any) -> None:
    """Run the chunks of ``todo`` into ``done``, each saved as it ends.

    On Ctrl-C the chunks not finished are cancelled (on Dask), and the
    interrupt propagates: ``done`` holds every finished chunk.
    """
    if client is None:
        for i, chunk, path, key in todo:
            done[i] = _keep(run_chunk(study, chunk), path, key, chunk)
            bar.update()
        return
    distributed = _distributed()
    futures = {client.submit(run_chunk, study, chunk, retries=retries,
                             pure=False): (i, chunk, path, key)
               for i, chunk, path, key in todo}
    try:
        for fut in distributed.as_completed(futures):
            i, chunk, path, key = futures[fut]
            done[i] = _keep(fut.result(), path, key, chunk)
            bar.update()
            check()
    except BaseException:
        with contextlib.suppress(Exception, KeyboardInterrupt):
            client.cancel(list(futures))
        raise


def _saved(study: Callable, chunks: list[list[dict]], folder: Path | None):
    """Split chunks into those saved and verified, and those to compute.

    Returns ``done`` ({index: rows}), ``todo`` ([(index, chunk, path,
    key)], path None without a folder) and ``failed`` (one "file:
    reason" per saved chunk that failed verification).
    """
    if folder is None:
        return {}, [(i, c, None, "") for i, c in enumerate(chunks)], []
    done: dict[int, list[dict]] = {}
    todo, failed = [], []
    name, code = study_name(study), code_version(study)
    memo: dict[Any, Any] = {}
    for i, chunk in enumerate(chunks):
        key = chunk_key(name, code, chunk_inputs(study, chunk, memo), chunk)
        path = chunk_path(folder, key)
        rows, reason = load_chunk(path, key, chunk)
        if rows is not None:
            done[i] = rows
            continue
        if reason:
            failed.append(f"{path.name}: {reason}")
        todo.append((i, chunk, path, key))
    return done, todo, failed


def _failed_text(n: int) -> str:
    """``"2 chunks failed verification, recomputed"``."""
    return (f"{n} saved chunk{'s' if n != 1 else ''} failed verification, "
            "recomputed")


def _keep(rows: list[dict], path: Path | None, key: str,
          chunk: list[dict]) -> list[dict]:
    """Save a finished chunk (with ``out``) and return its rows, as saved."""
    if path is None:
        return [{k: plain(v) for k, v in r.items()} for r in rows]
    try:
        return save_chunk(path, key, chunk, rows)
    except OSError as exc:
        raise SweepError(f"cannot save the chunk {path}: "
                         f"{exc.strerror or exc}") from None


def _dataset(rows: list[dict], pd, xr):
    """Gather rows into a Dataset.

    Numbers go along ``case``; a 1-D array output ``key`` (same length in
    every case) along ``(case, key_index)``, NaN-filled where a case
    failed.
    """
    arrays = sorted({k for r in rows for k, v in r.items()
                     if isinstance(v, (list, tuple))})
    table = pd.DataFrame([{k: v for k, v in r.items() if k not in arrays}
                          for r in rows])
    table.index.name = "case"
    ds = xr.Dataset.from_dataframe(table)
    for key in arrays:
        values = [r.get(key) for r in rows]
        lengths = {len(v) for v in values if isinstance(v, (list, tuple))}
        if len(lengths) != 1:
            raise SweepError(f"output {key!r} has different lengths across "
                             f"cases: {sorted(lengths)}")
        n = lengths.pop()
        data = np.array([v if isinstance(v, (list, tuple)) else [np.nan] * n
                         for v in values], dtype=float)
        ds[key] = (("case", f"{key}_index"), data)
    return ds
