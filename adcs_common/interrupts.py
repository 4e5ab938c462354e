"""Ctrl-C, wherever it lands: the toolbox's one test of an interrupt.

CasADi checks for SIGINT inside its own calls and turns the
`KeyboardInterrupt` it finds into a `RuntimeError` ("Error in
Function::call for 'mpc_nlp' [Sqpmethod] ... KeyboardInterrupt"). Code
that keeps finished work on Ctrl-C (the report's studies, the bench's
rows, a sweep's chunks) asks `interrupted` instead of catching
`KeyboardInterrupt` alone, and `Interrupted` carries what was finished
up to the caller that saves it.
"""

from __future__ import annotations

import signal
import threading
from typing import Any

__all__ = ["Interrupted", "check", "install_handler", "interrupted",
           "requested"]

#: Set by the command line's SIGINT handler: a solver (IPOPT) that
#: swallows the KeyboardInterrupt and returns a failure status cannot
#: hide the Ctrl-C from the loops that check it.
_REQUESTED = threading.Event()


class Interrupted(KeyboardInterrupt):
    """Ctrl-C, with the work finished before it (``partial``)."""

    def __init__(self, message: str = "", partial: Any = None) -> None:
        super().__init__(message)
        self.partial = partial


def interrupted(exc: BaseException) -> bool:
    """True for Ctrl-C: a `KeyboardInterrupt`, CasADi's wrapping of one,
    or any error raised after a recorded Ctrl-C (a solver's failure that
    the interrupt caused)."""
    if isinstance(exc, KeyboardInterrupt) or _REQUESTED.is_set():
        return True
    return isinstance(exc, RuntimeError) and "KeyboardInterrupt" in str(exc)


def requested() -> bool:
    """True once the handler has recorded a Ctrl-C."""
    return _REQUESTED.is_set()


def check() -> None:
    """Raise `Interrupted` if a Ctrl-C was recorded (a loop's checkpoint)."""
    if _REQUESTED.is_set():
        raise Interrupted()


def _on_sigint(signum: int, frame: Any) -> None:
    _REQUESTED.set()
    raise KeyboardInterrupt


def install_handler() -> None:
    """Record every Ctrl-C (main thread only; a no-op elsewhere).

    Also drops CasADi's own line about the interrupt it caught
    (``WARNING("KeyboardInterruptException")``) from ``sys.stderr``, so
    that Ctrl-C ends with the command line's one line.
    """
    import sys

    _REQUESTED.clear()
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, _on_sigint)
    if not isinstance(sys.stderr, _QuietInterrupts):
        sys.stderr = _QuietInterrupts(sys.stderr)


class _QuietInterrupts:
    """A text stream that drops CasADi's interrupt warnings."""

    _MARK = 'WARNING("KeyboardInterruptException")'
    _PREFIX = "CasADi - "

    def __init__(self, stream: Any) -> None:
        self._stream = stream
        self._held = ""

    #: What solvers print about the interrupt they caught once Ctrl-C is
    #: recorded (SUNDIALS through CasADi: "rhs failed: KeyboardInterrupt",
    #: "... failed in an unrecoverable manner.").
    _AFTER = ("KeyboardInterrupt", "failed in an unrecoverable manner")

    def write(self, text: str) -> int:
        if _REQUESTED.is_set():
            return self._write_after_interrupt(text)
        # CasADi writes its line in pieces: a line of CasADi's is held
        # until it is whole, anything else passes at once
        held = self._held + text
        self._held = ""
        while held:
            if not held.startswith(self._PREFIX[:len(held)]) or \
                    not held.startswith(self._PREFIX) and len(held) >= len(
                        self._PREFIX):
                self._stream.write(held)
                break
            line, nl, rest = held.partition("\n")
            if not nl:
                self._held = held
                break
            if self._MARK not in line:
                self._stream.write(line + nl)
            held = rest
        return len(text)

    def _write_after_interrupt(self, text: str) -> int:
        """Whole lines only, the solvers' own interrupt lines dropped."""
        held = self._held + text
        *lines, self._held = held.split("\n")
        for line in lines:
            if not any(m in line for m in (self._MARK, *self._AFTER)):
                self._stream.write(line + "\n")
        return len(text)

    def flush(self) -> None:
        self._stream.flush()

    def __getattr__(self, name: str) -> Any:
        return getattr(self._stream, name)
