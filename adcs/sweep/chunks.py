"""Saved chunks of a sweep: keyed by content, stored with a digest, verified.

A chunk's file name is its *key*: the SHA-256 of

* the study's qualified name and its *code version* (`code_version`: the
  SHA-256 of the source file of the module that defines the study, its
  optional ``sweep_version`` attribute and the toolbox's version);
* the content the cases read beyond their parameters (`chunk_inputs`:
  the study's optional ``sweep_inputs(row) -> dict``, e.g. the digest of
  a spacecraft's TOML text, and the SHA-256 of every file a string
  parameter names);
* the chunk's parameters.

So an edited craft file, an edited study or other parameters give other
keys: the chunk is computed, never "resumed" from another one.

The file (JSON: data, never code) holds the key, the parameters, the rows
and the SHA-256 of the three (`digest`). `load_chunk` checks all of them
and the rows' count and shape; a chunk that fails (truncated, not JSON,
hand-edited, rows removed or changed, NaN written in, ``[]``) is reported
with its reason, and `run_sweep` recomputes and rewrites it. The digest
finds corruption and edits, not a forgery: whoever can write the folder
can also write a matching digest.
"""

from __future__ import annotations

import functools
import hashlib
import inspect
import json
import os
import sys
from pathlib import Path
from typing import Any, Callable

import numpy as np

__all__ = ["FORMAT", "SweepCacheWarning", "chunk_inputs", "chunk_key",
           "code_version", "digest", "load_chunk", "save_chunk"]

#: Version of the chunk file layout (part of every key and file).
FORMAT = 2


class SweepCacheWarning(UserWarning):
    """Saved chunks failed verification and were recomputed."""


def plain(value: Any) -> Any:
    """Return a JSON-able copy of a value (numpy numbers and arrays)."""
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    return value


def _default(value: Any) -> Any:
    """JSON fallback: numpy as plain numbers and lists, the rest as text."""
    value = plain(value)
    if isinstance(value, (list, int, float, str)) or value is None:
        return value
    return os.fspath(value) if isinstance(value, os.PathLike) else str(value)


def canonical(value: Any) -> str:
    """Return one JSON text per value (sorted keys, numpy as plain)."""
    return json.dumps(value, sort_keys=True, separators=(",", ":"),
                      default=_default)


def _sha256(text: str | bytes) -> str:
    data = text.encode() if isinstance(text, str) else text
    return hashlib.sha256(data).hexdigest()


def _unwrap(study: Callable) -> tuple[Callable, list[str]]:
    """Return the function under `functools.partial` layers, their args."""
    bound = []
    while isinstance(study, functools.partial):
        bound.append(canonical([list(study.args), study.keywords]))
        study = study.func
    return study, bound


def study_name(study: Callable) -> str:
    """``module.qualname`` of a study (through `functools.partial`)."""
    func, _ = _unwrap(study)
    qualname = getattr(func, "__qualname__", type(func).__qualname__)
    return f"{getattr(func, '__module__', '')}.{qualname}"


def _source(func: Callable) -> str:
    """Digest of the source of the module defining ``func`` ("" if none)."""
    module = sys.modules.get(getattr(func, "__module__", "") or "")
    path = getattr(module, "__file__", None)
    if path:
        try:
            return _sha256(Path(path).read_bytes())
        except OSError:
            pass
    try:                            # a notebook cell, an interactive session
        return _sha256(inspect.getsource(func))
    except (OSError, TypeError):
        return ""


def code_version(study: Callable) -> str:
    """SHA-256 naming the code of a study, hex.

    The source file of the module defining it (any edit of that module
    changes it), its ``sweep_version`` attribute if it has one (bump it
    when code elsewhere changes the study's numbers), arguments bound by
    `functools.partial`, and the toolbox's version.
    """
    from adcs.provenance import version

    func, bound = _unwrap(study)
    return _sha256(canonical({
        "name": study_name(study), "source": _source(func), "bound": bound,
        "sweep_version": str(getattr(func, "sweep_version", "")),
        "toolbox": version()}))


def _file_digest(value: Any, memo: dict[str, str]) -> str | None:
    """SHA-256 of the file a string or path parameter names, else None."""
    if not isinstance(value, (str, os.PathLike)):
        return None
    try:
        path = Path(value)
        if not path.is_file():
            return None
        key = str(path.resolve())
        if key not in memo:
            memo[key] = _sha256(path.read_bytes())
    except (OSError, ValueError):
        return None
    return memo[key]


def chunk_inputs(study: Callable, chunk: list[dict],
                 memo: dict[str, str] | None = None) -> list[dict]:
    """Content the chunk's cases read beyond their parameters, per case.

    ``study.sweep_inputs(row)`` (a dict, if the study has the attribute)
    and, for each string or path parameter naming a file, its SHA-256.
    ``memo`` caches file digests across chunks of one sweep.
    """
    memo = {} if memo is None else memo
    func, _ = _unwrap(study)
    hook = getattr(func, "sweep_inputs", None)
    out = []
    for row in chunk:
        entry = {"files": {k: d for k, v in row.items()
                           if (d := _file_digest(v, memo)) is not None}}
        if hook is not None:
            entry["study"] = hook(row)
        out.append(entry)
    return out


def chunk_key(name: str, code: str, inputs: list[dict],
              chunk: list[dict]) -> str:
    """SHA-256 (hex) keying a chunk: study, code, inputs, parameters."""
    return _sha256(canonical({"format": FORMAT, "study": name, "code": code,
                              "inputs": inputs, "params": chunk}))


def digest(key: str, params: list[dict], rows: list[dict]) -> str:
    """SHA-256 (hex) stored with a chunk: its key, parameters and rows."""
    return _sha256(canonical({"key": key, "params": params, "rows": rows}))


def chunk_path(folder: Path, key: str) -> Path:
    """Where the chunk of ``key`` is saved in ``folder``."""
    return folder / f"{key[:32]}.json"


def save_chunk(path: Path, key: str, params: list[dict],
               rows: list[dict]) -> list[dict]:
    """Write a chunk with its digest (atomic replace); return the rows.

    The rows are returned as saved (numpy numbers and arrays as plain
    numbers and lists), so a loaded chunk equals a computed one.
    """
    rows = json.loads(json.dumps(rows, default=_default))
    params = json.loads(json.dumps(params, default=_default))
    text = json.dumps({"format": FORMAT, "key": key, "params": params,
                       "rows": rows, "digest": digest(key, params, rows)})
    tmp = path.with_name(f"{path.name}.{os.getpid()}.tmp")
    tmp.write_text(text, encoding="utf-8")
    tmp.replace(path)
    return rows


def load_chunk(path: Path, key: str,
               params: list[dict]) -> tuple[list[dict] | None, str]:
    """Read and verify a saved chunk.

    Returns
    -------
    rows : list of dict or None
        The chunk's rows, or None when there is no file or it fails.
    reason : str
        Why it failed ("" when it loaded or there is no file).
    """
    if not path.exists():
        return None, ""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError, RecursionError) as exc:
        return None, f"unreadable ({type(exc).__name__})"
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        return None, "not a chunk of this format"
    rows = data.get("rows")
    if data.get("key") != key:
        return None, "key differs"
    if canonical(data.get("params")) != canonical(params):
        return None, "parameters differ"
    if not isinstance(rows, list) or len(rows) != len(params):
        return None, f"{len(rows) if isinstance(rows, list) else 'no'} " \
                     f"rows for {len(params)} cases"
    if not all(isinstance(r, dict) and isinstance(r.get("error"), str)
               for r in rows):
        return None, "a row is not a case"
    if data.get("digest") != digest(key, data["params"], rows):
        return None, "digest differs"
    return rows, ""
