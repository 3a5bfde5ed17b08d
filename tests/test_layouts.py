"""The compiled draws of random layouts (physrover.domain.layouts) read each team's numpy
generator bit for bit: the uniform scenario's layouts against a plain loop over
``rng.random(2)`` (the scenario's Python implementation before it was compiled), and the
generators left where that loop leaves them; the stream handles against numpy's own draws
for every bit generator numpy ships."""

import math

import numpy as np
import pytest

from physrover.core.compiled import jit
from physrover.core.streams import next_double, stream_handles
from physrover.domain.layouts import uniform_layouts


def _uniform_oracle(rng, k, half, gap, max_tries):
    """The uniform scenario's layout as it was drawn in Python: POIs one after another, each
    redrawn until it is gap from those before it; after max_tries failed draws of one POI,
    the whole layout again, up to max_tries times."""
    for _ in range(max_tries):
        out = []
        while len(out) < k:
            for _ in range(max_tries):
                u, v = rng.random(2).tolist()
                p = (half * (2.0 * u - 1.0), half * (2.0 * v - 1.0))
                if all(math.hypot(x - p[0], y - p[1]) >= gap for x, y in out):
                    break
            else:
                break
            out.append(p)
        if len(out) == k:
            return np.array(out)
    raise RuntimeError("no layout")


@jit
def _draw(handles, n, out):
    for e in range(handles.shape[0]):
        for i in range(n):
            out[e, i] = next_double(handles[e])


BIT_GENERATORS = [np.random.PCG64, np.random.PCG64DXSM, np.random.Philox, np.random.MT19937,
                  np.random.SFC64]  # fmt: skip


@pytest.mark.parametrize("bit_generator", BIT_GENERATORS)
def test_stream_handles_draw_what_the_generators_draw(bit_generator):
    ours = [np.random.Generator(bit_generator(seed)) for seed in range(6)]
    theirs = [np.random.Generator(bit_generator(seed)) for seed in range(6)]
    out = np.empty((6, 9))
    _draw(stream_handles(ours), 9, out)
    np.testing.assert_array_equal(out, np.stack([rng.random(9) for rng in theirs]))
    for a, b in zip(ours, theirs, strict=True):  # both go on from the same place
        np.testing.assert_array_equal(a.random(5), b.random(5))
        assert a.integers(1 << 40) == b.integers(1 << 40)


@pytest.mark.parametrize(("k", "half", "gap"), [(4, 15.0, 8.0), (10, 15.0, 8.5), (6, 5.0, 0.0),
                                                (1, 2.0, 3.0), (12, 10.0, 4.0)])  # fmt: skip
def test_uniform_layouts_are_the_plain_loops_layouts(k, half, gap):
    seeds = range(200)
    ours = [np.random.default_rng(seed) for seed in seeds]
    theirs = [np.random.default_rng(seed) for seed in seeds]
    for _ in range(3):  # the generators continue from where each layout left them
        drawn = uniform_layouts(ours, k, half, gap, 200)
        expected = np.stack([_uniform_oracle(rng, k, half, gap, 200) for rng in theirs])
        np.testing.assert_array_equal(drawn, expected)
    assert [rng.random() for rng in ours] == [rng.random() for rng in theirs]


def test_a_dense_layout_restarts_and_an_impossible_one_fails_in_one_line():
    # 10 POIs 8.5 apart in a 30 x 30 square need restarts now and then: the oracle's too.
    rngs = [np.random.default_rng(s) for s in range(30)]
    expected = [_uniform_oracle(np.random.default_rng(s), 10, 15.0, 8.5, 200) for s in range(30)]
    np.testing.assert_array_equal(uniform_layouts(rngs, 10, 15.0, 8.5, 200), expected)
    with pytest.raises(RuntimeError, match="no layout of 5 POIs 3.0 apart in 7 attempts"):
        uniform_layouts([np.random.default_rng(0)], 5, 1.0, 3.0, 7)
    with pytest.raises(TypeError, match="expected numpy.random.Generator objects, got RandomState"):
        uniform_layouts([np.random.RandomState(0)], 4, 15.0, 8.0, 200)
