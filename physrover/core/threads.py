"""Pin the numeric libraries to a number of threads (benchmarks, sweeps, the CLI).

numpy's OpenBLAS starts its thread pool when numpy is imported, so setting
``OMP_NUM_THREADS`` afterwards does nothing; threadpoolctl resizes the pools that are
already loaded. The environment variables are set too, for child processes and for libraries
imported later (torch reads ``OMP_NUM_THREADS`` when it is first imported). torch is pinned
here only if something already imported it: importing it costs seconds, and only the
gradient-based baselines use it.
"""

from __future__ import annotations

import os
import sys


def pin_threads(n: int = 1) -> None:
    """Limit BLAS/OpenMP pools (and torch, if loaded) to ``n`` threads in this process and
    its children."""
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ[var] = str(n)
    from threadpoolctl import threadpool_limits

    threadpool_limits(limits=n)
    torch = sys.modules.get("torch")
    if torch is not None:
        torch.set_num_threads(n)
