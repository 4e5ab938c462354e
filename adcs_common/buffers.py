"""A casadi Function bound to numpy arrays through ``Function.buffer()``."""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np


class BoundCall:
    """Evaluate ``function`` in place on numpy arrays, without conversion.

    ``inputs[i]`` and ``outputs[j]`` (float64, contiguous, of the
    Function's sizes) are bound to its i-th input and j-th output; each
    `trigger` call evaluates the Function on the current input values and
    writes the outputs. A failed evaluation leaves the outputs as they
    were (set a sentinel first to notice it).

    The trigger reads through the buffer object: CasADi crashes the
    process if that object is freed first. This class keeps the
    Function, the buffer and the arrays alive as long as it lives, so
    hold the `BoundCall`, not just its `trigger`.

    Attributes
    ----------
    function : casadi.Function
    inputs, outputs : tuple of numpy.ndarray
    trigger : callable
        ``trigger()`` evaluates.
    """

    __slots__ = ("function", "inputs", "outputs", "trigger", "_buf")

    def __init__(self, function: Any, inputs: Sequence[np.ndarray],
                 outputs: Sequence[np.ndarray]) -> None:
        self.function = function
        self.inputs = tuple(inputs)
        self.outputs = tuple(outputs)
        self._buf, self.trigger = function.buffer()
        for i, a in enumerate(self.inputs):
            self._buf.set_arg(i, a.data)   # the array's memoryview
        for j, a in enumerate(self.outputs):
            self._buf.set_res(j, a.data)
