"""Agent classes ([[agents]], issue 33): config, hand-worked moves, a plain-loop oracle,
who counts toward captures, per-class sensors, and the paper's team as one class."""

import math

import numpy as np
import pytest
from conftest import play_alike
from oracles import classes_step

from physrover.config import ConfigError, DomainConfig, RunConfig
from physrover.domain.world import RoverWorld, StartOverrides

ROVERS_AND_UAVS = """
[domain]
n_req = 1

[[agents]]
name = "rover"
count = 4
moves_with = ["uav"]      # moves only while a UAV is within its sensor's radius (3)
sensor = { kind = "lidar", radius = 3.0, empty = -1.0 }

[[agents]]
name = "uav"
count = 2
captures = false          # never counts toward a POI: its D is 0
action = "world"          # (x, y) commands, the lab's dxdy
max_speed = 2.0
bounds = [-10.0, 10.0, -10.0, 10.0]
sensor = { kind = "lidar", sectors = 3, radius = 100.0, empty = -1.0 }
"""


def _domain(text=ROVERS_AND_UAVS, **changes):
    return DomainConfig.from_toml(text).replace(**changes) if changes else (
        DomainConfig.from_toml(text))  # fmt: skip


def test_classes_round_trip_and_derive_the_team_size():
    d = _domain()
    assert d.n_rovers == 6 and [c.name for c in d.agents] == ["rover", "uav"]
    assert d.agents[1].sensor.sectors == 3 and d.agents[0].sensor.radius == 3.0
    assert DomainConfig.from_toml(d.to_toml()) == d
    assert "[[agents]]" in d.to_toml() and "[agents.sensor]" in d.to_toml()
    assert "n_rovers" not in d.to_toml()
    assert "agents" not in DomainConfig().to_toml()  # the paper's TOML is what it was


@pytest.mark.parametrize(
    ("toml", "message"),
    [
        (
            "[domain]\nn_rovers = 4\nn_req = 1\n[[agents]]\ncount = 2\n[[agents]]\nname = 'u'",
            "n_rovers: is the sum of the [[agents]] counts (3); remove it or set it to 3",
        ),
        (
            "[domain]\nn_req = 1\n[[agents]]\nname = 'a'\n[[agents]]\nname = 'a'",
            "agents[1].name: 'a' is used twice",
        ),  # fmt: skip
        (
            "[domain]\nn_req = 1\n[[agents]]\nmoves_with = ['uvs']\n[[agents]]\nname = 'uav'",
            "agents[0].moves_with: unknown class 'uvs' (did you mean 'uav'?); classes: rover, uav",
        ),
        (
            "[domain]\nn_req = 1\n[[agents]]\nmoves_with = ['uav']\n[[agents]]\nname = 'uav'",
            "agents[0].moves_with_radius: the sensor's radius is inf; give a finite radius",
        ),
        ("[[agents]]\nname = 'Rover'", "agents[0].name: must match [a-z][a-z0-9_]*"),
        (
            "[domain]\nn_req = 1\n[[agents]]\ncaptures = false",
            "agents: no class counts toward captures",
        ),  # fmt: skip
        (
            "[domain]\nn_req = 3\n[[agents]]\ncount = 2\n[[agents]]\nname = 'u'\ncount = 5\n"
            "captures = false",
            "n_req: must be in [1, 2] (agents of capturing classes), got 3",
        ),
        ("[domain]\nn_req = 1\n[[agents]]\nbounds = [1, 0, 0, 1]", "agents[0].bounds: need"),
        (
            "[domain]\nn_req = 1\n[[agents]]\nsensor = { kind = 'lidr' }",
            "agents[0].sensor.kind: unknown sensor 'lidr' (did you mean 'lidar'?)",
        ),  # fmt: skip
        (
            "[domain]\nn_req = 1\nmotion = 'physics'\n[[agents]]\nbounds = [0, 1, 0, 1]",
            'agents[0].bounds: bounds need motion = "ideal"',
        ),  # fmt: skip
    ],
)
def test_bad_agents_tables_name_the_field(toml, message):
    with pytest.raises(ConfigError) as info:
        DomainConfig.from_toml(toml)
    assert message in str(info.value)


def test_classes_are_set_in_toml_not_on_the_command_line():
    with pytest.raises(ConfigError, match=r"set \[\[pois\]\] and \[\[agents\]\] tables"):
        RunConfig().with_overrides({"agents": []})
    with pytest.raises(ConfigError, match="n_rovers: set"):
        RunConfig.from_toml(ROVERS_AND_UAVS).with_overrides({"n_rovers": 3})


# -- moves, worked by hand ------------------------------------------------------------------


def _world(domain, positions, headings=None, pois=((50.0, 50.0),)):
    world = RoverWorld(domain.replace(poi_values=(1.0,) * len(pois)), 1)
    n = domain.n_rovers
    heads = np.zeros(n) if headings is None else np.asarray(headings, dtype=float)
    obs = world.reset([np.random.default_rng(0)], StartOverrides(
        rover_positions=np.asarray(positions, dtype=float), rover_headings=heads,
        poi_positions=np.asarray(pois, dtype=float)))  # fmt: skip
    return world, obs


TWO = """
[domain]
n_req = 1
[[agents]]
name = "rover"
moves_with = ["uav"]
moves_with_radius = 3.0
[[agents]]
name = "uav"
captures = false
action = "world"
max_speed = 2.0
bounds = [-10.0, 4.0, -10.0, 10.0]
"""


def test_the_gate_is_judged_before_the_step():
    d = _domain(TWO)
    # the UAV at 2.9 moves away this step: the rover, judged before the step, still moves
    world, _ = _world(d, [(0, 0), (2.9, 0)])
    world.step(np.array([[[1.0, 0.0], [1.0, 0.0]]]))
    assert world.rover_positions[0, 0].tolist() == [1.0, 0.0]
    assert world.rover_positions[0, 1].tolist() == [4.0, 0.0]  # 2.9 + 2, clamped at 4
    # the UAV at 3.5 comes within 3 this step: the rover waits a step
    world, _ = _world(d, [(0, 0), (3.5, 0)])
    world.step(np.array([[[1.0, 0.0], [-1.0, 0.0]]]))
    assert world.rover_positions[0, 0].tolist() == [0.0, 0.0]
    assert world.actions[0, 0, 0].tolist() == [1.0, 0.0]  # the command is still recorded
    world.step(np.array([[[1.0, 0.0], [0.0, 0.0]]]))
    assert world.rover_positions[0, 0].tolist() == [1.0, 0.0]


def test_speed_world_frame_and_bounds():
    d = _domain(TWO)
    # the UAV faces +y (heading pi/2) but (x, y) commands ignore it; speed 2, clipped first
    world, _ = _world(d, [(0, 0), (0, 1)], headings=[0.0, math.pi / 2])
    world.step(np.array([[[0.0, 0.0], [5.0, -0.5]]]))
    np.testing.assert_array_equal(world.rover_positions[0, 1], [2.0, 0.0])
    assert world.rover_headings[0, 1] == pytest.approx(math.atan2(-1.0, 2.0))
    world.step(np.array([[[0.0, 0.0], [1.0, 0.0]]]))
    np.testing.assert_array_equal(world.rover_positions[0, 1], [4.0, 0.0])  # 2 + 2 = 4 = x_max
    world.step(np.array([[[0.0, 0.0], [1.0, 0.0]]]))
    np.testing.assert_array_equal(world.rover_positions[0, 1], [4.0, 0.0])  # held at the bound


def test_only_capturing_classes_count():
    d = _domain(TWO)
    world, _ = _world(d, [(30, 30), (0, 0)], pois=[(1.0, 0.0)])  # only the UAV at the POI
    assert world.G[0] == 0.0 and not world.state.in_range[0, 0, 1, 0]
    world, _ = _world(d, [(1, 0), (0, 0)], pois=[(1.0, 0.0)])  # the rover there too
    assert world.G[0] == 1.0 and world.D[0].tolist() == [1.0, 0.0]


def _steps_as_the_oracle(d, n_teams, steps, seed, rng):
    """``steps`` random commands (from ``rng``) to ``n_teams`` teams of domain ``d``, each
    step checked against the plain-loop oracle (:func:`oracles.classes_step`); returns the
    world."""
    world = RoverWorld(d, n_teams)
    world.reset([np.random.default_rng([seed, e]) for e in range(n_teams)])
    classes = [c for c in d.agents for _ in range(c.count)]
    names = [c.name for c in d.agents]
    for _ in range(steps):
        before = world.rover_positions.copy(), world.rover_headings.copy()
        actions = rng.uniform(-1.5, 1.5, (n_teams, len(classes), 2))
        world.step(actions)
        for e in range(n_teams):
            positions, headings = classes_step(before[0][e].tolist(), before[1][e].tolist(),
                                               actions[e], classes, names)  # fmt: skip
            np.testing.assert_allclose(world.rover_positions[e], positions, rtol=0, atol=1e-9)
            np.testing.assert_allclose(world.rover_headings[e], headings, rtol=0, atol=1e-9)
    return world


@pytest.mark.parametrize("seed", range(5))
def test_random_episodes_move_as_the_oracle(seed):
    rng = np.random.default_rng(seed)
    text = TWO.replace("moves_with_radius = 3.0", f"moves_with_radius = {rng.uniform(1, 4)}")
    d = _domain(text).replace(n_req=1)
    d = DomainConfig.from_toml(d.to_toml().replace('name = "uav"\ncount = 1',
                                                   'name = "uav"\ncount = 3'))  # fmt: skip
    world = _steps_as_the_oracle(d, 3, 25, seed, rng)
    uav_x = world.position_history[:, :, 1:, 0]
    assert ((uav_x == 4.0) | (uav_x == -10.0)).any()  # a bound was met
    moved = np.abs(world.position_history[1:, :, 0] - world.position_history[:-1, :, 0])
    assert (moved.sum(-1) == 0).any() and (moved.sum(-1) > 0).any()  # the gate shut and opened


THREE = """
[domain]
n_req = 1
[[agents]]
name = "rover"
count = 3
moves_with = ["uav", "scout"]
moves_with_radius = 2.5
[[agents]]
name = "uav"
count = 2
action = "world"
captures = false
[[agents]]
name = "scout"
count = 2
moves_with = ["rover"]
moves_with_radius = 1.5
"""


@pytest.mark.parametrize("seed", range(3))
def test_gates_over_several_classes_move_as_the_oracle(seed):
    """Each gated agent's partners are the agents of every class it moves with (the
    compiled gate's partner lists): random episodes of three classes, two of them gated,
    one by two classes, step for step as the plain-loop oracle."""
    world = _steps_as_the_oracle(_domain(THREE), 2, 30, seed, np.random.default_rng(seed))
    gated = world.position_history[:, :, [0, 1, 2, 5, 6]]
    still = np.all(gated[1:] == gated[:-1], axis=-1)
    assert still.any() and (~still).any()  # the gates shut and opened


def test_each_class_observes_with_its_own_sensor_zero_padded():
    d = _domain()
    world = RoverWorld(d, 2)
    obs = world.reset([np.random.default_rng(e) for e in range(2)])
    assert obs.shape == (2, 6, 8)  # the rovers' 8, the UAVs' 6 padded to 8
    for rows, sensor in [(slice(0, 4), d.agents[0].sensor), (slice(4, 6), d.agents[1].sensor)]:
        alone = np.empty((2, 6, sensor.dim), dtype=np.float32)
        sensor.observe(world.state, d.d_min, alone)
        np.testing.assert_array_equal(obs[:, rows, : sensor.dim], alone[:, rows])
    assert (obs[:, 4:, 6:] == 0).all() and (obs[:, :4] == -1).any()


def test_one_class_of_the_paper_rovers_is_the_paper_team():
    """[[agents]] with one class of 15 default rovers: the classes' path (roles; the
    paper's sensor, which a team whose classes all sense with it takes for the whole team:
    the class table's equality with it is the test below) equals the paper's step bit for
    bit."""
    paper = DomainConfig(n_req=2)
    mirror = DomainConfig.from_toml('[domain]\nn_req = 2\n[[agents]]\nname = "rover"\n'
                                    "count = 15\n")  # fmt: skip
    worlds = [RoverWorld(c, 3) for c in (paper, mirror)]
    assert worlds[0].plan.step.classes is None and worlds[0].plan.step.motion.roles is None
    assert worlds[1].plan.step.density is not None and worlds[1].plan.step.motion.roles
    assert worlds[0].compiled and worlds[1].compiled
    actions = np.random.default_rng(3).uniform(-1.2, 1.2, (paper.steps, 3, 15, 2))
    play_alike(worlds, actions)
    a, b = worlds
    for name in ("observations", "position_history", "heading_history"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    np.testing.assert_array_equal(a.state.in_range, b.state.in_range)
    np.testing.assert_array_equal(a.G, b.G)
    np.testing.assert_array_equal(a.D, b.D)


SPAWNS = """
[domain]
n_req = 1
[[agents]]
name = "rover"
count = 3
[[agents]]
name = "base"
count = 2
spawn = "fixed"
spawn_positions = [[5.0, 5.0], [-5.0, 5.0]]
[[agents]]
name = "box"
count = 4
spawn = "box"
spawn_box = [10.0, 12.0, -3.0, -1.0]
[[agents]]
name = "ring"
count = 4
spawn = "circle"
spawn_circle = [1.0, 2.0, 7.0]
"""


def test_spawn_rules_place_each_class_after_the_scenario():
    domain = DomainConfig.from_toml(SPAWNS)
    world = RoverWorld(domain, 6)
    world.reset([np.random.default_rng(e) for e in range(6)])
    p = world.rover_positions
    np.testing.assert_array_equal(p[:, 3:5], np.broadcast_to([[5, 5], [-5, 5]], (6, 2, 2)))
    box = p[:, 5:9]
    assert ((box[..., 0] >= 10) & (box[..., 0] <= 12) & (box[..., 1] >= -3)
            & (box[..., 1] <= -1)).all() and len(np.unique(box[..., 0])) == 24  # fmt: skip
    np.testing.assert_allclose(np.linalg.norm(p[:, 9:] - [1.0, 2.0], axis=-1), 7.0, rtol=1e-12)
    # the "disc" class starts where the scenario puts it: as a team of 13 paper rovers would
    paper = RoverWorld(DomainConfig(n_rovers=13, n_req=1), 6)
    paper.reset([np.random.default_rng(e) for e in range(6)])
    np.testing.assert_array_equal(p[:, :3], paper.rover_positions[:, :3])


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [("spawn_positions = [[5.0, 5.0], [-5.0, 5.0]]", "spawn_positions = [[5.0, 5.0]]",
      "agents[1].spawn_positions: need one [x, y] per agent (2)"),
     ("spawn_box = [10.0, 12.0, -3.0, -1.0]", "spawn_box = [10.0, 9.0, -3.0, -1.0]",
      "agents[2].spawn_box: need [x_min, x_max, y_min, y_max] with min < max"),
     ("spawn_circle = [1.0, 2.0, 7.0]", "spawn_circle = [1.0, 2.0]",
      "agents[3].spawn_circle: need [cx, cy, r] with r > 0"),
     ('spawn = "box"', 'spawn = "boxes"', "agents[2].spawn: must be one of disc, fixed, box")],
)  # fmt: skip
def test_bad_spawn_rules_name_the_field(old, new, message):
    with pytest.raises(ConfigError) as info:
        DomainConfig.from_toml(SPAWNS.replace(old, new))
    assert message in str(info.value)


def test_derived_fields_are_never_silently_overridden():
    domain = DomainConfig.from_toml(ROVERS_AND_UAVS)
    with pytest.raises(ConfigError, match=r"n_rovers: is derived from the \[\[agents\]\] tables"):
        domain.replace(n_rovers=5)
    assert domain.replace(n_rovers=6) == domain  # the derived value itself is fine
    for name in ("n_rovers", "domain.n_rovers"):
        with pytest.raises(ConfigError, match=f"{name}: set"):
            RunConfig(domain).with_overrides({name: 5})


def test_class_names_that_the_torchrl_env_uses_are_reserved():
    with pytest.raises(ConfigError, match="agents.0..name: 'done' is one of the TorchRL"):
        DomainConfig.from_toml('[domain]\nn_req = 1\n[[agents]]\nname = "done"')


def test_a_typed_poi_lets_a_non_capturing_class_count():
    text = '[domain]\nn_req = 1\n[[agents]]\nname = "uav"\ncaptures = false\n'
    domain = DomainConfig.from_toml(text + "[[pois]]\nrequire = { uav = 1 }")
    assert domain.pois[0].require == {"uav": 1}


def test_runs_that_differ_in_a_class_are_told_apart():
    from physrover.analysis.curve_data import differing_fields
    from physrover.config.roles import role_fields

    one = DomainConfig.from_toml(ROVERS_AND_UAVS)
    two = DomainConfig.from_toml(ROVERS_AND_UAVS.replace("count = 2", "count = 3"))
    assert differing_fields([role_fields(one), role_fields(two)]) == [
        "n_rovers", "uav.count"]  # fmt: skip
    assert role_fields(DomainConfig()) == {}


# -- classes under physical motion --------------------------------------------------------


def test_world_frame_commands_become_the_bodies_setpoints():
    from physrover.domain.agents.roles import Roles
    from physrover.domain.motion.integrator import setpoints

    domain = _domain(TWO.replace("bounds = [-10.0, 4.0, -10.0, 10.0]\n", "")).replace(
        motion="physics")  # fmt: skip
    world, _ = _world(domain, [(0, 0), (1, 1)], headings=[0.3, 2.0])  # the UAV within 3
    actions = np.array([[[0.5, 0.2], [0.6, -0.4]]])
    target_v, heading = np.empty((1, 2, 2)), np.empty((1, 2))
    state = world.state
    setpoints(actions, state.rover_positions, state.rover_headings, state.cos_h, state.sin_h,
              None, Roles.build(domain), target_v, heading)  # fmt: skip
    assert target_v[0, 1].tolist() == [1.2, -0.8]  # speed 2, (x, y): exact, no frame turned
    c, s = np.cos(0.3), np.sin(0.3)  # the rover: its own frame, speed 1
    np.testing.assert_allclose(target_v[0, 0], [c * 0.5 - s * 0.2, s * 0.5 + c * 0.2],
                               atol=1e-12)  # fmt: skip


def test_a_gated_body_stays_at_rest():
    domain = _domain(TWO.replace("bounds = [-10.0, 4.0, -10.0, 10.0]\n", "")).replace(
        motion="physics")  # fmt: skip
    world, _ = _world(domain, [(0, 0), (8, 0)])  # the UAV beyond 3: the rover may not move
    for _ in range(5):
        world.step(np.array([[[1.0, 0.0], [0.0, 1.0]]]))
    np.testing.assert_array_equal(world.position_history[:6, 0, 0], np.zeros((6, 2)))
    assert world.rover_positions[0, 1, 1] > 1.0  # the UAV flew up (+y), heading or not


def test_one_class_of_the_paper_rovers_is_the_paper_team_under_physics():
    paper = DomainConfig(n_req=2, motion="physics", n_rovers=6)
    mirror = DomainConfig.from_toml('[domain]\nn_req = 2\nmotion = "physics"\n[[agents]]\n'
                                    'name = "rover"\ncount = 6\n')  # fmt: skip
    worlds = [RoverWorld(c, 2) for c in (paper, mirror)]
    actions = np.random.default_rng(4).uniform(-1.2, 1.2, (20, 2, 6, 2))
    play_alike(worlds, actions)
    a, b = worlds
    np.testing.assert_array_equal(a.position_history, b.position_history)
    np.testing.assert_array_equal(a.observations, b.observations)


def test_a_class_that_never_captures_is_a_mask_equal_to_the_rules_path():
    """UAVs that never capture and the paper's POIs: the plan scores with the paper's
    kernel and a ``counted`` mask; the POI rules' kernel (``counts_for``) gives the same
    episode bit for bit."""
    import dataclasses

    from physrover.domain.scoring.rules import PoiRules

    domain = DomainConfig.from_toml(ROVERS_AND_UAVS).replace(n_req=2, poi_ring_radius=4.0)
    worlds = [RoverWorld(domain, 3) for _ in range(2)]
    step = worlds[0].plan.step
    assert step.rules is None and step.counted.tolist() == [True] * 4 + [False] * 2
    ruled = step._replace(rules=PoiRules.build(domain, 3, always=True), counted=None)
    worlds[1].plan = dataclasses.replace(worlds[1].plan, step=ruled)
    for seed in range(5):
        actions = np.random.default_rng(seed).uniform(-1.2, 1.2, (domain.steps, 3, 6, 2))
        play_alike(worlds, actions)
        a, b = worlds
        assert a.G.max() > 0  # couplings met, so both paths' captures are exercised
        np.testing.assert_array_equal(a.state.in_range, b.state.in_range)
        np.testing.assert_array_equal(a.G, b.G)
        np.testing.assert_array_equal(a.D, b.D)


@pytest.mark.parametrize("seed", range(3))
def test_classes_that_all_sense_with_the_papers_sensor_take_its_kernel_bit_for_bit(seed):
    """A team of classes (one that does not capture) whose every class senses with the
    paper's density sensor is sensed by its vectorised kernel for the whole team; the class
    table (the lidar as the density sensor) reads the same, bit for bit."""
    import dataclasses

    from physrover.domain.sensing.classes import ClassSensing

    agents = [{"name": "rover", "count": 10}, {"name": "uav", "count": 5, "captures": False}]
    config = DomainConfig(n_req=1, agents=agents)
    worlds = [RoverWorld(config, 5) for _ in range(2)]
    assert worlds[0].plan.step.density is not None and worlds[0].plan.step.classes is None
    table = worlds[1].plan.step._replace(density=None, classes=ClassSensing.build(config))
    worlds[1].plan = dataclasses.replace(worlds[1].plan, step=table)
    rng = np.random.default_rng(seed)
    commands = rng.uniform(-1.5, 1.5, (config.steps, 5, 15, 2))
    for world in worlds:
        world.reset([np.random.default_rng([seed, e]) for e in range(5)])
        for t in range(config.steps):
            world.step(commands[t])
    np.testing.assert_array_equal(worlds[0].observations, worlds[1].observations)
    np.testing.assert_array_equal(worlds[0].D, worlds[1].D)
