"""The lidar sensor (issue 33): hand-worked scans, the density sensor as one of its settings,
a plain-loop oracle, and the envs' spaces with a negative empty value."""

import math

import numpy as np
import pytest
from conftest import play_alike
from gymnasium.utils.env_checker import check_env

from physrover.config import ConfigError, DomainConfig
from physrover.domain.sensing.lidar import Lidar
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
    with pytest.raises(ConfigError, match='measure: "linear" divides by the radius'):
        Lidar(measure="linear")
    with pytest.raises(ConfigError, match='measure: "ratio" divides by the radius'):
        Lidar(measure="ratio")


def _lab_measure(mtype, distance, observation_radius):
    """``SmartLidar::measure`` as the lab writes it (``lidar.hpp``)."""
    if mtype == "inverse_distance_squared":
        return 1.0 / max(0.001, distance * distance)
    elif mtype == "exponential_negative_distance":
        return math.exp(-distance)
    elif mtype == "inverse_distance":
        return 1.0 / max(0.001, distance)
    elif mtype == "distance_over_observation_radius":
        return distance / observation_radius
    elif mtype == "one_minus_inverse_distance_over_observation_radius":
        return 1.0 - distance / observation_radius
    raise ValueError(mtype)


@pytest.mark.parametrize(("ours", "lab"), [
    ("inverse-square", "inverse_distance_squared"), ("linear",
     "one_minus_inverse_distance_over_observation_radius"), ("inverse", "inverse_distance"),
    ("exponential", "exponential_negative_distance"), ("ratio",
     "distance_over_observation_radius")])  # fmt: skip
def test_every_measure_is_the_labs(ours, lab):
    """One rover and one POI of value 2 at random distances (beyond the floors, ours d_min
    = 1 here and the lab's 0.001), each alone in its sector: its term is the lab's measure
    (times the POI's value), world bearings."""
    rng = np.random.default_rng(0)
    for _ in range(20):
        d_rover, d_poi = rng.uniform(1.0, 6.0, 2)
        obs = _scan([(0, 0), (d_rover, 0.0)], pois=[(-d_poi, -0.001)], values=(2.0,),
                    measure=ours, radius=6.0, bearing="world")  # fmt: skip
        assert obs[0] == pytest.approx(_lab_measure(lab, d_rover, 6.0), rel=1e-6)  # float32
        assert obs[4 + 2] == pytest.approx(2.0 * _lab_measure(lab, np.hypot(d_poi, 0.001),
                                                              6.0), rel=1e-6)  # fmt: skip


@pytest.mark.parametrize("sectors", [4, 6])
@pytest.mark.parametrize("radius", [math.inf, 6.0])
def test_density_composition_is_the_density_sensor_bit_for_bit(sectors, radius):
    base = DomainConfig(n_rovers=12, n_req=2)
    worlds = [RoverWorld(base.replace(sensor={"kind": kind, "sectors": sectors,
                                              "radius": radius}), 5)
              for kind in ("density", "lidar")]  # fmt: skip
    rng = np.random.default_rng(sectors)
    actions = rng.uniform(-1, 1, (30, 5, 12, 2))
    play_alike(worlds, actions)
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


# -- agent classes and POIs some agents do not sense (issue 33) ---------------------------------

CLASSES = """
[domain]
n_req = 1
[[agents]]
name = "rover"
count = 2
sensor = {{ kind = "lidar", radius = 10.0, empty = -1.0, channels = "by-class" }}
[[agents]]
name = "uav"
captures = false
sensor = {{ kind = "lidar", radius = 10.0, empty = -1.0, channels = "by-class" }}
[[pois]]
value = 2.0
{poi}
"""


def _class_scan(positions, poi, poi_rule=""):
    domain = DomainConfig.from_toml(CLASSES.format(poi=poi_rule))
    world = RoverWorld(domain, 1)
    obs = world.reset([np.random.default_rng(0)], StartOverrides(
        rover_positions=np.asarray(positions, dtype=float), rover_headings=np.zeros(3),
        poi_positions=np.asarray([poi], dtype=float)))  # fmt: skip
    return world, obs[0]


def test_channels_by_class_hand_worked():
    # rover 0 at the origin facing +x: rover 1 dead ahead at 2 (rover block, sector 2),
    # the UAV dead left at 3 (UAV block, sector 3), the POI of value 2 dead right at 1
    _, obs = _class_scan([(0, 0), (2, 0), (0, 3)], (0, -1))
    expected = [-1, -1, 0.25, -1, -1, -1, -1, 1 / 9, -1, 2.0, -1, -1]
    np.testing.assert_allclose(obs[0], expected, rtol=1e-7)


def test_hidden_pois_and_their_sense_radius():
    rule = 'visible_to = ["uav"]\nsense_radius = 4.0'
    _, obs = _class_scan([(0, 0), (20, 0), (0, 1)], (0, -1), rule)
    assert (obs[0, 8:] == -1).all()  # the rover does not sense the hidden POI
    assert obs[2, 8:].max() == pytest.approx(2.0 / 4.0)  # the UAV at distance 2 does
    _, obs = _class_scan([(0, 0), (20, 0), (0, 4)], (0, -1), rule)
    assert (obs[2, 8:] == -1).all()  # 5 from the UAV: beyond the POI's sense radius


def test_a_captured_poi_disappears_from_the_next_step():
    world, obs = _class_scan([(0, 0), (20, 0), (0, 5)], (0, -1), 'disappear = "captured"')
    assert world.G[0] == 2.0 and obs[0, 8:].max() > 0  # captured at reset, still sensed
    obs = world.step(np.zeros((1, 3, 2)))[0]
    assert (obs[:, 8:] == -1).all() and obs[0, 7] > 0  # nobody senses it; the UAV is seen


def test_only_a_class_aware_sensor_hides_pois():
    text = CLASSES.format(poi='visible_to = ["uav"]').replace(
        'sensor = { kind = "lidar", radius = 10.0, empty = -1.0, channels = "by-class" }',
        'sensor = { kind = "density" }', 1)  # fmt: skip
    with pytest.raises(ConfigError, match="agents.0..sensor: .density. cannot hide POIs"):
        DomainConfig.from_toml(text)
    with pytest.raises(ConfigError, match="pois.0..visible_to: unknown class 'uvs'"):
        DomainConfig.from_toml(CLASSES.format(poi='visible_to = ["uvs"]'))


def _class_oracle(positions, headings, classes, pois, values, rules, me, radius, d_min):
    """Plain loops: agent ``me``'s by-class lidar readings (density composition, empty -1),
    each POI sensed iff visible to its class and within its sense radius."""
    n_classes = max(classes) + 1
    channels = [[] for _ in range(4 * (n_classes + 1))]
    x, y = positions[me]
    objects = [(p, 1.0, 4 * classes[j]) for j, p in enumerate(positions) if j != me]
    for p, v, (visible, sense) in zip(pois, values, rules, strict=True):
        if classes[me] in visible:
            objects.append((p, v, 4 * n_classes, sense))
    for entry in objects:
        (ox, oy), num, base = entry[:3]
        d = math.hypot(ox - x, oy - y)
        if d > radius or (len(entry) == 4 and d > entry[3]):
            continue
        bearing = (math.atan2(oy - y, ox - x) - headings[me] + math.pi) % (2 * math.pi)
        channels[base + int(bearing / (math.pi / 2)) % 4].append(num / max(d, d_min) ** 2)
    return [sum(t) if t else -1.0 for t in channels]


@pytest.mark.parametrize("seed", range(3))
def test_random_class_scans_match_plain_loops(seed):
    text = CLASSES.format(poi='visible_to = ["uav"]\n[[pois]]\nvalue = 1.0\nsense_radius = 3.0')
    text = text.replace("count = 2", "count = 3").replace("n_req = 1", 'n_req = 1\nscenario = '
                        '{ kind = "uniform", half_size = 4.0, min_separation = 1.0 }')  # fmt: skip
    domain = DomainConfig.from_toml(text)
    world = RoverWorld(domain, 2)
    world.reset([np.random.default_rng([seed, e]) for e in range(2)])
    rng = np.random.default_rng(seed)
    for _ in range(8):
        obs = world.step(rng.uniform(-1, 1, (2, 4, 2)))
    classes, rules = [0, 0, 0, 1], [({1}, math.inf), ({0, 1}, 3.0)]
    for e in range(2):
        for me in range(4):
            expected = _class_oracle(world.rover_positions[e], world.rover_headings[e],
                                     classes, world.poi_positions[e], world.poi_values[e],
                                     rules, me, 10.0, domain.d_min)  # fmt: skip
            np.testing.assert_allclose(obs[e, me], expected, rtol=2e-6)
    assert (obs > 0).any() and (obs == -1).any()
    to_hidden = np.linalg.norm(
        world.rover_positions[:, :3] - world.poi_positions[:, None, 0], axis=-1
    )
    assert (to_hidden <= 10.0).any()  # a rover would have sensed the hidden POI


BIG_TEAM = """
[domain]
n_req = 1
scenario = {{ kind = "uniform", half_size = {half}, min_separation = 4.0 }}
[[pois]]
value = 1.0
visible_to = ["uav"]
[[pois]]
value = 2.0
[[agents]]
name = "rover"
count = {rovers}
[agents.sensor]
kind = "lidar"
radius = 3.0
empty = -1.0
channels = "by-class"
compose = "{compose}"
[[agents]]
name = "uav"
count = {uavs}
captures = false
sensor = {{ kind = "lidar", radius = 10.0, channels = "by-class", measure = "linear" }}
"""


@pytest.mark.parametrize("compose", ["density", "average", "closest"])
def test_the_grid_reads_what_every_pair_reads_bit_for_bit(compose):
    """A team above LIDAR_GRID_MIN_POINTS with finite radii finds each class's neighbours
    from the grid (physrover.domain.sensing.classes), in index order: its readings are the
    all-pairs readings bit for bit, in a dense spread and a sparse one."""
    import dataclasses

    from physrover.domain.sensing.classes import LIDAR_GRID_MIN_POINTS

    for half, rovers, uavs in [(8.0, 80, 20), (40.0, 120, 30)]:
        domain = DomainConfig.from_toml(BIG_TEAM.format(half=half, rovers=rovers, uavs=uavs,
                                                        compose=compose))  # fmt: skip
        assert domain.n_rovers >= LIDAR_GRID_MIN_POINTS
        worlds = [RoverWorld(domain, 2) for _ in range(2)]
        classes = worlds[0].plan.step.classes
        assert classes.local.all() and classes.cell == 3.0
        every_pair = classes._replace(local=classes.local & False, cell=0.0)
        step = worlds[1].plan.step._replace(classes=every_pair)
        worlds[1].plan = dataclasses.replace(worlds[1].plan, step=step)
        for seed in range(3):
            shape = (domain.steps, 2, domain.n_rovers, 2)
            play_alike(worlds, np.random.default_rng(seed).uniform(-1, 1, shape))
            a, b = worlds
            np.testing.assert_array_equal(a.observations, b.observations)
            assert (a.observations[..., :12] > 0).any() and (a.observations == -1).any()


MIXED_SENSORS = """
[domain]
n_req = 1
scenario = { kind = "uniform", half_size = 5.0, min_separation = 1.0 }
[[agents]]
name = "rover"
count = 3
sensor = { kind = "lidar", radius = 6.0, empty = -1.0, channels = "by-class" }
[[agents]]
name = "scout"
count = 2
sensor = { kind = "lidar", sectors = 5, bearing = "world", compose = "average", radius = 8.0 }
[[agents]]
name = "uav"
count = 2
captures = false
sensor = { kind = "density", sectors = 6, radius = 7.0 }
"""


def test_the_classes_table_is_each_sensor_s_own_kernel():
    """The compiled step's table of the classes (a lidar by class, a world-bearing lidar of
    five sectors, a density sensor of six) reads, class by class, what each class's sensor
    reads through its own observe, and 0 past the class's size."""
    domain = DomainConfig.from_toml(MIXED_SENSORS)
    world = RoverWorld(domain, 3)
    world.reset([np.random.default_rng(e) for e in range(3)])
    rng = np.random.default_rng(1)
    for _ in range(6):
        obs = world.step(rng.uniform(-1, 1, (3, domain.n_rovers, 2)))
    for c, (agent, rows) in enumerate(zip(domain.agents, [slice(0, 3), slice(3, 5),
                                                          slice(5, 7)], strict=True)):  # fmt: skip
        sensor = agent.sensor
        alone = np.zeros((3, domain.n_rovers, world.obs_dim), dtype=np.float32)
        if hasattr(sensor, "view"):
            sensor.observe_class(world.state, domain.d_min, alone, sensor.view(domain, c), rows)
        else:
            sensor.observe(world.state, domain.d_min, alone[..., : sensor.dim])
        np.testing.assert_array_equal(obs[:, rows], alone[:, rows], err_msg=agent.name)
        assert (obs[:, rows] != 0).any(), agent.name
