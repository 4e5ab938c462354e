"""Objects users keep, shared between threads: one lock per object.

The allocators and controllers hold state that one call changes and the
next reads (a solver's warm start, CasADi work buffers bound to numpy
arrays): two threads inside one such object at once would read each
other's answers or crash the process. `synchronized` methods take the
object's re-entrant lock, so a shared object is safe and answers exactly
as it would from one thread; threads that must not wait on each other
should each build their own object.
"""

from __future__ import annotations

import functools
import threading
from typing import Any, Callable, TypeVar

__all__ = ["new_lock", "synchronized"]

F = TypeVar("F", bound=Callable[..., Any])


def new_lock() -> threading.RLock:
    """Return the lock a `synchronized` object keeps as ``self._lock``."""
    return threading.RLock()


def synchronized(method: F) -> F:
    """Run ``method`` holding ``self._lock`` (re-entrant)."""
    @functools.wraps(method)
    def locked(self, *args, **kwargs):
        with self._lock:
            return method(self, *args, **kwargs)

    return locked  # type: ignore[return-value]
