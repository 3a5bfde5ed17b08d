"""Which implementation runs the hot loops: compiled kernels (numba) or the numpy reference.

Every hot loop of physrover exists twice:

- the **numpy reference** (``geometry.relate`` + ``sensing.sense`` + ``ScoreKeeper.record``,
  ``PolicyLayout.forward``, ``IntermediateCritics`` ...): short, array-at-a-time code that
  reads like the paper's equations and is the one to change first when extending the
  domain;
- the **compiled kernels** (:mod:`physrover.domain.kernels`, :mod:`physrover.learn.kernels`):
  the same computations as explicit loops compiled by numba, one call per world step or per
  generation phase instead of dozens of numpy calls. They are the default because the numpy
  path spends most of its time in per-call overhead on these small arrays (measured numbers
  in ``experiments/BENCHMARKS.md``).

The tests check that both agree (to float32 rounding for continuous values, exactly for
captures, quadrants and scores on random cases). Choose with the environment variable
``PHYSROVER_ENGINE=numba|numpy`` (read when a world, policy or critic is built) or by passing
``engine=`` where a constructor takes it. Kernels compile on first use (a few seconds) and
are cached on disk by numba afterwards.
"""

from __future__ import annotations

import os

ENGINES = ("numba", "numpy")
ENV_VAR = "PHYSROVER_ENGINE"


class EngineError(ValueError):
    """An unknown engine name (argument or environment variable)."""


def resolve(engine: str | None = None) -> str:
    """``engine``, or the environment's choice (default ``"numba"``), validated."""
    name = engine if engine is not None else os.environ.get(ENV_VAR, "numba")
    if name not in ENGINES:
        source = "engine" if engine is not None else ENV_VAR
        raise EngineError(f"{source} must be one of {', '.join(ENGINES)}, got {name!r}")
    return name


def jit(fn):
    """Compile ``fn`` with numba (nopython, cached on disk); compilation happens on first call.

    No ``fastmath``: the kernel keeps IEEE semantics (no reassociation, no fused
    multiply-adds), so its results do not depend on the CPU's vector width.
    """
    import numba

    return numba.njit(cache=True, nogil=True)(fn)


def jit_reassoc(fn):
    """As :func:`jit`, but the compiler may reassociate floating-point sums (``fastmath``
    flag ``reassoc`` only), which lets it vectorise reductions. Results stay deterministic
    on a machine; their last bits depend on its vector width."""
    import numba

    return numba.njit(cache=True, nogil=True, fastmath={"reassoc"})(fn)
