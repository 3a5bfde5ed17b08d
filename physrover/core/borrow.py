"""Borrowed views: a compiled kernel's arrays without numba's reference counting.

numba counts references to every array it handles: taking an array out of a tuple (a
world's :class:`~physrover.domain.plan.StepPlan`, its
:class:`~physrover.domain.state.WorldState`) or passing it to a function that is not
inlined increments a counter in the array's memory record, and the end of that value's
life decrements it, each an atomic read-modify-write (``lock inc``/``lock dec`` on x86-64,
a full memory barrier). numba's own pass removes the pairs it can prove redundant, which
is those inside one basic block or one branch; in a step, whose body is many blocks and
calls, most stay. Measured (2026-12-06, ``perf record`` of 300 CCEA generations of D on
one core of a 2-core AMD EPYC): the samples in ``NRT_incref``/``NRT_decref`` came to 3.5
ms a generation on the 15-agent mixed team and 1.35 ms on the paper's team; traced to
their callers by their return addresses (the mixed team's), 94% came from the step inside
the compiled episode, which counts a dozen arrays and more up at the start of every
team-step and down at its end.

The kernels that borrow their arguments: the compiled episode
(:func:`physrover.learn.rollout.policy_episode`) and the world's step
(:func:`physrover.domain.step.step_teams`, :func:`~physrover.domain.step.step_teams_at`).

:func:`borrowed` gives the same arrays (same type, data, shape and strides) with no memory
record: numba's counting of them then reads a null pointer and returns, without the atomic
instruction. A borrowed view does not keep its memory alive, so it is only for arrays that
something else keeps alive for as long as the view is used: a kernel's own arguments, which
its caller holds until it returns. It must not escape the call (returned, or stored in an
array or structure that outlives it).
"""

from __future__ import annotations

from numba import types
from numba.core import cgutils
from numba.extending import lower_builtin, type_callable


def _borrow(context, builder, typ, value):
    """``value`` of numba type ``typ`` with every array in it (at any depth of tuples and
    named tuples) given a null memory record, as a new reference (what numba takes a
    call's result for): anything else it holds that numba counts (a string, a list) is
    counted once more, as numba will count it down at the end of the result's life."""
    if isinstance(typ, types.Array):
        array = context.make_array(typ)(context, builder, value=value)
        array.meminfo = cgutils.get_null_value(array.meminfo.type)
        return array._getvalue()
    if isinstance(typ, types.BaseTuple):
        for i, item_type in enumerate(typ.types):
            item = builder.extract_value(value, i)
            value = builder.insert_value(value, _borrow(context, builder, item_type, item), i)
        return value
    context.nrt.incref(builder, typ, value)  # nothing for a number or None
    return value


def borrowed(value):
    """``value`` (an array, or a tuple or named tuple holding arrays at any depth) whose
    arrays are borrowed views (module docstring), of the same type; other values
    unchanged. In Python (``NUMBA_DISABLE_JIT=1``) ``value`` itself: nothing is counted."""
    return value


@type_callable(borrowed)
def _type_borrowed(context):
    """In compiled code ``borrowed(value)`` has ``value``'s type. Typed and lowered directly
    (not an ``@overload`` of a function calling an intrinsic): an overload compiles its
    implementation once per argument type before inlining it, which for a step's plan cost
    0.7 s of compile a kernel and 37 s over the test suite (2026-12-07)."""

    def typer(value):
        return value

    return typer


@lower_builtin(borrowed, types.Any)
def _lower_borrowed(context, builder, signature, args):
    return _borrow(context, builder, signature.args[0], args[0])


__all__ = ["borrowed"]
