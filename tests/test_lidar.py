"""The lidar sensor (issue 33): hand-worked scans, the density sensor as one of its settings,
a plain-loop oracle, and the envs' spaces with a negative empty value."""

import math

import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from physrover.config import ConfigError, DomainConfig
from physrover.domain.lidar import Lidar
from physrover.domain.world import RoverWorld, StartOverrides
from physrover.envs import RoverEnv


def _scan(rovers, pois=(), values=(), headings=None, **sensor):
    """Rover 0's readings: rovers (R, 2), pois (K, 2) with values, one team."""
    rovers = np.asarray(rovers, dtype=float)
    pois = np.asarray(pois or [(100.0, 100.0)], dtype=float)  # a POI too far to matter
    values = values or (1.0,) * len(pois)
    config = DomainConfig(n_rovers=len(rovers), poi_values=tuple(values), n_req=1,
                          sensor={"kind": "lidar", **sensor})  # fmt: skip
    world = RoverWorld(config, 1)
    heads = np.zeros(len(rovers)) if headings is None else np.asarray(headings, dtype=float)
    obs = world.reset([np.random.default_rng(0)], StartOverrides(
        rover_positions=rovers, rover_headings=heads, poi_positions=pois,
        poi_values=np.asarray(values, dtype=float)))  # fmt: skip
    return obs[0, 0]


def test_hand_worked_scan_heading_frame():
    # rover 0 at the origin facing +x. Rover 1 at (2, 0) is dead ahead: front-left (2),
    # 1 / 2^2. POI of value 2 at (0, -3) is dead right: front-right (1), 2 / 3^2.
    obs = _scan([(0, 0), (2, 0)], pois=[(0, -3)], values=(2.0,), empty=-1.0, radius=10.0)
    expected = [-1, -1, 0.25, -1, -1, 2 / 9, -1, -1]
    np.testing.assert_allclose(obs, expected, rtol=1e-7)


@pytest.mark.parametrize(("compose", "reading"),
                         [("density", 1.25), ("average", 0.625), ("closest", 1.0)])  # fmt: skip
def test_two_rovers_in_one_sector_compose(compose, reading):
    obs = _scan([(0, 0), (1, 0.0), (2, 0.0)], compose=compose, empty=-1.0, radius=10.0)
    assert obs[2] == pytest.approx(reading, rel=1e-7)  # 1/1 and 1/4, front-left
    assert list(obs[[0, 1, 3]]) == [-1.0, -1.0, -1.0]


def test_closest_is_the_largest_term_not_the_nearest_object():
    # POIs of value 4 at distance 2 (term 1) and value 1 at distance 1 (term 1): equal;
    # value 8 at distance 2 (term 2) beats value 1 at distance 1 (term 1).
    obs = _scan([(0, 0), (50, 50)], pois=[(2, 0), (1, 0)], values=(8.0, 1.0),
                compose="closest", radius=10.0)  # fmt: skip
    assert obs[4 + 2] == pytest.approx(2.0)


def test_world_bearing_ignores_the_heading():
    # an object at (0, 3) is at 90 degrees: sector 1 of four (the lab's l2a), whatever the
    # heading; relative to a heading of pi/2 it would be dead ahead (sector 2)
    for heading in (0.0, math.pi / 2, 2.0):
        obs = _scan([(0, 0), (0, 3)], headings=[heading, 0.0], bearing="world", radius=10.0)
        assert obs[1] == pytest.approx(1 / 9) and obs[[0, 2, 3]].tolist() == [0, 0, 0]
    # 0 degrees exactly is sector 0; just below 360 is the last sector
    assert _scan([(0, 0), (3, 0)], bearing="world", radius=10.0)[0] == pytest.approx(1 / 9)
    assert _scan([(0, 0), (3, -1e-9)], bearing="world", radius=10.0)[3] > 0


def test_linear_measure_and_radius():
    obs = _scan([(0, 0), (2, 0), (4.5, 0)], measure="linear", radius=4.0)
    assert obs[2] == pytest.approx(0.5)  # 1 - 2/4; the rover at 4.5 is beyond the radius
    assert _scan([(0, 0), (4, 0)], measure="linear", radius=4.0, empty=-1.0)[2] == 0.0
    with pytest.raises(ConfigError, match='measure: "linear" is 1 - d / radius'):
        Lidar(measure="linear")


@pytest.mark.parametrize("sectors", [4, 6])
@pytest.mark.parametrize("radius", [math.inf, 6.0])
def test_density_composition_is_the_density_sensor_bit_for_bit(sectors, radius):
    base = DomainConfig(n_rovers=12, n_req=2)
    worlds = [RoverWorld(base.replace(sensor={"kind": kind, "sectors": sectors,
                                              "radius": radius}), 5)
              for kind in ("density", "lidar")]  # fmt: skip
    rng = np.random.default_rng(sectors)
    actions = rng.uniform(-1, 1, (30, 5, 12, 2))
    for w in worlds:
        w.reset([np.random.default_rng(e) for e in range(5)])
        for a in actions:
            w.step(a)
    np.testing.assert_array_equal(worlds[0].observations, worlds[1].observations)
    assert (worlds[1].observations > 0).mean() > 0.1  # not every sector empty


def _oracle(positions, headings, pois, values, n_sectors, radius, compose, empty, d_min):
    """Plain loops over one team: every rover's lidar readings, heading frame, inverse
    square measure, the sector from the bearing angle."""
    out = []
    for i, (x, y) in enumerate(positions):
        channels = [[] for _ in range(2 * n_sectors)]
        objects = [(p, 1.0, 0) for j, p in enumerate(positions) if j != i]
        objects += [(p, v, n_sectors) for p, v in zip(pois, values, strict=True)]
        for (ox, oy), num, base in objects:
            d = math.hypot(ox - x, oy - y)
            if d > radius:
                continue
            bearing = math.atan2(oy - y, ox - x) - headings[i]  # relative to the heading
            bearing = (bearing + math.pi) % (2 * math.pi)  # from dead behind, in [0, 2 pi)
            q = int(bearing / (2 * math.pi / n_sectors)) % n_sectors
            channels[base + q].append(num / max(d, d_min) ** 2)
        reading = {"density": sum, "average": lambda t: sum(t) / len(t), "closest": max}
        out.append([reading[compose](t) if t else empty for t in channels])
    return np.array(out)


@pytest.mark.parametrize("compose", ["density", "average", "closest"])
@pytest.mark.parametrize("seed", range(4))
def test_random_scans_match_plain_loops(compose, seed):
    rng = np.random.default_rng(seed)
    n_sectors = [4, 6, 8, 3][seed]
    sensor = Lidar(sectors=n_sectors, radius=7.0, compose=compose, empty=-1.0)
    config = DomainConfig(n_rovers=9, n_req=1, sensor=sensor)
    world = RoverWorld(config, 3)
    world.reset([np.random.default_rng([seed, e]) for e in range(3)])
    for _ in range(10):
        obs = world.step(rng.uniform(-1, 1, (3, 9, 2)))
    for e in range(3):
        expected = _oracle(world.rover_positions[e], world.rover_headings[e],
                           world.poi_positions[e], world.poi_values[e], n_sectors, 7.0,
                           compose, -1.0, config.d_min)  # fmt: skip
        # float32 readings; a bearing on a sector boundary could differ by rounding: none
        # of these random layouts has one
        np.testing.assert_allclose(obs[e], expected, rtol=2e-6)
    assert (obs == -1.0).any() and (obs > 0).any()


def test_the_gymnasium_env_declares_the_empty_value():
    env = RoverEnv(n_rovers=4, n_req=1, sensor={"kind": "lidar", "empty": -1.0,
                                                 "radius": 3.0})  # fmt: skip
    assert env.observation_space.low.min() == -1.0
    check_env(env, skip_render_check=True)
    obs, _ = env.reset(seed=0)
    assert (obs == -1.0).any()


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [("compose", "sum", "compose: must be one of density, average, closest"),
     ("bearing", "north", "bearing: must be one of heading, world"),
     ("empty", math.nan, "empty: must not be NaN"),
     ("sectors", 0, "sectors: must be >= 1")],
)  # fmt: skip
def test_bad_lidar_fields(field, value, message):
    with pytest.raises(ConfigError, match=message):
        Lidar(**{field: value})
