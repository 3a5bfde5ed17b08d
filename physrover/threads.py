"""Pin the numeric libraries to a number of threads (benchmarks, sweeps, the CLI).

numpy's OpenBLAS starts its thread pool when numpy is imported, so setting
``OMP_NUM_THREADS`` afterwards does nothing; threadpoolctl resizes the pools that are
already loaded. The environment variables are set too, for child processes.
"""

from __future__ import annotations

import os


def pin_threads(n: int = 1) -> None:
    """Limit BLAS/OpenMP pools and torch to ``n`` threads in this process (and children)."""
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ[var] = str(n)
    from threadpoolctl import threadpool_limits

    threadpool_limits(limits=n)
    try:
        import torch
    except ImportError:  # pragma: no cover - torch is a dependency
        return
    torch.set_num_threads(n)
