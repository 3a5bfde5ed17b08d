"""POIs that leave sight (``[[pois]] disappear``, issue 43): "visited", the lab's
``disappear_bool``, by hand and against a plain-loop oracle over random episodes; the
config's checks; what import-lab makes of the lab's flag."""

import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from physrover.config import ConfigError, DomainConfig
from physrover.config.lab_run import lab_run
from physrover.domain.world import RoverWorld, StartOverrides

EXAMPLE = Path(__file__).parent / "data" / "lab-example" / "config.yaml"

DOMAIN = """
[domain]
n_req = 1
steps = {steps}
[[agents]]
name = "rover"
count = 2
sensor = {{ kind = "lidar", radius = {rover_radius}, empty = -1.0, channels = "by-class" }}
[[agents]]
name = "uav"
captures = false
sensor = {{ kind = "lidar", radius = 10.0, empty = -1.0, channels = "by-class" }}
[[pois]]
value = 2.0
visible_to = ["uav"]
disappear = "visited"
{poi}
"""


def _domain(poi="", rover_radius=10.0, steps=10, extra=""):
    return DomainConfig.from_toml(DOMAIN.format(poi=poi, rover_radius=rover_radius,
                                                steps=steps) + extra)  # fmt: skip


def _uav_sees_poi(rover, poi="", rover_radius=10.0) -> bool:
    """Whether the UAV at (0, 5) senses the POI at (0, -3) at reset, rover 0 at ``rover``."""
    world = RoverWorld(_domain(poi, rover_radius), 1)
    obs = world.reset([np.random.default_rng(0)], StartOverrides(
        rover_positions=np.array([rover, (20.0, 0.0), (0.0, 5.0)]), rover_headings=np.zeros(3),
        poi_positions=np.array([(0.0, -3.0)])))  # fmt: skip
    poi_block = obs[0, 2, 8:12]  # the UAV's POI channels: [rovers | UAVs | POIs], 4 each
    assert world.state.gone[0, 0] == (poi_block == -1).all()
    return bool((poi_block > 0).any())


def test_a_rover_within_the_visit_radius_hides_the_poi_from_the_uavs_at_once():
    assert _uav_sees_poi((0.0, 0.0))  # 3 from the POI
    assert _uav_sees_poi((0.0, -1.9))  # 1.1
    assert not _uav_sees_poi((0.0, -2.0))  # 1.0: within (<=), at the same state
    assert not _uav_sees_poi((0.5, -3.5))
    assert not _uav_sees_poi((0.0, 0.0), "visit_radius = 3.0")


def test_the_rover_marks_only_within_its_own_sensor_radius():
    # 0.5 from the POI: within visit_radius 1.0, beyond its own sensor's 0.4 (the lab's
    # SmartLidar skips a POI beyond the agent's observation radius before marking it)
    assert _uav_sees_poi((0.0, -2.5), rover_radius=0.4)
    assert not _uav_sees_poi((0.0, -2.7), rover_radius=0.4)


def test_visited_by_names_the_classes_that_mark():
    assert _uav_sees_poi((0.0, -2.5), 'visited_by = ["uav"]')  # a rover near: not a marker
    world = RoverWorld(_domain('visited_by = ["uav"]'), 1)
    world.reset([np.random.default_rng(0)], StartOverrides(
        rover_positions=np.array([(0.0, 0.0), (20.0, 0.0), (0.0, -2.5)]),
        rover_headings=np.zeros(3), poi_positions=np.array([(0.0, -3.0)])))  # fmt: skip
    assert world.state.gone[0, 0]  # the UAV itself within 0.5


def test_gone_stays_until_reset_and_scoring_is_unchanged():
    world = RoverWorld(_domain(steps=3), 1)
    start = StartOverrides(
        rover_positions=np.array([(0.0, -2.5), (20.0, 0.0), (0.0, 5.0)]),
        rover_headings=np.zeros(3),
        poi_positions=np.array([(0.0, -3.0)]),
    )
    world.reset([np.random.default_rng(0)], start)
    assert world.state.gone[0, 0] and world.G[0] > 0  # captured and gone: scoring unchanged
    world.step(np.ones((1, 3, 2)))  # everyone drives away: it stays gone
    assert world.state.gone[0, 0]
    world.reset([np.random.default_rng(0)], StartOverrides(
        rover_positions=np.array([(0.0, 0.0), (20.0, 0.0), (0.0, 5.0)]),
        rover_headings=np.zeros(3), poi_positions=np.array([(0.0, -3.0)])))  # fmt: skip
    assert not world.state.gone[0, 0]


def _oracle_gone(positions, pois, alive, reach, gone):
    """Plain loops: ``gone`` (K,) after a state: a POI is gone once an alive agent is within
    its reach (``reach[i][k]``, None where agent i never marks POI k)."""
    out = list(gone)
    for k, (px, py) in enumerate(pois):
        for i, (x, y) in enumerate(positions):
            if reach[i][k] is not None and alive[i] and math.dist((x, y), (px, py)) <= reach[i][k]:
                out[k] = True
    return out


@pytest.mark.parametrize("seed", range(6))
def test_random_episodes_match_a_plain_loop_oracle(seed):
    """Random layouts and commands, three POIs (visited with radii 1 and 2.5, and one
    that never goes), rovers of sensor radius 2 or 10, one agent failing mid-episode: the
    world's gone marks equal the oracle's at every state, and every agent's POI channels
    equal its lidar over the POIs not gone."""
    rng = np.random.default_rng(seed)
    rover_radius = (2.0, 10.0)[seed % 2]
    text = DOMAIN.format(poi="visit_radius = 2.5", rover_radius=rover_radius, steps=30)
    text += ('[[pois]]\nvalue = 1.0\nvisible_to = ["uav"]\ndisappear = "visited"\n'
             '[[pois]]\nvalue = 3.0\n[failures]\nn_failing = 1\n')  # fmt: skip
    domain = DomainConfig.from_toml(text)
    world = RoverWorld(domain, 1)
    obs = world.reset([rng], StartOverrides(
        rover_positions=rng.uniform(-4, 4, (3, 2)), rover_headings=rng.uniform(-3, 3, 3),
        poi_positions=rng.uniform(-4, 4, (3, 2))))  # fmt: skip
    # the rovers (agents 0, 1) mark the first two POIs within min(visit radius, their
    # sensor's radius); the UAV (agent 2) marks nothing; the third POI never goes
    reach = [[min(r, rover_radius) if i < 2 and r else None for r in (2.5, 1.0, None)]
             for i in range(3)]  # fmt: skip
    failing_at = world.plan.step.failures.at[0]
    gone = [False] * 3
    lidar = domain.agents[1].sensor
    for t in range(31):
        alive = [t < failing_at[i] for i in range(3)]
        positions = world.state.rover_positions[0]
        gone = _oracle_gone(positions, world.state.poi_positions[0], alive, reach, gone)
        assert world.state.gone[0].tolist() == gone, t
        # the UAV's readings: its lidar over the POIs in sight (a view without the gone)
        view = lidar.view(domain, 1)
        view = view._replace(visible=view.visible & ~np.array(gone))
        expected = np.zeros_like(obs)
        clear = world.state._replace(gone=np.zeros_like(world.state.gone))
        lidar.observe_class(clear, domain.d_min, expected, view, slice(2, 3))
        if alive[2]:
            np.testing.assert_array_equal(obs[0, 2], expected[0, 2], err_msg=str(t))
        if t < 30:
            obs = world.step(rng.uniform(-1, 1, (1, 3, 2)))
    assert not gone[2]


def test_some_random_episode_hides_a_poi():
    """The oracle test is not vacuous: its layouts do hide POIs mid-episode."""
    hidden = 0
    for seed in range(6):
        rng = np.random.default_rng(seed)
        world = RoverWorld(_domain("visit_radius = 2.5", steps=30), 1)
        world.reset([rng], StartOverrides(
            rover_positions=rng.uniform(-4, 4, (3, 2)), rover_headings=rng.uniform(-3, 3, 3),
            poi_positions=rng.uniform(-4, 4, (1, 2))))  # fmt: skip
        start = world.state.gone[0, 0]
        for _ in range(30):
            world.step(rng.uniform(-1, 1, (1, 3, 2)))
        hidden += int(world.state.gone[0, 0] and not start)
    assert hidden >= 1


@pytest.mark.parametrize(
    ("poi", "message"),
    [("visit_radius = 0.0", "visit_radius: must be > 0 and finite"),
     ('visited_by = ["uvs"]', "pois.0..visited_by: unknown class 'uvs'")],
)  # fmt: skip
def test_bad_visit_fields(poi, message):
    with pytest.raises(ConfigError, match=message):
        _domain(poi)


def test_visit_fields_need_disappear_visited():
    text = DOMAIN.format(poi="visit_radius = 2.0", rover_radius=10.0, steps=10)
    with pytest.raises(ConfigError, match='visit_radius: is read only under disappear = "vis'):
        DomainConfig.from_toml(text.replace('disappear = "visited"', 'disappear = "captured"'))


def test_the_toml_round_trip_writes_the_visit_fields_only_where_read():
    domain = _domain('visit_radius = 2.0\nvisited_by = ["rover"]')
    again = DomainConfig.from_toml(domain.to_toml())
    assert again == domain and again.pois[0].visit_radius == 2.0
    assert "visit_radius" not in DomainConfig.from_toml(
        DOMAIN.format(poi="", rover_radius=10.0, steps=10).replace(
            'disappear = "visited"', 'disappear = "captured"')).to_toml()  # fmt: skip


def test_import_lab_maps_disappear_bool_on_a_smart_lidar_rover():
    lab = yaml.safe_load(EXAMPLE.read_text())  # its rovers on RoverLidar: the flag is a no-op
    assert lab_run(lab)[0].domain.pois[0].disappear == "never"
    lab["env"]["agents"]["rovers"][0]["sensor"]["type"] = "SmartLidar"
    lab["env"]["pois"]["hidden_pois"][0]["disappear_bool"] = True
    run, notes = lab_run(lab)
    (poi,) = run.domain.pois
    assert (poi.disappear, poi.visit_radius, poi.visited_by) == ("visited", 1.0, ("rover",))
    assert not any("disappear_bool" in note for note in notes)
