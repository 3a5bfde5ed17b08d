"""Borrowed views (physrover.core.borrow): the same arrays, without a memory record."""

from __future__ import annotations

import sys
from typing import NamedTuple

import numpy as np
from numba import njit, types
from numba.extending import intrinsic

from physrover.core.borrow import borrowed


@intrinsic
def _record_and_data(typingctx, array):
    """(address of the array's memory record, address of its data) as int64."""

    def codegen(context, builder, signature, args):
        view = context.make_array(signature.args[0])(context, builder, value=args[0])
        record = builder.ptrtoint(view.meminfo, context.get_value_type(types.int64))
        data = builder.ptrtoint(view.data, context.get_value_type(types.int64))
        return context.make_tuple(builder, signature.return_type, (record, data))

    return types.UniTuple(types.int64, 2)(array), codegen


class Inner(NamedTuple):
    weights: np.ndarray
    scale: float


class Outer(NamedTuple):
    positions: np.ndarray
    inner: Inner
    nothing: None
    count: int
    name: str


@njit
def _records(outer):
    """The memory records and data of ``outer``'s arrays, as given and borrowed."""
    view = borrowed(outer)
    return (_record_and_data(outer.positions), _record_and_data(outer.inner.weights),
            _record_and_data(view.positions), _record_and_data(view.inner.weights),
            view.inner.scale, view.count)  # fmt: skip


@njit
def _sum_borrowed(outer, times):
    """Reads and writes through borrowed views in a loop with calls: the step's pattern."""
    total = 0.0
    for _ in range(times):
        view = borrowed(outer)
        positions, weights = borrowed((view.positions, view.inner.weights))
        positions[0, 0] += 1.0
        total += positions.sum() * weights[1] * view.inner.scale + view.count + len(view.name)
    return total


def _outer():
    name = "".join(["rov", "er"])  # a string of its own, counted by numba as arrays are
    return Outer(np.arange(6.0).reshape(3, 2), Inner(np.array([0.5, 2.0]), 3.0), None, 4, name)


def test_borrowed_arrays_keep_their_data_and_lose_their_memory_record():
    outer = _outer()
    given_p, given_w, view_p, view_w, scale, count = _records(outer)
    assert given_p[0] != 0 and given_w[0] != 0  # numba's own views are counted
    assert view_p[0] == 0 and view_w[0] == 0  # borrowed: no record, at every depth
    assert view_p[1] == given_p[1] == outer.positions.ctypes.data
    assert view_w[1] == given_w[1] == outer.inner.weights.ctypes.data
    assert (scale, count) == (3.0, 4)  # other fields as they were


def test_borrowed_views_read_and_write_the_arrays_and_leave_their_counts():
    outer = _outer()
    expected, positions = 0.0, outer.positions.copy()
    for _ in range(50):  # the kernel's arithmetic, as a plain loop
        positions[0, 0] += 1.0
        expected += positions.sum() * 2.0 * 3.0 + 4 + 5
    held = (outer.positions, outer.inner.weights, outer.name)  # the string: counted as before
    before = [sys.getrefcount(a) for a in held]
    assert _sum_borrowed(outer, 50) == expected
    np.testing.assert_array_equal(outer.positions, positions)  # written through the view
    for _ in range(200):
        _sum_borrowed(outer, 3)
    assert [sys.getrefcount(a) for a in held] == before


def test_borrowed_in_python_is_the_value_itself():
    outer = _outer()
    assert borrowed(outer) is outer
