"""Scenarios: the built-in start states, their draws checked against hand-replayed draws,
determinism per seed and per redraw mode, and errors for bad values."""

import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from physrover import RoverEnv, RoverVectorEnv
from physrover.config import ConfigError, DomainConfig, RunConfig
from physrover.domain.world import RoverWorld, StartOverrides


def _world(scenario, n_teams=4, **fields):
    return RoverWorld(DomainConfig(scenario=scenario, **fields), n_teams)


def _starts(world, seeds):
    world.reset([np.random.default_rng(s) for s in seeds])
    return world.rover_positions.copy(), world.rover_headings.copy(), world.poi_positions.copy()


def test_ring_random_replays_its_draws():
    # Per team: 3 uniforms per rover (radius, angle, heading), then 2 per POI (angle, radius).
    scenario = {"kind": "ring-random", "poi_ring_radius": 10.0, "ring_thickness": 0.4}
    world = _world(scenario, n_teams=2)
    _, _, pois = _starts(world, [7, 8])
    for team, seed in enumerate([7, 8]):
        rng = np.random.default_rng(seed)
        rng.random((15, 3))
        u = rng.random((4, 2))
        angle, radius = 2 * np.pi * u[:, 0] - np.pi, 6.0 + 4.0 * u[:, 1]
        expected = np.stack([radius * np.cos(angle), radius * np.sin(angle)], -1)
        np.testing.assert_allclose(pois[team], expected, rtol=0, atol=1e-14)
    radii = np.hypot(*pois.reshape(-1, 2).T)
    assert radii.min() >= 6.0 and radii.max() <= 10.0
    # Thickness 0: every POI on the ring.
    _, _, pois = _starts(_world({"kind": "ring-random", "poi_ring_radius": 10.0}), range(4))
    np.testing.assert_allclose(np.hypot(*pois.reshape(-1, 2).T), 10.0, rtol=1e-14)


def test_uniform_keeps_its_square_and_separation():
    scenario = {"kind": "uniform", "half_size": 6.0, "min_separation": 4.0}
    _, _, pois = _starts(_world(scenario, n_teams=50), range(50))
    assert np.abs(pois).max() <= 6.0
    gaps = np.linalg.norm(pois[:, :, None] - pois[:, None], axis=-1)
    gaps[:, np.arange(4), np.arange(4)] = np.inf
    assert gaps.min() >= 4.0
    with pytest.raises(ConfigError, match="min_separation: 4 POIs cannot be drawn 30.0 apart"):
        DomainConfig(scenario={"kind": "uniform", "half_size": 6.0, "min_separation": 30.0})


def test_explicit_places_what_the_table_says():
    scenario = {
        "kind": "explicit",
        "poi_positions": [[1, 2], [3, 4]],
        "rover_positions": [[0, 0], [1, 0], [2, 0]],
        "rover_headings": [0, 1, 2],
    }
    world = _world(scenario, n_teams=2, n_rovers=3, n_req=1, poi_values=(1.0, 5.0))
    positions, headings, pois = _starts(world, [0, 1])
    np.testing.assert_array_equal(pois, [[[1, 2], [3, 4]]] * 2)
    np.testing.assert_array_equal(positions, [[[0, 0], [1, 0], [2, 0]]] * 2)
    np.testing.assert_array_equal(headings, [[0, 1, 2]] * 2)
    np.testing.assert_array_equal(world.poi_values, [[1, 5]] * 2)
    with pytest.raises(ConfigError, match=r"poi_positions: need one position per POI value \(4\)"):
        DomainConfig(scenario={"kind": "explicit", "poi_positions": [[1, 2]]})
    with pytest.raises(ConfigError, match="rover_positions: need none or one per rover"):
        DomainConfig(scenario={"kind": "explicit", "rover_positions": [[1, 2]]})
    text = RunConfig(DomainConfig(scenario=scenario, n_rovers=3, n_req=1,
                                  poi_values=(1.0, 5.0))).to_toml()  # fmt: skip
    assert "poi_positions = [[1.0, 2.0], [3.0, 4.0]]" in text
    assert RunConfig.from_toml(text).domain.scenario.rover_headings == (0.0, 1.0, 2.0)


@pytest.mark.parametrize("kind", ["ring", "ring-random", "uniform", "explicit"])
def test_same_seeds_same_starts_other_seeds_other_starts(kind):
    a = _starts(_world(kind), [1, 2, 3, 4])
    b = _starts(_world(kind), [1, 2, 3, 4])
    c = _starts(_world(kind), [5, 6, 7, 8])
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x, y)
    assert not np.array_equal(a[0], c[0])  # the rovers are drawn in every scenario


def test_redraw_generation_shares_all_but_the_fresh_teams():
    world = _world({"kind": "ring-random", "redraw": "generation"}, n_teams=6)
    world.fresh_teams = 2
    positions, headings, pois = _starts(world, range(6))
    for arr in (positions, headings, pois):
        assert all(np.array_equal(arr[0], arr[e]) for e in range(4))
        assert not np.array_equal(arr[0], arr[4]) and not np.array_equal(arr[4], arr[5])
    # The shared draw is team 0's own, and the generators advance as under "episode".
    episode = _world({"kind": "ring-random"}, n_teams=6)
    rngs_g, rngs_e = ([np.random.default_rng(s) for s in range(6)] for _ in range(2))
    world.reset(rngs_g)
    episode.reset(rngs_e)
    np.testing.assert_array_equal(world.poi_positions[:4], episode.poi_positions[[0] * 4])
    np.testing.assert_array_equal(world.poi_positions[4:], episode.poi_positions[4:])
    assert [r.random() for r in rngs_g] == [r.random() for r in rngs_e]


def test_redraw_never_is_one_start_for_every_team_seed_and_episode():
    scenario = {"kind": "uniform", "redraw": "never", "layout_seed": 3}
    a = _starts(_world(scenario), [0, 1, 2, 3])
    again = _world(scenario)
    b = _starts(again, [9, 9, 9, 9])
    c = _starts(again, [4, 5, 6, 7])
    for x, y, z in zip(a, b, c, strict=True):
        np.testing.assert_array_equal(x, y)
        np.testing.assert_array_equal(y, z)
        assert all(np.array_equal(x[0], x[e]) for e in range(4))
    other = _starts(_world({**scenario, "layout_seed": 4}), [0, 1, 2, 3])
    assert not np.array_equal(a[2], other[2])


def test_the_ccea_shares_a_generation_start_and_evaluates_on_fresh_ones():
    from physrover.learn.ccea import CCEA

    config = RunConfig().with_overrides({"scenario": "ring-random", "redraw": "generation",
                                         "population": 4, "eval_episodes": 3, "n_rovers": 3,
                                         "n_req": 1, "steps": 5})  # fmt: skip
    ccea = CCEA(config)
    ccea.run_generation()
    pois = ccea.env.world.poi_positions  # 4 training teams, then 3 evaluation episodes
    assert all(np.array_equal(pois[0], pois[e]) for e in range(4))
    assert len({pois[e].tobytes() for e in range(4, 7)} | {pois[0].tobytes()}) == 4


def test_scenarios_through_the_env_and_the_command_line(capsys):
    from physrover.cli.main import main

    check_env(RoverEnv(scenario="ring-random", redraw="generation"), skip_render_check=True)
    check_env(RoverEnv(scenario="uniform", min_separation=3.0), skip_render_check=True)
    venv = RoverVectorEnv(3, scenario="uniform", half_size=8.0)
    obs, _ = venv.reset(seed=0)
    assert obs.shape == (3, 15, 8) and np.abs(venv.world.poi_positions).max() <= 8.0
    assert main(["info", "--set", "scenario=ring-random", "--set", "ring_thickness=0.5"]) == 0
    out = capsys.readouterr().out
    assert '[scenario]\nkind = "ring-random"' in out and "ring_thickness = 0.5" in out
    assert main(["info", "--set", "scenario=ring-random", "--set", "redraw=always"]) == 2
    assert "redraw: must be one of episode, generation, never" in capsys.readouterr().err
    with pytest.raises(ConfigError, match="ring_thickness: must be in"):
        DomainConfig(scenario={"kind": "ring-random", "ring_thickness": 1.5})


def test_obstacles_stop_physical_rovers_and_are_an_error_under_ideal_motion():
    # One rover at the origin facing +x drives at full speed into a disc of radius 1 at
    # (4, 0) for 12 steps; POIs out of the way.
    scenario = {"kind": "explicit", "poi_positions": [[0.0, 30.0]],
                "rover_positions": [[0.0, 0.0]], "rover_headings": [0.0],
                "obstacle_discs": [[4.0, 0.0, 1.0]]}  # fmt: skip
    fields = dict(n_rovers=1, n_req=1, poi_values=(1.0,), steps=12)
    with pytest.raises(ConfigError, match="motion: 'ideal' motion cannot hold the scenario's"):
        _world(scenario, **fields)
    world = _world(scenario, n_teams=3, motion="physics", **fields)
    np.testing.assert_array_equal(world.state.obstacles, [[[4.0, 0.0, 4.0, 0.0, 1.0]]] * 3)
    world.reset([np.random.default_rng(e) for e in range(3)])
    for _ in range(12):
        world.step(np.tile([1.0, 0.0], (3, 1, 1)))
    track = world.position_history[:, :, 0]  # (T + 1, E, 2)
    gap = np.hypot(*(track - [4.0, 0.0]).transpose(2, 0, 1))
    radius = DomainConfig().physics.rover_radius
    # The speculative pass stops the full-speed impact at contact (within Chipmunk's slop,
    # 1% of the radius); without it the body overlapped the disc by 0.14 units for a step.
    assert gap.min() >= 1.0 + radius - 0.01 * radius - 1e-9
    np.testing.assert_allclose(gap[-1], 1.0 + radius, atol=0.01)
    assert track[-1, :, 0].max() < 4.0  # in front of it
    with pytest.raises(ConfigError, match=r"obstacle_discs: every obstacle is \[x, y, radius"):
        DomainConfig(scenario={"kind": "explicit", "obstacle_discs": [[1.0, 2.0, -1.0]]})


def test_uniform_draws_a_dense_layout_it_accepts():
    # 10 POIs 8.5 apart in a 30 x 30 square: accepted, and every draw succeeds (a bad early
    # placement restarts the layout instead of failing the reset).
    scenario = {"kind": "uniform", "half_size": 15.0, "min_separation": 8.5}
    config = DomainConfig(poi_values=tuple(range(1, 11)), scenario=scenario)
    world = RoverWorld(config, 20)
    for s in range(5):
        world.reset([np.random.default_rng(100 * s + e) for e in range(20)])
        gaps = np.linalg.norm(
            world.poi_positions[:, :, None] - world.poi_positions[:, None], axis=-1
        )
        gaps[:, np.arange(10), np.arange(10)] = np.inf
        assert gaps.min() >= 8.5
    with pytest.raises(ConfigError, match="10 POIs cannot be drawn 10.0 apart"):
        config.replace(min_separation=10.0)


def test_evaluation_envs_draw_a_fresh_start_per_team_under_generation_redraws():
    scenario = {"kind": "ring-random", "redraw": "generation"}
    shared = RoverVectorEnv(4, scenario=scenario)
    fresh = RoverVectorEnv(4, scenario=scenario, fresh_teams=4)
    shared.reset(seed=0)
    fresh.reset(seed=0)
    assert len({shared.world.poi_positions[e].tobytes() for e in range(4)}) == 1
    assert len({fresh.world.poi_positions[e].tobytes() for e in range(4)}) == 4
    # Each fresh team starts as RoverEnv with its own seed under "episode" redraws.
    single = RoverEnv(scenario="ring-random")
    single.reset(seed=2)
    np.testing.assert_array_equal(
        fresh.world.poi_positions[2], single.unwrapped.world.poi_positions[0]
    )


@pytest.mark.parametrize("integrator", ["auto", "compiled"])
def test_obstacle_contacts_hold_at_every_impact_phase_and_angle(integrator):
    # Rovers start 3.0-4.0 from a disc of radius 1 (so the impact falls at different
    # points of the step), aimed at it head-on and off-centre, at full speed.
    starts, headings = [], []
    for distance in np.linspace(3.0, 4.0, 9):
        for offset in (0.0, 0.5, 1.0):  # lateral offset of the aim, world units
            starts.append([-distance, offset])
            headings.append(0.0)
    n = len(starts)
    scenario = {"kind": "explicit", "poi_positions": [[0.0, 30.0]],
                "obstacle_discs": [[0.0, 0.0, 1.0]]}  # fmt: skip
    world = _world(scenario, n_teams=n, n_rovers=1, n_req=1, poi_values=(1.0,), steps=8,
                   motion="physics", physics={"integrator": integrator})  # fmt: skip
    assert world.dynamics.uses_pymunk == (integrator == "auto")
    world.reset([np.random.default_rng(e) for e in range(n)],
                StartOverrides(np.array(starts)[:, None], np.array(headings)[:, None]))  # fmt: skip
    worst = np.inf
    for _ in range(8):
        world.step(np.tile([1.0, 0.0], (n, 1, 1)))
        worst = min(worst, np.hypot(*world.rover_positions[:, 0].T).min())
    radius = DomainConfig().physics.rover_radius
    assert worst >= 1.0 + radius - 0.01 * radius - 1e-9


def test_spawn_density_grows_the_disc_with_the_team_and_a_thousand_rovers_start_apart():
    import math

    from physrover import DomainConfig, RoverVectorEnv
    from physrover.config import ConfigError
    from physrover.domain.motion.separation import pair_overlaps

    paper = DomainConfig(n_rovers=1000).scenario
    assert paper.disc_radius(1000) == 1.5  # off by default: the paper's disc at any R
    dense = DomainConfig(n_rovers=15, scenario={"kind": "ring", "spawn_density": 2.2})
    assert dense.scenario.disc_radius(15) == 1.5  # 2.1 per unit^2 already: the disc stays
    assert dense.scenario.disc_radius(1000) == pytest.approx(math.sqrt(1000 / (2.2 * math.pi)))
    config = DomainConfig(n_rovers=1000, motion="physics",
                          scenario={"kind": "ring", "spawn_density": 0.2})  # fmt: skip
    env = RoverVectorEnv(2, config)
    env.reset(seed=3)
    positions = env.world.state.rover_positions
    assert np.hypot(*positions.reshape(-1, 2).T).max() <= 39.9 + 0.5
    # none of 2 x 499,500 pairs overlaps by more than the spawn separation's slop (~0.1%)
    assert pair_overlaps(positions, 0.2).max() <= 0.005
    with pytest.raises(ConfigError, match="wall_half_size"):  # walls must hold the grown disc
        config.replace(walls=True, wall_half_size=30.0)
    with pytest.raises(ConfigError, match="spawn_density"):
        DomainConfig(scenario={"kind": "ring", "spawn_density": -1.0})


def test_a_spawn_density_too_small_for_a_finite_disc_is_one_line_error():
    """A density so small that the disc's radius overflows (found by the property test:
    2.2e-313 spawned every rover at infinity) is refused, naming the floor."""
    with pytest.raises(ConfigError, match=r"^spawn_density: must be 0 \(off\) or >= 1e-06"):
        DomainConfig(scenario={"kind": "ring", "spawn_density": 2.2e-313})
    assert DomainConfig(scenario={"kind": "ring", "spawn_density": 1e-6}).scenario.disc_radius(
        15) < 3000  # fmt: skip
