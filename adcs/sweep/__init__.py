"""Design-space sweeps and Monte Carlo campaigns on Dask."""

from .builtin import SWEEPS
from .engine import (SweepCacheWarning, SweepError, close, connect,
                     local_cluster, run_chunk, run_sweep)

__all__ = ["SWEEPS", "SweepCacheWarning", "SweepError", "close", "connect",
           "local_cluster", "run_chunk", "run_sweep"]
