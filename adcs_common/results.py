"""What result objects share: a short repr, and saving to a file.

Result dataclasses of the toolbox inherit `ResultMixin` (and are declared
with ``repr=False``): ``repr`` shows scalars and short values in full and
arrays by their shape, and `ResultMixin.save` / `ResultMixin.load` write
and read the fields as one ``.npz`` file (arrays as arrays, everything
else as JSON).
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Any, ClassVar, TypeVar

import numpy as np

from .exceptions import InvalidValueError
from .paths import output_folder

__all__ = ["ResultMixin", "short_repr"]

R = TypeVar("R", bound="ResultMixin")
_META = "__fields__"


def short_repr(value: Any, width: int = 60) -> str:
    """Return a short text of ``value``: an array by its shape if long."""
    if isinstance(value, np.ndarray):
        if value.size <= 6:
            return np.array2string(value, precision=5, separator=", ")
        return f"<array {value.shape}>"
    if isinstance(value, (float, np.floating)):
        return f"{float(value):.6g}"
    if isinstance(value, (list, tuple)) and len(value) > 6:
        return f"<{type(value).__name__} of {len(value)}>"
    if isinstance(value, dict):
        keys = ", ".join(map(str, list(value)[:5]))
        more = ", ..." if len(value) > 5 else ""
        return f"{{{keys}{more}}}" if value else "{}"
    text = repr(value)
    return text if len(text) <= width else text[:width - 3] + "..."


def _jsonable(value: Any) -> Any:
    if isinstance(value, (np.floating, np.integer, np.bool_)):
        return value.item()
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    return value


class ResultMixin:
    """Short ``repr``; `save` / `load` of the fields (one ``.npz``)."""

    # set by @dataclass on each subclass (the mixin is for dataclasses)
    __dataclass_fields__: ClassVar[dict[str, dataclasses.Field[Any]]]

    def __repr__(self) -> str:
        """Return the fields, arrays by their shape."""
        parts = [f"{f.name}={short_repr(getattr(self, f.name))}"
                 for f in dataclasses.fields(self) if f.repr]
        return f"{type(self).__name__}({', '.join(parts)})"

    def save(self, path: str | Path) -> Path:
        """Write the fields to ``path`` (``.npz`` added if missing).

        Raises
        ------
        InvalidValueError
            A field holds something other than arrays, numbers, strings,
            None, lists, tuples or dicts of those (e.g. a model object).
        OutputPathError
            The folder cannot be written.
        """
        path = Path(path)
        if path.suffix != ".npz":
            path = path.with_suffix(".npz")
        output_folder(path.parent, "path")
        arrays: dict[str, np.ndarray] = {}
        meta: dict[str, Any] = {}
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if isinstance(value, np.ndarray):
                arrays[f.name] = value
                continue
            try:
                meta[f.name] = json.loads(json.dumps(_jsonable(value)))
            except (TypeError, ValueError) as exc:
                raise InvalidValueError(
                    f"{type(self).__name__}.{f.name} cannot be saved "
                    f"({type(value).__name__})") from exc
        contents: dict[str, Any] = {**arrays,
                                    _META: np.array(json.dumps(meta))}
        np.savez(path, **contents)
        return path

    @classmethod
    def load(cls: type[R], path: str | Path) -> R:
        """Read a result written by `save` (tuples come back as lists)."""
        with np.load(Path(path), allow_pickle=False) as data:
            meta = json.loads(str(data[_META]))
            fields = {k: data[k] for k in data.files if k != _META}
        values = {**meta, **fields}
        out = {}
        for f in dataclasses.fields(cls):
            if f.name not in values:
                continue
            v = values[f.name]
            if isinstance(v, list) and "tuple" in str(f.type):
                v = tuple(v)
            out[f.name] = v
        return cls(**out)
