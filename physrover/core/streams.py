"""numpy generators' streams read inside compiled kernels, bit for bit what the generators
themselves give.

Every team draws its random start from its own ``numpy.random.Generator`` (so team e's
start does not depend on how many teams there are). Drawing from E generators in Python is a
loop of E small numpy calls; passing the generators into a numba kernel costs about 11 us
each (numba unboxes every one). Instead, :func:`stream_handles` takes, once per call, each
generator's bit generator's C state address and its ``next_double`` function (numpy's own,
``BitGenerator.ctypes``: the documented interface for using numpy's bit generators from
numba), and a kernel calls :func:`next_double` on them. That is the very function
``Generator.random`` calls once per double, on the same state, so a kernel's draws are the
generator's, in the same order, and the generator continues from where the kernel left it.

Conventions: the kernel does not take the bit generator's lock (``Generator`` does): do not
draw from the same generator in another thread meanwhile. The generators must outlive the
kernel's call (their addresses are only valid while they live). Under
``NUMBA_DISABLE_JIT=1`` :func:`next_double` calls the same function through ctypes.
"""

from __future__ import annotations

import ctypes
from collections.abc import Sequence

import numba
import numpy as np
from llvmlite import ir
from numba.core import types
from numba.extending import intrinsic

from physrover.core.compiled import jit_inline

_NEXT_DOUBLE = ctypes.CFUNCTYPE(ctypes.c_double, ctypes.c_void_p)
_functions: dict[type, int] = {}  # a bit generator's type -> its next_double's address


def stream_handles(rngs: Sequence[np.random.Generator]) -> np.ndarray:
    """(E, 2) int64: for each generator, the address of its bit generator's ``next_double``
    and of the state that function takes (row e for ``rngs[e]``)."""
    out = np.empty((len(rngs), 2), dtype=np.int64)
    for e, rng in enumerate(rngs):
        if not isinstance(rng, np.random.Generator):
            raise TypeError(f"expected numpy.random.Generator objects, got {type(rng).__name__}")
        interface = rng.bit_generator.ctypes
        kind = type(rng.bit_generator)
        fn = _functions.get(kind)
        if fn is None:
            fn = _functions[kind] = ctypes.cast(interface.next_double, ctypes.c_void_p).value
        out[e, 0], out[e, 1] = fn, interface.state_address
    return out


def _next_double_python(handle) -> float:
    return _NEXT_DOUBLE(int(handle[0]))(ctypes.c_void_p(int(handle[1])))


@intrinsic
def _call_next_double(typingctx, fn, state):
    """Call the C function at address ``fn`` (double (*)(void *)) on the address ``state``."""

    def codegen(context, builder, signature, args):
        byte_ptr = ir.IntType(8).as_pointer()
        kind = ir.FunctionType(ir.DoubleType(), [byte_ptr])
        function = builder.inttoptr(args[0], kind.as_pointer())
        return builder.call(function, [builder.inttoptr(args[1], byte_ptr)])

    return types.float64(types.int64, types.int64), codegen


@jit_inline
def _next_double_compiled(handle):
    return _call_next_double(handle[0], handle[1])


next_double = _next_double_python if numba.config.DISABLE_JIT else _next_double_compiled
"""``next_double(handle)``: the next double in [0, 1) of the stream of ``handle`` (a row of
:func:`stream_handles`), advancing it: what ``Generator.random()`` gives. Callable from
compiled kernels."""
