"""Agents that fail mid-episode (``[failures]``): the compiled step against plain loops.

An agent that fails at step s does not move into state s or after (its command recorded as
0), is in range of nothing from state s on, and observes 0; its teammates still see its
body. Checked here against loops written from that rule over many seeds: the positions,
records, observations, G and D (Eq. 1) of whole episodes, the compiled episode of the
learners, the physical model, teams reset apart, influence credit, and the draws
(reproducible, each team's from its own generator, nothing drawn when off).
"""

import numpy as np
import pytest

from physrover.config import ConfigError, DomainConfig
from physrover.domain.agents.failures import NEVER, draw_failures
from physrover.domain.world import RoverWorld
from tests.oracles import numerators, relate, sense

SEEDS = range(6)


def _config(**fields):
    """6 rovers near 3 POIs (ring radius 3, capture radius 2), 12 steps: couplings form."""
    base = DomainConfig(n_rovers=6, poi_values=(1.0, 2.0, 4.0), steps=12, d_cap=2.0)
    return base.replace(poi_ring_radius=3.0, **fields)


def _episode(config, seed, n_teams=8):
    world = RoverWorld(config, n_teams)
    world.reset([np.random.default_rng([seed, e]) for e in range(n_teams)])
    rng = np.random.default_rng(seed + 100)
    commands = rng.uniform(-1.5, 1.5, (config.steps, n_teams, config.n_rovers, 2))
    for t in range(config.steps):
        world.step(commands[t])
    return world, commands


def _moves_loops(world, commands):
    """Positions (T + 1, E, R, 2) of the idealised kinematics, agent by agent: an agent
    alive at state t + 1 moves by its clipped command in its heading's frame and turns to
    face the move; a failed one stays, its heading kept."""
    at = world.plan.step.failures.at
    pos = world.position_history[0].copy()
    heading = world.heading_history[0].copy()
    out = [pos.copy()]
    for t in range(commands.shape[0]):
        for e in range(pos.shape[0]):
            for i in range(pos.shape[1]):
                if t + 1 >= at[e, i]:
                    continue
                fwd, left = np.clip(commands[t, e, i], -1.0, 1.0)
                c, s = np.cos(heading[e, i]), np.sin(heading[e, i])
                mx, my = c * fwd - s * left, s * fwd + c * left
                pos[e, i] += (mx, my)
                if fwd != 0.0 or left != 0.0:
                    heading[e, i] = np.arctan2(my, mx)
        out.append(pos.copy())
    return np.stack(out)


def _scores_loops(world, scored):
    """G (E,) and D (E, R) by plain loops (Eqs. 11-13, 1) over the recorded positions of
    the ``scored`` states, a failed agent in range of nothing."""
    cfg, at = world.config, world.plan.step.failures.at
    n_teams, n_rovers = world.n_teams, world.n_rovers

    def team_g(e, removed):
        total = 0.0
        for k in range(world.n_pois):
            for t in scored:
                n = 0
                for i in range(n_rovers):
                    d = world.position_history[t, e, i] - world.poi_positions[e, k]
                    if i != removed and t < at[e, i] and d @ d <= cfg.d_cap**2:
                        n += 1
                if n >= cfg.n_req_per_poi[k]:
                    total += world.poi_values[e, k]
                    break
        return total

    G = np.array([team_g(e, -1) for e in range(n_teams)])
    D = np.array([[G[e] - team_g(e, i) for i in range(n_rovers)] for e in range(n_teams)])
    return G, D


@pytest.mark.parametrize("n_req", [1, 2])
@pytest.mark.parametrize("scored_states", ["all", "before-steps"])
def test_an_episode_with_failures_is_the_plain_loops(n_req, scored_states):
    config = _config(n_req=n_req, scored_states=scored_states,
                     failures={"given": [[0, 0], [1, 5]], "n_failing": 2})  # fmt: skip
    captures = 0
    for seed in SEEDS:
        world, commands = _episode(config, seed)
        at = world.plan.step.failures.at
        np.testing.assert_allclose(world.position_history, _moves_loops(world, commands),
                                   rtol=0, atol=1e-12)  # fmt: skip
        for t in range(config.steps):  # a failed agent's command is recorded as 0
            dead = t + 1 >= at
            assert (world.actions[t][dead] == 0).all()
            live = np.clip(commands[t], -1, 1).astype(np.float32)
            np.testing.assert_array_equal(world.actions[t][~dead], live[~dead])
        numerator = numerators(world.n_rovers, world.poi_values)
        for t in range(config.steps):  # teammates still see a failed body; it sees nothing
            rel = relate(world.position_history[t], world.heading_history[t],
                         world.poi_positions, config.d_min)  # fmt: skip
            expected = np.where((t < at)[..., None], sense(rel, numerator), 0.0)
            np.testing.assert_allclose(world.observations[t], expected, rtol=1e-5, atol=1e-6)
        last = config.steps if scored_states == "all" else config.steps - 1
        G, D = _scores_loops(world, range(last + 1))
        np.testing.assert_allclose(world.G, G)
        np.testing.assert_allclose(world.D, D)
        assert (world.D[:, 0] == 0).all()  # out from the start: it changed nothing
        captures += int((G > 0).sum())
        np.testing.assert_array_equal(world.alive, config.steps < at)
    assert captures > 0  # the check saw captures, not only zeros


def test_failures_under_agent_classes_and_poi_rules_are_the_plain_rule():
    """A failed agent of a class world (UAVs and rovers, typed and distance-valued POIs)
    is in range of nothing and out of every distance value: the world equals a world where
    the failed agents' commands are 0 and the scoring is replayed without them."""
    agents = [{"name": "uav", "count": 2, "max_speed": 2.0, "captures": False},
              {"name": "rover", "count": 4}]  # fmt: skip
    pois = [{"value": 1.0, "n_req": 1}, {"value": 2.0, "n_req": 2, "value_by": "distance"},
            {"value": 3.0, "require": {"rover": 1}}]  # fmt: skip
    base = DomainConfig(poi_values=(1.0, 2.0, 3.0), steps=12, d_cap=3.0, agents=agents,
                        pois=pois).replace(poi_ring_radius=2.0)  # fmt: skip
    failing = base.replace(failures={"given": [[0, 3], [3, 4], [4, 0]]})
    for seed in SEEDS:
        world, commands = _episode(failing, seed, n_teams=4)
        at = world.plan.step.failures.at
        halted = commands.copy()
        for t in range(base.steps):
            halted[t][t + 1 >= at] = 0.0
        free, _ = _episode(base, seed, n_teams=4)  # the same draws: failures draw nothing
        free.reset([np.random.default_rng([seed, e]) for e in range(4)])
        for t in range(base.steps):
            free.step(halted[t])
        np.testing.assert_array_equal(world.position_history, free.position_history)
        alive = np.arange(base.steps + 1)[:, None, None] < at[None]
        np.testing.assert_array_equal(world.state.in_range,
                                      free.state.in_range & alive[..., None])  # fmt: skip
        from physrover.domain.scoring.influence import rescore

        replay = rescore(free, np.ascontiguousarray(~alive.transpose(1, 0, 2)[:, None]))
        np.testing.assert_allclose(world.G, replay[:, 0])


def test_the_compiled_episode_plays_failures_as_the_step_loop():
    from physrover.learn.policies import PolicyLayout
    from physrover.learn.rollout import play_episode

    config = _config(n_req=2, failures={"n_failing": 3, "between": [2, 9]})
    layout = PolicyLayout(7, RoverWorld(config, 1).obs_dim)
    policy = layout.prepare(layout.init((5, 6), np.random.default_rng(0)) * 4.0)
    worlds = []
    for compiled in (True, False):
        world = RoverWorld(config, 5)
        obs = world.reset([np.random.default_rng([3, e]) for e in range(5)])
        if compiled:
            play_episode(world, obs, policy, True)
        else:
            for _ in range(config.steps):
                obs = world.step(policy(obs))
        worlds.append(world)
    for name in ("observations", "actions", "position_history"):
        np.testing.assert_array_equal(getattr(worlds[0], name), getattr(worlds[1], name))
    np.testing.assert_array_equal(worlds[0].D, worlds[1].D)


def test_a_physical_rover_that_fails_brakes_to_rest_and_captures_nothing():
    config = _config(n_req=1, motion="physics", collisions=False, max_force=0.25,
                     steps=30, failures={"given": [[2, 6], [4, 0]]})  # fmt: skip
    world = RoverWorld(config, 3)
    world.reset([np.random.default_rng(e) for e in range(3)])
    speeds = []
    for _ in range(config.steps):
        world.step(np.ones((3, 6, 2)))
        speeds.append(np.linalg.norm(world.state.rover_velocities[:, 2], axis=-1))
    speeds = np.array(speeds)  # (T, E): rover 2's speed after each step
    assert (world.actions[5:, :, 2] == 0).all() and (world.actions[:5, :, 2] == 1).all()
    assert (speeds[5:] <= speeds[4:-1] + 1e-12).all()  # braking: never faster
    assert (speeds[-5:] < 1e-9).all()  # at rest
    still = world.position_history[:, :, 4] - world.position_history[:1, :, 4]
    assert np.abs(still).max() < 1e-12  # out from the start: never moved (the teams' shared
    # frame, each in its own cell, rounds a position's last bits)
    assert not world.state.in_range[6:, :, 2].any() and not world.state.in_range[:, :, 4].any()
    assert (world.observations[6:, :, 2] == 0).all()


def test_a_team_reset_apart_fails_as_a_world_of_it_alone():
    config = _config(n_req=1, failures={"n_failing": 2})
    world = RoverWorld(config, 4)
    rngs = [np.random.default_rng(e) for e in range(4)]
    world.reset(rngs)
    for _ in range(5):
        world.step(np.full((4, 6, 2), 0.5))
    mask = np.array([False, True, False, True])
    alone_rngs = [np.random.default_rng(e) for e in range(4)]
    for rng, other in zip(alone_rngs, rngs, strict=True):  # the same generator states
        rng.bit_generator.state = other.bit_generator.state
    world.reset(rngs, teams=mask)
    for _ in range(config.steps):
        world.step_teams(np.full((4, 6, 2), 0.5), mask)
    for e in np.flatnonzero(mask):
        alone = RoverWorld(config, 1)
        alone.reset([alone_rngs[e]])
        for _ in range(config.steps):
            alone.step(np.full((1, 6, 2), 0.5))
        np.testing.assert_array_equal(world.plan.step.failures.at[e],
                                      alone.plan.step.failures.at[0])  # fmt: skip
        np.testing.assert_array_equal(world.position_history[:, e], alone.position_history[:, 0])
        np.testing.assert_array_equal(world.observations[:, e], alone.observations[:, 0])
        np.testing.assert_array_equal(world.D[e], alone.D[0])


def test_draws_are_seeded_per_team_and_nothing_is_drawn_when_off():
    config = _config(failures={"given": [[5, 7]], "n_failing": 3, "between": [2, 4]})
    rngs = [np.random.default_rng(s) for s in range(50)]
    at = draw_failures(config, rngs)
    assert (at[:, 5] == 7).all()
    failing = at[:, :5] != NEVER
    assert (failing.sum(1) == 3).all()
    assert ((at[:, :5][failing] >= 2) & (at[:, :5][failing] <= 4)).all()
    again = draw_failures(config, [np.random.default_rng(s) for s in (7, 3)])
    np.testing.assert_array_equal(again, at[[7, 3]])  # a team's draw is its generator's
    assert failing.any(0).all()  # every free agent is drawn by some team
    off = _config()
    worlds = [RoverWorld(c, 2) for c in (off, off.replace(failures={"given": [[1, 3]]}))]
    states = []
    for world in worlds:  # given steps draw nothing: the scenario's draws are unchanged
        rngs = [np.random.default_rng(e) for e in range(2)]
        world.reset(rngs)
        states.append([r.bit_generator.state["state"]["state"] for r in rngs])
    assert states[0] == states[1]
    assert worlds[0].plan.step.failures is None  # off: the paper's step


def test_influence_credit_leaves_out_a_failed_uav():
    from physrover.domain.scoring.influence import influence

    agents = [{"name": "uav", "count": 2, "captures": False, "influence_radius": 50.0},
              {"name": "rover", "count": 4}]  # fmt: skip
    config = DomainConfig(poi_values=(1.0, 2.0), n_req=1, steps=8, agents=agents,
                          failures={"given": [[0, 3], [3, 5]]})  # fmt: skip
    world, _ = _episode(config, 0, n_teams=2)
    phi = influence(world)
    assert phi[:3, :, 0, 2:].any() and not phi[3:, :, 0].any()  # UAV 0 out from state 3
    assert not phi[5:, :, :, 3].any() and phi[:5, :, 1, 3].all()  # rover 3 out from 5


@pytest.mark.parametrize(
    ("table", "message"),
    [
        ({"given": [[6, 1]]}, "given: agent 6 is not in a team of 6"),
        ({"given": [[1, 13]]}, "given: step 13 is past the episode's 12 steps"),
        ({"given": [[1, 2], [1, 3]]}, "given: an agent is named twice: [1, 1]"),
        ({"given": [1, 2]}, "given: each entry must be [agent, step], got 1"),
        ({"n_failing": 7}, "n_failing: must be at most 6 (the agents given does not name), got 7"),
        ({"between": [5, 2]}, "between: must be [first, last], 0 <= first <= last, got [5, 2]"),
        ({"between": [1, 20]}, "between: last step 20 is past the episode's 12 steps"),
        ({"every": 3}, "every: unknown FailureConfig field"),
    ],
)
def test_bad_failures_are_one_line_errors(table, message):
    with pytest.raises(ConfigError) as info:
        _config(failures=table)
    assert str(info.value).startswith(message) and "\n" not in str(info.value)


def test_a_failed_agent_that_picks_or_follows_stays_put_under_idealised_motion():
    """Its move is its target's, whatever its command; failed, its gate is closed."""
    agents = [{"name": "uav", "count": 1, "captures": False, "max_speed": 2.0},
              {"name": "picker", "count": 2, "action": "pick", "picks": ["uav"]},
              {"name": "follower", "count": 2, "action": "follow", "picks": ["uav"],
               "sensor": {"kind": "lidar", "radius": 100.0}}]  # fmt: skip
    config = DomainConfig(n_req=1, steps=10, agents=agents,
                          failures={"given": [[1, 2], [3, 4]]})  # fmt: skip
    world = RoverWorld(config, 2)
    world.reset([np.random.default_rng(e) for e in range(2)])
    for _ in range(config.steps):
        world.step(np.tile([[1.0, 0.5], [-1.0, 0.0], [-1.0, 0.0], [0.0, 0.0], [0.0, 0.0]],
                           (2, 1, 1)))  # fmt: skip
    path = world.position_history
    assert (path[2:, :, 1] == path[1:2, :, 1]).all() and (path[4:, :, 3] == path[3:4, :, 3]).all()
    assert (path[1] != path[0])[:, [1, 3]].any()  # they moved while alive
    assert (path[-1] != path[4])[:, [2, 4]].any()  # and their live teammates still do


def test_failures_of_agents_that_pick_or_follow_under_physics_are_refused():
    """Under physics a picking or following agent's move is its target's, whatever its
    command: a failed one would keep moving, so the combination is refused in one line
    (the idealised motion stops it: its gate is closed)."""
    agents = [{"name": "uav", "count": 1, "captures": False},
              {"name": "rover", "count": 2, "action": "pick", "picks": ["uav"]}]  # fmt: skip
    base = DomainConfig(n_req=1, agents=agents)
    base.replace(failures={"n_failing": 1})  # idealised: fine
    with pytest.raises(ConfigError, match=r"^failures: agents that pick or follow \(rover\)"):
        base.replace(motion="physics", failures={"n_failing": 1})


def test_the_table_round_trips_and_is_absent_when_off():
    config = _config(failures={"given": [[2, 4]], "n_failing": 1, "between": [3, 9]})
    text = config.to_toml()
    assert "[failures]" in text
    assert DomainConfig.from_toml(text) == config
    assert "[failures]" not in _config().to_toml()  # configs written before it read the same
    assert _config().replace(n_failing=2).failures.n_failing == 2  # a bare --set name
