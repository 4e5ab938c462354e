"""Solver option dictionaries: nested merge."""

from __future__ import annotations

__all__ = ["merge_options"]


def merge_options(base: dict, extra: dict) -> dict:
    """Merge nested option dicts, ``extra`` winning (neither is changed)."""
    out = dict(base)
    for key, value in extra.items():
        out[key] = (merge_options(out[key], value)
                    if isinstance(value, dict)
                    and isinstance(out.get(key), dict) else value)
    return out
