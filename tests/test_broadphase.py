"""The broad phase: the grid lists exactly the pairs, in exactly the order, that testing every
pair lists (random layouts, cell-boundary lines, coincident points, far coordinates, and
the states of crowds, head-on impacts and columns pushed into walls), and contacts hold
at team sizes that take the grid."""

import math

import numpy as np
import pytest

from physrover import DomainConfig, RoverVectorEnv
from physrover.core.compiled import jit
from physrover.domain.broadphase import (
    GRID_MIN_POINTS,
    drain_ascending,
    mark,
    near_pairs_all,
    near_pairs_grid,
)
from physrover.domain.motion.contacts import speculative_contacts
from physrover.domain.motion.separation import pair_overlaps, separate_teams

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


def _inclusive_pairs(points, reach_sq):
    """The sensor's pairs as a plain loop: i < j, squared distance <= reach_sq, coincident
    ones included, in index order."""
    n = len(points)
    return [(i, j) for i in range(n) for j in range(i + 1, n)
            if ((points[j] - points[i]) ** 2).sum() <= reach_sq]  # fmt: skip


@pytest.mark.parametrize("seed", range(20))
def test_the_grid_lists_a_sensors_pairs_coincident_ones_too(seed):
    rng = np.random.default_rng(100 + seed)
    for points in _layouts(rng):
        points = np.ascontiguousarray(points[:150])
        reach = float(rng.choice([0.5, 2.0, 5.0]))
        count, grid = near_pairs_grid(points, reach * reach, np.empty((1, 2), np.int64), True)
        expected = _inclusive_pairs(points, reach * reach)
        np.testing.assert_array_equal(grid[:count], np.array(expected, np.int64).reshape(-1, 2))


def test_points_with_nan_or_infinite_coordinates_are_listed_with_nothing():
    """As testing every pair does (their distances compare False), for both kinds of list;
    the finite points keep their pairs."""
    rng = np.random.default_rng(0)
    points = rng.uniform(-2, 2, (40, 2))
    points[3] = [np.nan, 0.0]
    points[7] = [np.inf, 1.0]
    points[8] = [-np.inf, np.nan]
    every, grid = _both(points, 0.9)
    np.testing.assert_array_equal(grid, every)
    count, sensed = near_pairs_grid(points, 0.81, np.empty((1, 2), np.int64), True)
    np.testing.assert_array_equal(sensed[:count], np.array(_inclusive_pairs(points, 0.81)))
    assert not {3, 7, 8} & set(sensed[:count].ravel())
    nothing = np.full((5, 2), np.nan)
    assert near_pairs_grid(nothing, 1.0, np.empty((1, 2), np.int64))[0] == 0


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


def _contacts_every_pair_every_sweep(positions, velocities, contact, mass, dt, allowance, sweeps,
                                     radius=None, capsules=None):  # fmt: skip
    """The contact pass as it reads (the docstring of :func:`speculative_contacts`), a
    plain loop: every pair of every team tested in every sweep, in index order, then every
    rover against the capsules (the package's own ``_capsule_contact``), until a sweep
    changes nothing."""
    from physrover.domain.motion.contacts import _capsule_contact

    points, velocities = positions, velocities.copy()
    positions = positions.tolist()
    for e, team in enumerate(positions):
        n = len(team)
        for _ in range(sweeps):
            changed = False
            for i in range(n):
                for j in range(i + 1, n):
                    dx, dy = team[j][0] - team[i][0], team[j][1] - team[i][1]
                    d = math.sqrt(dx * dx + dy * dy)
                    if d < 1e-12:
                        continue
                    nx, ny = dx / d, dy / d
                    v = velocities[e]
                    u = (v[i, 0] - v[j, 0]) * nx + (v[i, 1] - v[j, 1]) * ny
                    limit = (d - contact[i, j] + allowance) / dt
                    if u > limit:
                        excess = u - limit
                        share_i = excess * (mass[j] / (mass[i] + mass[j]))
                        share_j = excess * (mass[i] / (mass[i] + mass[j]))
                        v[i, 0] -= share_i * nx
                        v[i, 1] -= share_i * ny
                        v[j, 0] += share_j * nx
                        v[j, 1] += share_j * ny
                        changed = True
            for i in range(n if capsules is not None else 0):
                if _capsule_contact(points, velocities, e, i, radius[i], capsules, dt, allowance):
                    changed = True
            if not changed:
                break
    return velocities


@pytest.mark.parametrize("n", [12, GRID_MIN_POINTS + 20])
def test_the_contact_pass_is_every_pair_every_sweep_bit_for_bit(n):
    """The pass visits only the pairs within reach, and of those only the ones whose
    velocities changed since their last visit; the plain loop visits every pair every
    sweep. Crowds of rovers of unequal sizes and masses driving at each other."""
    rng = np.random.default_rng(n)
    for trial in range(6):
        spread = 0.3 * math.sqrt(n) * (1 + trial % 3)
        positions = rng.uniform(-spread, spread, (2, n, 2))
        velocities = rng.normal(0.0, 1.5, (2, n, 2))
        radius = rng.uniform(0.15, 0.3, n)
        contact = radius[:, None] + radius[None, :]
        mass = rng.uniform(0.5, 2.0, n)
        before = velocities.copy()
        expected = _contacts_every_pair_every_sweep(positions, velocities, contact, mass,
                                                    0.25, 0.01, 20)  # fmt: skip
        speculative_contacts(positions, velocities, contact, mass, radius, None, 0.25, 0.01, 20)
        np.testing.assert_array_equal(velocities, expected)
        assert not np.array_equal(velocities, before)  # contacts did act
        # Walls around them (capsules: segment ends, thickness) that push back along rows
        # of rovers: a rover's capsule contact makes its pairs to be visited again.
        half = spread * 0.8
        corners = [(-half, -half), (half, -half), (half, half), (-half, half), (-half, -half)]
        walls = np.array([[*corners[c], *corners[c + 1], 0.1] for c in range(4)])
        capsules = np.ascontiguousarray(np.broadcast_to(walls, (2, 4, 5)))
        velocities = before.copy()
        expected = _contacts_every_pair_every_sweep(positions, velocities, contact, mass,
                                                    0.25, 0.01, 20, radius, capsules)  # fmt: skip
        speculative_contacts(positions, velocities, contact, mass, radius, capsules, 0.25, 0.01,
                             20)  # fmt: skip
        np.testing.assert_array_equal(velocities, expected)


@pytest.mark.parametrize("n", [GRID_MIN_POINTS, 300])
def test_the_spawn_separation_from_the_grid_is_every_pair_bit_for_bit(n):
    """:func:`separate_teams` on a symmetric contact matrix takes the grid from
    GRID_MIN_POINTS rovers; asked not to (``symmetric=False``), it tests every pair. Crowds
    started in a disc far too small, with coincident points."""
    rng = np.random.default_rng(n)
    radius = rng.uniform(0.15, 0.3, n)
    contact = np.ascontiguousarray(radius[:, None] + radius[None, :])
    r = 0.15 * math.sqrt(n) * np.sqrt(rng.uniform(0, 1, (2, n)))
    angle = rng.uniform(0, 2 * np.pi, (2, n))
    x, y = r * np.cos(angle), r * np.sin(angle)
    x[:, 1], y[:, 1] = x[:, 0], y[:, 0]  # a coincident pair
    every = (x.copy(), y.copy())
    grid = (x.copy(), y.copy())
    separate_teams(*every, contact, 1e-3, 500, False)
    separate_teams(*grid, contact, 1e-3, 500, True)
    np.testing.assert_array_equal(grid[0], every[0])
    np.testing.assert_array_equal(grid[1], every[1])
    assert not np.array_equal(every[0], x)  # they were crowded, and were pushed apart
    d = np.hypot(every[0][:, :, None] - every[0][:, None], every[1][:, :, None] - every[1][:, None])
    assert (d + np.eye(n) * 10 >= contact - 1e-3 - 1e-9).all()


def test_contacts_hold_in_a_jam_of_four_hundred():
    """400 rovers (spread as the scaling benchmark spreads them, so the grid lists the
    pairs) all driven at full command towards the team's centre for 50 steps: a jam as
    deep as the team is wide. Step ends stay within 1.5% of a diameter, as at 15 rovers;
    with the 20 sweeps of a 15-rover team a 1000-rover jam reached 8.9%."""
    from physrover.experiment.bench import scaling_config

    cfg = scaling_config(PHYSICS, 400).replace(steps=50)
    env = RoverVectorEnv(1, config=cfg)
    _, info = env.reset(seed=0)
    worst = 0.0
    for _ in range(cfg.steps):
        positions, headings = info["rover_positions"], info["rover_headings"]
        toward = -positions / np.linalg.norm(positions, axis=-1, keepdims=True)
        c, s = np.cos(headings), np.sin(headings)
        command = np.stack([c * toward[..., 0] + s * toward[..., 1],
                            -s * toward[..., 0] + c * toward[..., 1]], axis=-1)  # fmt: skip
        info = env.step(command)[4]
        worst = max(worst, pair_overlaps(info["rover_positions"], cfg.physics.rover_radius).max())
    assert worst <= 0.015
    spread = np.linalg.norm(info["rover_positions"], axis=-1).max()
    assert spread < 0.5 * cfg.scenario.spawn_radius  # they did jam at the centre


def test_a_set_of_bits_drains_its_indices_in_ascending_order():
    """mark / drain_ascending against sorted(set(...)): indices across several words, the
    64-bit boundaries, repeats, an empty set; the set is empty again after each drain."""

    @jit
    def through_bits(indices, marks, out):
        for j in indices:
            mark(marks, j)
        return drain_ascending(marks, out)

    rng = np.random.default_rng(5)
    n = 300
    marks = np.zeros((n + 63) // 64, np.uint64)
    out = np.full(n, -1, np.int64)
    cases = [np.array([63, 64, 0, 127, 128, 299, 64], np.int64), np.zeros(0, np.int64)]
    cases += [rng.integers(0, n, rng.integers(1, 80)) for _ in range(200)]
    for indices in cases:
        expected = sorted(set(indices.tolist()))
        count = through_bits(indices, marks, out)
        assert out[:count].tolist() == expected
        assert not marks.any()
