"""The broad phase: the grid lists exactly the pairs, in exactly the order, that testing every
pair lists (random layouts, cell-boundary lines, coincident points, far coordinates, and
the states of crowds, head-on impacts and columns pushed into walls), and contacts hold
at team sizes that take the grid."""

import numpy as np
import pytest

from physrover import DomainConfig, RoverVectorEnv
from physrover.domain.broadphase import GRID_MIN_POINTS, near_pairs_all, near_pairs_grid
from physrover.domain.physics import pair_overlaps

PHYSICS = DomainConfig(motion="physics").replace(collisions=True)


def _both(points, reach):
    points = np.ascontiguousarray(points, dtype=np.float64)
    n = len(points)
    every = np.empty((max(n * (n - 1) // 2, 1), 2), np.int64)
    count = near_pairs_all(points, reach * reach, every)
    found, grid = near_pairs_grid(points, reach * reach, np.empty((1, 2), np.int64))
    return every[:count], grid[:found]


def _layouts(rng):
    n = int(rng.integers(2, 400))
    spread = float(rng.choice([0.5, 3.0, 20.0, 200.0]))
    yield rng.uniform(-spread, spread, (n, 2))  # uniform, sparse to packed
    yield rng.normal(0.0, spread / 4, (n, 2)) + rng.uniform(-1e6, 1e6, 2)  # far from origin
    clusters = rng.uniform(-spread, spread, (5, 2))
    yield clusters[rng.integers(0, 5, n)] + rng.normal(0, 0.05, (n, 2))  # clumps
    dup = rng.uniform(-1, 1, (n, 2))
    dup[n // 2 :] = dup[: n - n // 2]  # coincident pairs: never listed
    yield dup


@pytest.mark.parametrize("seed", range(60))
def test_the_grid_lists_the_pairs_every_pair_lists(seed):
    rng = np.random.default_rng(seed)
    for points in _layouts(rng):
        reach = float(rng.choice([0.4, 0.75, 1.3, 5.0]))
        every, grid = _both(points, reach)
        np.testing.assert_array_equal(grid, every)


def test_points_on_cell_boundaries_and_at_exactly_the_reach():
    reach = 0.5
    line = np.stack([np.arange(50) * reach, np.zeros(50)], axis=-1)  # each pair exactly reach
    lattice = np.stack(np.meshgrid(np.arange(12) * reach, np.arange(12) * reach), -1)
    for points in (line, line * 0.999, line * 1.001, lattice.reshape(-1, 2), -line):
        every, grid = _both(points, reach)
        np.testing.assert_array_equal(grid, every)
    assert len(_both(line * 0.999, reach)[1]) == 49  # neighbours only


def _episode_states(config, start, headings, command, steps):
    env = RoverVectorEnv(len(start), config=config)
    env.reset(seed=0, options={"rover_positions": start, "rover_headings": headings})
    states = []
    for _ in range(steps):
        states.append(env.step(command)[4]["rover_positions"])
    return states


def test_the_grid_lists_the_same_pairs_in_crowds_impacts_and_columns():
    """The pairs the contact pass would visit, from both broad phases, at every step of
    large-team episodes: a crowd, two lines meeting head on, a column driven into a wall
    (the reach of a physics step of rovers at their top speed, and wider)."""
    rng = np.random.default_rng(0)
    n = 80
    crowd = PHYSICS.replace(n_rovers=n, n_req=1, steps=20,
                            scenario={"kind": "ring", "spawn_radius": 5.0})  # fmt: skip
    env = RoverVectorEnv(3, config=crowd)
    env.reset(seed=1)
    states = []
    for _ in range(crowd.steps):
        action = np.stack([np.ones((3, n)), rng.uniform(-1, 1, (3, n))], axis=-1)
        states.append(env.step(action)[4]["rover_positions"])
    half = n // 2
    lines = np.zeros((1, n, 2))
    lines[0, :half] = np.stack([np.full(half, -3.0), np.linspace(-8, 8, half)], -1)
    lines[0, half:] = np.stack([np.full(half, 3.0), np.linspace(-8, 8, half) + 0.1], -1)
    heads = np.r_[np.zeros(half), np.full(half, np.pi)]
    config = PHYSICS.replace(n_rovers=n, n_req=1, steps=6, scenario="explicit",
                             poi_positions=[[0.0, 2.0]], poi_values=(1.0,))  # fmt: skip
    states += _episode_states(config, lines, heads, np.tile([1.0, 0.0], (1, n, 1)), 6)
    column = np.stack([np.linspace(-22, 22, n), np.linspace(-0.3, 0.3, n)], -1)[None]
    walled = config.replace(walls=True, wall_half_size=25.0, steps=20)
    states += _episode_states(walled, column, np.zeros(n), np.tile([1.0, 0.0], (1, n, 1)), 20)
    assert GRID_MIN_POINTS > 0  # the lists below are compared whichever path the world takes
    for positions in states:
        for team in positions:
            for reach in (0.4 + 2 * 0.25, 1.0):
                every, grid = _both(team, reach)
                np.testing.assert_array_equal(grid, every)


def test_contacts_hold_in_a_crowd_of_two_hundred():
    n = 200
    cfg = PHYSICS.replace(n_rovers=n, n_req=1, steps=30,
                          scenario={"kind": "ring", "spawn_radius": 6.0})  # fmt: skip
    env = RoverVectorEnv(2, config=cfg)
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    worst = 0.0
    for _ in range(cfg.steps):
        toward = rng.uniform(-1, 1, (2, n, 2))
        toward[..., 0] = 1.0
        positions = env.step(toward)[4]["rover_positions"]
        worst = max(worst, pair_overlaps(positions, cfg.physics.rover_radius).max())
    assert worst <= 0.05  # of a diameter, as at 15 rovers
