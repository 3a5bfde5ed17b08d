"""Sensing (Eqs. 14-16): hand-worked values, quadrant boundaries, and plain-loop oracles.

Each check runs on the package's compiled kernel and on the numpy oracle (tests/oracles.py),
so a hand-worked value that fails on one only points at that one."""

import math

import numpy as np
import pytest
from oracles import observe, quadrants, relate

from physrover.domain.motion.ideal import heading_trig
from physrover.domain.sensing import density, sectors
from physrover.domain.state import WorldState


def compiled_observe(rovers, headings, pois, values, d_min):
    """Observations from the compiled kernel (same arguments as ``oracles.observe``)."""
    n_teams, n_rovers, _ = rovers.shape
    state = WorldState.zeros(n_teams, n_rovers, pois.shape[1])
    state.rover_positions[:] = rovers
    state.rover_headings[:] = headings
    state.poi_positions[:] = pois
    state.poi_values[:] = values
    heading_trig(state.rover_headings, state.cos_h, state.sin_h)
    obs = np.empty((n_teams, n_rovers, 8), dtype=np.float32)
    density.sense(state, d_min * d_min, (0,) * 4, None, obs)
    return obs


OBSERVE = {"oracle": observe, "compiled": compiled_observe}


@pytest.fixture(params=list(OBSERVE))
def engine(request):
    return request.param


def _obs(rovers, headings, pois, values, d_min=1.0, engine="compiled"):
    return OBSERVE[engine](
        np.array([rovers], dtype=float),
        np.array([headings], dtype=float),
        np.array([pois], dtype=float),
        np.array([values], dtype=float),
        d_min,
    )[0]


def test_hand_worked_observation(engine):
    # Rover 0 at the origin facing +x. Rover 1 dead ahead at distance 2 -> front-left (q2),
    # 1/4. Rover 2 dead right at 0.5 < d_min -> front-right (q1), 1/d_min^2 = 1.
    # POI V=2 dead behind at 1 -> behind-right (q0), 2/1. POI V=4 dead left at 3 ->
    # behind-left (q3), 4/9.
    obs = _obs(
        rovers=[(0, 0), (2, 0), (0, -0.5)],
        headings=[0.0, 0.0, 0.0],
        pois=[(-1, 0), (0, 3)],
        values=[2.0, 4.0],
        engine=engine,
    )
    np.testing.assert_allclose(obs[0], [0, 1.0, 0.25, 0, 2.0, 0, 0, 4 / 9], rtol=1e-6)
    # Rover 1 (facing +x at (2, 0)): rover 0 dead behind (q0) at 2 -> 1/4; rover 2 behind and
    # to the right at sqrt(4.25) (q0) -> 1/4.25. POIs: (-1,0) behind at 3 -> 2/9 (q0);
    # (0,3) behind-left (q3) at sqrt(13) -> 4/13.
    np.testing.assert_allclose(obs[1], [0.25 + 1 / 4.25, 0, 0, 0, 2 / 9, 0, 0, 4 / 13], rtol=1e-6)


def test_d_min_bounds_the_distance(engine):
    # Coincident and very close objects both count as 1/d_min^2, never more.
    obs = _obs(
        rovers=[(0, 0), (0.01, 0.0), (0.0, 0.0)],
        headings=[0.0, 0.0, 0.0],
        pois=[(0.0, 0.2)],
        values=[3.0],
        d_min=0.5,
        engine=engine,
    )
    # rover 1 dead ahead (q2), rover 2 coincident (bearing 0 -> q2): each 1/0.25 = 4.
    # POI dead left at 0.2 < 0.5 (q3): 3 / 0.25 = 12.
    np.testing.assert_allclose(obs[0], [0, 0, 8.0, 0, 0, 0, 0, 12.0], rtol=1e-6)


def test_sensing_uses_the_rovers_own_frame(engine):
    # Same layout, rover rotated by +90 deg: the object at world (0, 2) is now dead ahead.
    # (Headings with inexact sines keep objects off the boundaries.)
    obs = _obs(
        rovers=[(0, 0), (0.3, 2.0)],
        headings=[math.pi / 2, 0.0],
        pois=[(-3, 0.2)],
        values=[1.0],
        engine=engine,
    )
    # rover 1 at (0.3, 2): in rover 0's frame forward 2, left -0.3 -> front-right (q1).
    # POI at (-3, 0.2): forward 0.2, left 3 -> front-left (q2).
    np.testing.assert_allclose(obs[0], [0, 1 / 4.09, 0, 0, 0, 0, 1 / 9.04, 0], rtol=1e-6)


@pytest.mark.parametrize(
    ("forward", "left", "q"),
    [
        (1.0, 0.0, 2),  # dead ahead: 0 deg starts front-left
        (0.0, -1.0, 1),  # dead right: -90 deg starts front-right
        (0.0, 1.0, 3),  # dead left: 90 deg starts behind-left
        (-1.0, 0.0, 0),  # dead behind: 180 deg wraps to -180, behind-right
        (-1.0, -0.0, 0),
        (0.0, 0.0, 2),  # own position: bearing atan2(0, 0) = 0
        (1.0, 1.0, 2),
        (-1.0, 1.0, 3),
        (-1.0, -1.0, 0),
        (1.0, -1.0, 1),
    ],
)
def test_quadrant_boundaries(forward, left, q):
    assert quadrants(np.array([forward]), np.array([left]))[0] == q
    assert sectors.quadrant(forward, left) == q


def test_quadrant_matches_the_atan2_definition():
    rng = np.random.default_rng(0)
    f, l = rng.standard_normal((2, 5000))
    b = np.arctan2(l, f)
    b = np.where(b >= math.pi, -math.pi, b)
    expected = np.floor((b + math.pi) / (math.pi / 2)).astype(int)
    np.testing.assert_array_equal(quadrants(f, l), expected)
    compiled = [sectors.quadrant(*fl) for fl in zip(f, l, strict=True)]
    np.testing.assert_array_equal(compiled, expected)


def _reference_observe(rovers, headings, pois, values, d_min):
    """Plain loops straight from Eqs. 14-16 and the atan2 quadrant definition."""
    n_teams, n_rovers, _ = rovers.shape
    out = np.zeros((n_teams, n_rovers, 8))
    for e in range(n_teams):
        for i in range(n_rovers):
            objects = [(rovers[e, j], 1.0, 0) for j in range(n_rovers) if j != i]
            objects += [(pois[e, k], values[e, k], 4) for k in range(pois.shape[1])]
            for pos, numerator, base in objects:
                dx, dy = pos - rovers[e, i]
                b = math.atan2(dy, dx) - headings[e, i]
                b = (b + math.pi) % (2 * math.pi) - math.pi
                q = int((b + math.pi) // (math.pi / 2))
                delta = max(math.hypot(dx, dy), d_min)
                out[e, i, base + q] += numerator / delta**2
    return out


def test_batched_equals_plain_loop(engine):
    rng = np.random.default_rng(1)
    rovers = rng.uniform(-6, 6, (4, 7, 2))
    headings = rng.uniform(-math.pi, math.pi, (4, 7))
    pois = rng.uniform(-15, 15, (4, 3, 2))
    values = rng.uniform(0.5, 4, (4, 3))
    np.testing.assert_allclose(
        OBSERVE[engine](rovers, headings, pois, values, 1.0),
        _reference_observe(rovers, headings, pois, values, 1.0),
        rtol=2e-5,
    )


def test_relations_shapes_and_self_distance():
    rel = relate(
        np.zeros((2, 3, 2)) + [[[0, 0], [1, 0], [5, 5]]],
        np.zeros((2, 3)),
        np.ones((2, 4, 2)),
        d_min=1.0,
    )
    assert rel.delta_sq.shape == rel.quadrant.shape == (2, 3, 7)
    assert rel.delta_sq[0, 2, 2] == 1.0  # own distance is bounded to d_min^2


def _sector_oracle(rovers, headings, pois, values, d_min, n, radius):
    """Plain loops from world-frame angles: an object's bearing is its direction minus the
    rover's heading, wrapped to [-pi, pi); sector floor((b + pi) n / (2 pi))."""
    n_teams, n_rovers, _ = rovers.shape
    out = np.zeros((n_teams, n_rovers, 2 * n))
    for e in range(n_teams):
        for i in range(n_rovers):
            others = [(rovers[e, j], 1.0, 0) for j in range(n_rovers) if j != i]
            others += [(pois[e, k], values[e, k], n) for k in range(pois.shape[1])]
            for pos, value, offset in others:
                dx, dy = pos - rovers[e, i]
                dist = math.hypot(dx, dy)
                if dist > radius:
                    continue
                b = (math.atan2(dy, dx) - headings[e, i] + math.pi) % (2 * math.pi) - math.pi
                q = int((b + math.pi) * n / (2 * math.pi)) % n
                out[e, i, offset + q] += value / max(dist, d_min) ** 2
    return out


@pytest.mark.parametrize(("n", "radius", "n_rovers"), [(4, np.inf, 7), (6, np.inf, 7),
                                                    (3, np.inf, 7), (6, 5.0, 7),
                                                    (6, 5.0, 70), (4, 3.0, 70)])  # fmt: skip
def test_sectors_and_radius_match_the_plain_loop_oracle(n, radius, n_rovers):
    rng = np.random.default_rng(n)
    rovers = rng.uniform(-8, 8, (5, n_rovers, 2))
    headings = rng.uniform(-np.pi, np.pi, (5, n_rovers))
    pois = rng.uniform(-8, 8, (5, 3, 2))
    values = rng.uniform(1, 4, (5, 3))
    state = WorldState.zeros(5, n_rovers, 3)
    for name, value in (("rover_positions", rovers), ("rover_headings", headings),
                        ("poi_positions", pois), ("poi_values", values)):  # fmt: skip
        getattr(state, name)[:] = value
    heading_trig(state.rover_headings, state.cos_h, state.sin_h)
    obs = np.empty((5, n_rovers, 2 * n), dtype=np.float32)
    density.sense(state, 1.0, (0,) * n, radius**2 if radius < np.inf else None, obs)
    expected = _sector_oracle(rovers, headings, pois, values, 1.0, n, radius)
    np.testing.assert_allclose(obs, expected, rtol=1e-6, atol=1e-9)
    if radius < np.inf:  # the radius took something away
        full = np.empty_like(obs)
        density.sense(state, 1.0, (0,) * n, None, full)
        assert (full.sum(-1) > obs.sum(-1) + 1e-6).any()


def test_the_radius_excludes_an_object_just_beyond_it():
    # Rover at the origin facing +x; a POI (value 2) dead ahead at 5, another at 5 + 1e-9.
    def seen(distance, radius=5.0):
        state = WorldState.zeros(1, 1, 1)
        state.poi_positions[:] = [[[distance, 0.0]]]
        state.poi_values[:] = 2.0
        heading_trig(state.rover_headings, state.cos_h, state.sin_h)
        obs = np.empty((1, 1, 12), dtype=np.float32)
        density.sense(state, 1.0, (0,) * 6, radius**2 if radius < np.inf else None, obs)
        return obs[0, 0]

    # Six sectors of 60 deg from dead behind: dead ahead (bearing 0) starts sector 3.
    np.testing.assert_allclose(seen(5.0)[6 + 3], 2.0 / 25.0, rtol=1e-7)
    assert seen(5.0).sum() == pytest.approx(2.0 / 25.0, rel=1e-7)
    assert not seen(5.0 + 1e-9).any()
    assert seen(5.0 + 1e-9, radius=np.inf).sum() > 0


@pytest.mark.parametrize("n", [4, 6])
def test_sectors_through_the_env_and_the_ccea(n):
    from gymnasium.utils.env_checker import check_env

    from physrover import RoverEnv
    from physrover.config import ConfigError, DomainConfig, RunConfig
    from physrover.learn.ccea import CCEA

    env = RoverEnv(n_rovers=3, sectors=n, radius=10.0)
    assert env.observation_space.shape == (3, 2 * n)
    check_env(env, skip_render_check=True)
    ccea = CCEA(RunConfig().with_overrides({"sectors": n, "n_rovers": 3, "population": 4,
                                            "eval_episodes": 1, "steps": 5}))  # fmt: skip
    ccea.run_generation()
    assert ccea.layout.n_in == 2 * n
    with pytest.raises(ConfigError, match="sectors: must be >= 1"):
        DomainConfig(sensor={"kind": "density", "sectors": 0})
    with pytest.raises(ConfigError, match="radius: must be > 0"):
        DomainConfig().replace(radius=-1.0)


def _same_order_observe(state, d_min, radius_sq=None):
    """The sensor's arithmetic as a plain loop, in the kernels' float64 order: each channel
    adds its objects' terms one by one (rovers by index, then POIs), ``1 / max(d^2,
    d_min^2)`` and ``V / max(d^2, d_min^2)``, in the rover's frame from cos_h and sin_h."""
    n_teams, n_rovers = state.cos_h.shape
    out = np.zeros((n_teams, n_rovers, 8), dtype=np.float32)
    for e in range(n_teams):
        for i in range(n_rovers):
            c, s = float(state.cos_h[e, i]), float(state.sin_h[e, i])
            xi, yi = state.rover_positions[e, i]
            acc = [0.0] * 8
            objects = [(*state.rover_positions[e, j], 1.0, 0) for j in range(n_rovers) if j != i]
            objects += [(*state.poi_positions[e, k], state.poi_values[e, k], 4)
                        for k in range(state.poi_positions.shape[1])]  # fmt: skip
            for x, y, numerator, base in objects:
                dx, dy = float(x) - float(xi), float(y) - float(yi)
                d_sq = dx * dx + dy * dy
                if radius_sq is not None and d_sq > radius_sq:
                    continue
                q = sectors.quadrant.py_func(c * dx + s * dy, c * dy - s * dx)
                acc[base + q] += float(numerator) / max(d_sq, d_min * d_min)
            out[e, i] = acc
    return out


def _coarse_state(n_teams, n_rovers, seed):
    """Rovers and 4 POIs on a coarse grid (objects on quadrant boundaries, at equal
    distances, exactly at a radius, on each other), headings on and off the axes."""
    rng = np.random.default_rng(seed)
    state = WorldState.zeros(n_teams, n_rovers, 4)
    state.rover_positions[:] = rng.integers(-6, 7, (n_teams, n_rovers, 2)) * 0.5
    state.rover_headings[:] = rng.choice([0.0, math.pi / 2, 1.0, -2.5], (n_teams, n_rovers))
    state.poi_positions[:] = rng.integers(-8, 9, (n_teams, 4, 2)) * 1.0
    state.poi_values[:] = rng.uniform(0.5, 4.0, (n_teams, 4))
    heading_trig(state.rover_headings, state.cos_h, state.sin_h)
    return state


@pytest.mark.parametrize("n_rovers", [1, 4, 15, 16, 17, 33, 60, 130])
@pytest.mark.parametrize("radius", [None, 4.0, 1.5])
def test_the_vectorised_quadrant_sensor_is_the_plain_loop_bit_for_bit(n_rovers, radius):
    """The compiled sensor adds +0.0 to the three other channels of each object, over
    lanes padded to 16 rovers: the same sums in the same order as the plain loop. Positions
    on a coarse grid put objects on the quadrant boundaries and at equal distances (and
    exactly at the radius, and on each other). (The grid path, which a radius takes from
    SENSOR_GRID_MIN_POINTS rovers, is checked below.)"""
    state = _coarse_state(3, n_rovers, seed=n_rovers)
    obs = np.empty((3, n_rovers, 8), dtype=np.float32)
    radius_sq = None if radius is None else radius * radius
    density.sense(state, 1.0, (0,) * 4, radius_sq, obs)
    np.testing.assert_array_equal(obs, _same_order_observe(state, 1.0, radius_sq))


@pytest.mark.parametrize("n_rovers", [2, 7, 33, 90])
@pytest.mark.parametrize("radius", [4.0, 2.0, 0.5])
def test_the_grid_sensor_sees_the_plain_loops_neighbours_in_their_sectors(n_rovers, radius):
    """The sensor's grid path (:func:`physrover.domain.density._sense_local`, which
    the world takes from SENSOR_GRID_MIN_POINTS rovers) called directly on small teams,
    with d_min = radius (a power of 2): every seen object's term is then 1 / radius^2 (V_k
    / radius^2 for a POI), so each sum is exact in any order and the observations are
    exactly the plain loop's only if every rover sees the same objects in the same
    sectors. Coarse positions: objects on quadrant boundaries, exactly at the radius, and
    on each other."""

    state = _coarse_state(2, n_rovers, seed=n_rovers)
    state.poi_values[:] = 1.0  # exact sums of POI terms too
    obs = np.empty((2, n_rovers, 8), dtype=np.float32)
    for e in range(2):
        density._sense_local(e, state, radius * radius, 4, radius * radius, obs)
    np.testing.assert_array_equal(obs, _same_order_observe(state, radius, radius * radius))
    assert n_rovers == 2 or (obs[..., :4] > 0).any()  # the radius left some rovers in view


@pytest.mark.parametrize("n_rovers", [33, 200])
@pytest.mark.parametrize("radius", [4.0, 1.5])
def test_the_grid_sensor_sums_as_the_plain_loop_to_rounding(n_rovers, radius):
    """Terms of every size: the grid path adds them in the grid's order, so a sum may
    differ from the plain loop's by float64 rounding, which float32 shows at most as one
    unit in the last place, and rarely."""

    rng = np.random.default_rng(n_rovers)
    state = WorldState.zeros(3, n_rovers, 4)
    state.rover_positions[:] = rng.uniform(-8, 8, (3, n_rovers, 2))
    state.rover_headings[:] = rng.uniform(-math.pi, math.pi, (3, n_rovers))
    state.poi_positions[:] = rng.uniform(-8, 8, (3, 4, 2))
    state.poi_values[:] = rng.uniform(0.5, 4.0, (3, 4))
    heading_trig(state.rover_headings, state.cos_h, state.sin_h)
    obs = np.empty((3, n_rovers, 8), dtype=np.float32)
    for e in range(3):
        density._sense_local(e, state, 1.0, 4, radius * radius, obs)
    expected = _same_order_observe(state, 1.0, radius * radius)
    np.testing.assert_array_max_ulp(obs, expected, maxulp=1)
    assert (obs == expected).mean() > 0.999
    assert (obs[..., :4] > 0).mean() > 0.15  # rovers in view


def test_a_team_above_the_grid_threshold_senses_as_the_plain_loop():
    from physrover.domain.broadphase import SENSOR_GRID_MIN_POINTS

    n_rovers = SENSOR_GRID_MIN_POINTS
    rng = np.random.default_rng(0)
    state = WorldState.zeros(1, n_rovers, 4)
    state.rover_positions[:] = rng.uniform(-20, 20, (1, n_rovers, 2))
    state.rover_headings[:] = rng.uniform(-math.pi, math.pi, (1, n_rovers))
    state.poi_positions[:] = rng.uniform(-20, 20, (1, 4, 2))
    state.poi_values[:] = 1.0
    heading_trig(state.rover_headings, state.cos_h, state.sin_h)
    obs = np.empty((1, n_rovers, 8), dtype=np.float32)
    density.sense(state, 9.0, (0,) * 4, 9.0, obs)  # d_min = radius: exact sums, any order
    np.testing.assert_array_equal(obs, _same_order_observe(state, 3.0, 9.0))
    density.sense(state, 1.0, (0,) * 4, 9.0, obs)  # every size of term: to rounding
    np.testing.assert_array_max_ulp(obs, _same_order_observe(state, 1.0, 9.0), maxulp=1)
