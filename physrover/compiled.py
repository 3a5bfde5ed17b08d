"""How physrover compiles its kernels: numba, nopython, cached on disk.

The compiled kernels are the one implementation of the hot equations (the world step, the
policies' forward pass, the critics' values and updates). They compile on first use (5-10 s)
and numba caches them on disk, so later processes load them. ``NUMBA_DISABLE_JIT=1`` runs
them as plain Python, for debugging with a debugger or prints (slow, but the same results).
"""

from __future__ import annotations


def jit(fn):
    """Compile ``fn`` with numba (nopython, cached on disk); compilation happens on first call.

    No ``fastmath``: the kernel keeps IEEE semantics (no reassociation, no fused
    multiply-adds), so its results do not depend on the CPU's vector width.

    ``error_model="numpy"``: a float division by zero gives inf or NaN as in numpy, instead
    of Python's ZeroDivisionError. The kernels never divide by zero (their divisors are
    bounded away from it, e.g. by ``d_min``), and the check Python's model adds to every
    division is a branch that stops the compiler vectorising the loop around it.
    """
    import numba

    return numba.njit(cache=True, nogil=True, error_model="numpy")(fn)


def jit_reassoc(fn):
    """As :func:`jit`, but the compiler may reassociate floating-point sums (``fastmath``
    flag ``reassoc`` only), which lets it vectorise reductions. Results stay deterministic
    on a machine; their last bits depend on its vector width."""
    import numba

    return numba.njit(cache=True, nogil=True, error_model="numpy", fastmath={"reassoc"})(fn)


def dims(n: int) -> tuple[int, ...]:
    """``n`` zeros: kernels read ``len(dims)`` as a size the compiler knows, so each size
    (a sensor's observations, its sectors) gets its own compiled version with its loops over
    that size unrolled (what hand-unrolled loops did for the paper's 8 observations and 10
    critic inputs)."""
    return (0,) * n
