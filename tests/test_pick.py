"""Rovers that pick a UAV (issue 43, item 4): the lab's ``pick_uav`` action and ``follow``
policy (``action = "pick"``, ``"follow"``) and its ``UavDistanceLidar`` (``kind =
"distances"``), on the compiled step: hand-worked moves, the lab's code written as it is,
and a plain-loop oracle over random episodes."""

import math

import numpy as np
import pytest

from physrover.config import ConfigError, DomainConfig, LearnConfig
from physrover.domain.world import RoverWorld, StartOverrides

TEAM = """
[domain]
n_req = 1
steps = {steps}
motion = "{motion}"
[[agents]]
name = "rover"
count = 2
action = "{action}"
picks = ["uav"]
max_speed = 1.0
[agents.sensor]
kind = "distances"
classes = ["uav"]
radius = 5.0
[[agents]]
name = "uav"
count = 2
captures = false
action = "world"
max_speed = 2.0
[agents.sensor]
kind = "lidar"
radius = 10.0
"""


def _world(action="pick", steps=3, motion="ideal", start=None, teams=1):
    domain = DomainConfig.from_toml(TEAM.format(action=action, steps=steps, motion=motion))
    world = RoverWorld(domain, teams)
    start = np.array(start if start is not None else
                     [(0.0, 0.0), (10.0, 10.0), (3.0, 0.5), (-0.3, -4.0)])  # fmt: skip
    overrides = StartOverrides(rover_positions=start, rover_headings=np.zeros(4))
    obs = world.reset([np.random.default_rng(e) for e in range(teams)], overrides)
    return world, obs


def _command(*firsts):
    """Team 0's commands: each rover's first component, the UAVs still."""
    return np.array([[[a, 0.0] for a in firsts] + [[0.0, 0.0], [0.0, 0.0]]])


def test_a_pick_steps_towards_the_picked_uav_clipped_per_component():
    world, _ = _world()
    # U = 2 UAVs, 3 bins of [-1, 1]: [-1, -1/3) UAV 0, [-1/3, 1/3) UAV 1, [1/3, 1] stay
    world.step(_command(-1.0, 0.0))
    # rover 0 towards UAV 0 at (3, 0.5): (3, 0.5) clipped to (1, 0.5); rover 1 towards
    # UAV 1 at (-0.3, -4) from (10, 10): (-10.3, -14) clipped to (-1, -1)
    np.testing.assert_array_equal(world.rover_positions[0, :2], [[1.0, 0.5], [9.0, 9.0]])
    world.step(_command(0.34, 1.0))  # both stay (the last bin, and 1 itself)
    np.testing.assert_array_equal(world.rover_positions[0, :2], [[1.0, 0.5], [9.0, 9.0]])
    world.step(_command(-0.34, 7.0))  # -0.34 is UAV 0's bin; 7 is clipped to 1: stay
    np.testing.assert_array_equal(world.rover_positions[0, :2], [[2.0, 0.5], [9.0, 9.0]])
    assert world.rover_headings[0, 0] == 0.0  # facing its move (+x)


def test_the_pick_is_judged_on_the_positions_before_anyone_moves():
    world, _ = _world(start=[(0.0, 0.0), (10.0, 10.0), (0.5, 0.0), (20.0, 20.0)])
    uavs_flee = np.array([[[-1.0, 0.0], [0.0, 0.0], [2.0, 0.0], [0.0, 0.0]]])
    world.step(uavs_flee)  # UAV 0 moves +1.. (clipped to 1 x 2) to (2.5, 0) in the same step
    assert world.rover_positions[0, 0].tolist() == [0.5, 0.0]  # to where it was: 0.5 away


def test_follow_takes_the_nearest_uav_in_sensor_range_or_stays():
    world, obs = _world("follow", start=[(0.0, 0.0), (10.0, 10.0), (3.0, 0.0), (0.0, -3.0)])
    # the lab's UavDistanceLidar: d / r within r, else -1
    np.testing.assert_allclose(obs[0, 0, :2], [0.6, 0.6])
    np.testing.assert_array_equal(obs[0, 1, :2], [-1.0, -1.0])
    world.step(_command(0.9, -0.9))  # a follower's command is not read
    # a tie at 3: the lower index, UAV 0; rover 1 sees no UAV within 5 and stays
    np.testing.assert_array_equal(world.rover_positions[0, :2], [[1.0, 0.0], [10.0, 10.0]])


def test_the_uav_gate_still_holds_a_picking_rover():
    text = TEAM.format(action="pick", steps=2, motion="ideal").replace(
        'picks = ["uav"]', 'picks = ["uav"]\nmoves_with = ["uav"]\nmoves_with_radius = 2.0'
    )
    world = RoverWorld(DomainConfig.from_toml(text), 1)
    world.reset([np.random.default_rng(0)], StartOverrides(
        rover_positions=np.array([(0.0, 0.0), (0.0, 5.0), (3.0, 0.0), (0.0, 6.0)]),
        rover_headings=np.zeros(4)))  # fmt: skip
    world.step(_command(-1.0, 0.0))  # rover 0: its UAV 3 away (gate 2): held; rover 1 moves
    np.testing.assert_array_equal(world.rover_positions[0, :2], [[0.0, 0.0], [0.0, 6.0]])


def _lab_uav_distances(agent, positions, types, obs_radius):
    """``UavDistanceLidar.scan`` as the lab writes it (``custom_env.py``)."""
    distances = []
    for i in range(len(positions)):
        if types[i] == "uav":
            distance = math.dist(positions[agent], positions[i])
            if distance <= obs_radius:
                distances.append(distance / obs_radius)
            else:
                distances.append(-1.0)
    return distances


def _lab_follow(observation):
    """``FollowPolicy.forward`` as the lab writes it (``ccea_utils.py``)."""
    observation = np.asarray(observation)
    if all(observation == -1):
        return [0.0 for _ in observation] + [1]
    f_obs = [o if o != -1 else np.inf for o in observation]
    action = [0.0 for _ in observation]
    action[np.argmin(f_obs)] = 1
    return action


def _lab_pick_move(agent, choice_outputs, positions, num_rovers, num_uavs, max_velocity):
    """The lab's ``pick_uav`` branch of ``evaluateTeamStatic`` (``ccea_lib.py``): argmax of
    the outputs, the last stays, else a step to that UAV bounded per component."""
    uav_ind = np.argmax(choice_outputs)
    if uav_ind == num_uavs:
        return np.array([0.0, 0.0])
    delta = np.asarray(positions[num_rovers + uav_ind]) - np.asarray(positions[agent])
    return np.array([min(max(v, -max_velocity), max_velocity) for v in delta])


@pytest.mark.parametrize("motion", ["ideal"])
@pytest.mark.parametrize("action", ["pick", "follow"])
@pytest.mark.parametrize("seed", range(3))
def test_random_episodes_move_as_the_labs_code(seed, action, motion):
    """Random UAV flights and random picks over 20 steps, 4 teams: every rover's move and
    reading is the lab's code as written (its pick as the one-hot of the bin's UAV)."""
    rng = np.random.default_rng(seed)
    start = rng.uniform(-6, 6, (4, 2))
    world, obs = _world(action, steps=20, motion=motion, start=start, teams=4)
    for _ in range(20):
        before = world.rover_positions.copy()
        commands = rng.uniform(-1, 1, (4, 4, 2))
        for e in range(4):
            for i in range(2):
                lab_obs = _lab_uav_distances(i, before[e], ["rover"] * 2 + ["uav"] * 2, 5.0)
                np.testing.assert_allclose(obs[e, i, :2], lab_obs, rtol=1e-6, atol=1e-7)
        obs = world.step(commands)
        for e in range(4):
            for i in range(2):
                if action == "follow":
                    outputs = _lab_follow(_lab_uav_distances(i, before[e], ["rover"] * 2 +
                                                             ["uav"] * 2, 5.0))  # fmt: skip
                else:
                    bin_ = min(int((commands[e, i, 0] + 1) / 2 * 3), 2)
                    outputs = np.eye(3)[bin_]
                move = _lab_pick_move(i, outputs, before[e], 2, 2, 1.0)
                np.testing.assert_array_equal(world.rover_positions[e, i], before[e, i] + move)


def test_under_physics_a_picking_rover_heads_for_its_pick():
    world, _ = _world("pick", motion="physics", start=[(0.0, 0.0), (10.0, 10.0), (4.0, 3.0),
                                                        (-9.0, 0.0)])  # fmt: skip
    for _ in range(3):
        world.step(_command(-1.0, 0.0))  # both rovers pick UAV 0 at (4, 3)
    for i, start in enumerate([(0.0, 0.0), (10.0, 10.0)]):
        moved = world.rover_positions[0, i] - start
        towards = np.array([4.0, 3.0]) - start
        cosine = moved @ towards / np.linalg.norm(moved) / np.linalg.norm(towards)
        assert np.linalg.norm(moved) > 0.3 and cosine > 0.95, (i, moved)


@pytest.mark.parametrize(("change", "message"), [
    ({"picks": []}, 'agents\\[0\\].picks: names the classes a "pick" or "follow" agent'),
    ({"picks": ["uav"], "action": "world"}, "agents\\[0\\].picks: names the classes"),
    ({"picks": ["uavs"]}, "agents\\[0\\].picks: unknown class 'uavs'"),
    ({"sensor": {"kind": "distances", "classes": ["uav"], "radius": math.inf}},
     "radius: must be finite and > 0"),
    ({"sensor": {"kind": "distances", "classes": []}}, "classes: name the"),
])  # fmt: skip
def test_bad_picks_name_the_field(change, message):
    domain = DomainConfig.from_toml(TEAM.format(action="pick", steps=3, motion="ideal"))
    rover = {**domain.agents[0].table(), **change}
    with pytest.raises(ConfigError, match=message):
        domain.replace(agents=[rover, domain.agents[1]])
    with pytest.raises(ConfigError, match='"follow" moves to the nearest agent within the s'):
        domain.replace(agents=[{**domain.agents[0].table(), "action": "follow",
                                "sensor": {"kind": "lidar"}}, domain.agents[1]])  # fmt: skip


def test_a_pick_policy_plays_its_largest_output_as_the_lab_does():
    """The CCEA's policies of a picking class: U + 1 outputs, the largest picks (a plain
    numpy forward and argmax, the lab's ``NeuralNetwork`` then ``np.argmax``), written as
    its bin's centre, which the world decodes back to the same pick."""
    from physrover.learn.classes import team_layout

    domain = DomainConfig.from_toml(TEAM.format(action="pick", steps=3, motion="ideal"))
    layout = team_layout(LearnConfig(hidden=6), domain)
    rover = layout.layouts[0]
    assert (rover.n_out, rover.n_in) == (3, 2)  # 2 UAVs + stay; one distance per UAV
    rng = np.random.default_rng(0)
    genomes = layout.init((4, 7), rng)[:, rng.integers(0, 7, 4)].transpose(1, 0, 2)  # (E, R, P)
    genomes = np.ascontiguousarray(genomes * 4.0)  # wide weights: every choice comes up
    obs = rng.uniform(-1, 1, (4, 4, layout.n_in)).astype(np.float32)
    out = layout.act(genomes, obs)
    picks = []
    for e in range(4):
        for r in range(2):
            g = genomes[e, r]
            w1 = g[:12].reshape(2, 6)
            b1, w2, b2 = g[12:18], g[18:36].reshape(6, 3), g[36:39]
            h = np.maximum(obs[e, r, :2] @ w1 + b1, 0)
            choice = int(np.argmax(h @ w2 + b2))
            assert out[e, r].tolist() == pytest.approx([-1 + (2 * choice + 1) / 3, 0.0])
            assert min(int((out[e, r, 0] + 1) / 2 * 3), 2) == choice  # the world's bin
            picks.append(choice)
    assert set(picks) == {0, 1, 2}
