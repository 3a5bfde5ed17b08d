"""RoverWorld: start state, idealised motion, determinism, trajectories, input errors."""

import math

import numpy as np
import pytest
from oracles import IdealMotion

from physrover.config import DomainConfig
from physrover.domain.world import RoverWorld, StartOverrides


def _gens(n, seed=0):
    return [np.random.default_rng(seed + i) for i in range(n)]


def test_pois_evenly_on_the_ring_counter_clockwise():
    w = RoverWorld(DomainConfig(), n_teams=2)
    w.reset(_gens(2))
    expected = 15.0 * np.array([[1, 0], [0, 1], [-1, 0], [0, -1]])
    np.testing.assert_allclose(w.poi_positions[1], expected, atol=1e-12)
    np.testing.assert_array_equal(w.poi_values[0], [1, 2, 3, 4])


def test_rovers_start_in_the_spawn_disc_with_uniform_headings():
    w = RoverWorld(DomainConfig(), n_teams=400)
    w.reset(_gens(400))
    r = np.hypot(w.rover_positions[..., 0], w.rover_positions[..., 1])
    assert r.max() <= 1.5
    # Uniform in the disc: P(r <= 1.5 / sqrt(2)) = 1/2.
    assert abs(np.mean(r <= 1.5 / math.sqrt(2)) - 0.5) < 0.02
    h = w.rover_headings
    assert h.min() >= -math.pi and h.max() < math.pi
    assert abs(np.mean(h > 0) - 0.5) < 0.02


def test_ideal_motion_moves_in_the_rover_frame_and_turns_to_the_move():
    motion = IdealMotion()
    pos = np.zeros((1, 3, 2))
    heading = np.array([[0.0, math.pi / 2, 1.0]])
    act = np.array([[[1.0, 0.0], [1.0, 1.0], [0.0, 0.0]]])
    new_pos, new_heading = motion.step(pos, heading, act)
    # Rover 0 faces +x: moves (1, 0), keeps heading 0.
    np.testing.assert_allclose(new_pos[0, 0], [1.0, 0.0])
    assert new_heading[0, 0] == 0.0
    # Rover 1 faces +y: forward 1 and left 1 is world (-1, 1); heading becomes 135 deg.
    np.testing.assert_allclose(new_pos[0, 1], [-1.0, 1.0], atol=1e-12)
    assert new_heading[0, 1] == pytest.approx(3 * math.pi / 4)
    # Rover 2 does not move: heading unchanged.
    np.testing.assert_array_equal(new_pos[0, 2], [0.0, 0.0])
    assert new_heading[0, 2] == 1.0


def test_actions_are_clipped_and_nan_is_an_error():
    w = RoverWorld(DomainConfig(n_rovers=1, n_req=1, steps=3), n_teams=1)
    w.reset(_gens(1), StartOverrides(rover_positions=[(0.0, 0.0)], rover_headings=[0.0]))
    w.step(np.array([[[5.0, 0.0]]]))
    np.testing.assert_allclose(w.rover_positions[0, 0], [1.0, 0.0])
    np.testing.assert_array_equal(w.actions[0, 0, 0], [1.0, 0.0])
    with pytest.raises(ValueError, match="NaN"):
        w.step(np.array([[[np.nan, 0.0]]]))
    with pytest.raises(ValueError, match=r"shape \(1, 1, 2\)"):
        w.step(np.zeros((1, 2, 2)))


def test_same_seed_same_episode_and_teams_are_independent():
    cfg = DomainConfig(n_rovers=5)
    actions = np.random.default_rng(3).uniform(-1, 1, (cfg.steps, 4, 5, 2))

    def run(gens):
        w = RoverWorld(cfg, n_teams=4)
        obs = [w.reset(gens)]
        obs += [w.step(a) for a in actions]
        return np.array(obs), w.rover_positions

    a, pa = run(_gens(4, seed=10))
    b, pb = run(_gens(4, seed=10))
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(pa, pb)
    c, _ = run(_gens(4, seed=11))  # team i now starts like team i + 1 did
    np.testing.assert_array_equal(c[0, :3], a[0, 1:])


def test_trajectories_record_observation_action_pairs():
    cfg = DomainConfig(n_rovers=3, steps=4)
    w = RoverWorld(cfg, n_teams=2)
    obs0 = w.reset(_gens(2))
    acts = np.random.default_rng(0).uniform(-1, 1, (4, 2, 3, 2))
    obs = [obs0] + [w.step(a) for a in acts]
    s, a = w.trajectories()
    assert s.shape == (4, 2, 3, 8) and a.shape == (4, 2, 3, 2)
    np.testing.assert_allclose(s, np.array(obs[:4]), rtol=1e-6)
    np.testing.assert_allclose(a, acts, rtol=1e-6)
    with pytest.raises(RuntimeError, match="episode is over"):
        w.step(acts[0])


def test_scenario_shapes_are_checked():
    w = RoverWorld(DomainConfig(n_rovers=3), n_teams=2)
    with pytest.raises(ValueError, match=r"rover_positions must have shape \(3, 2\)"):
        w.reset(_gens(2), StartOverrides(rover_positions=np.zeros((4, 2))))
    with pytest.raises(ValueError, match="poi_values must have shape"):
        w.reset(_gens(2), StartOverrides(poi_values=[1.0, 2.0]))
    with pytest.raises(ValueError, match="poi_values must be positive"):
        w.reset(_gens(2), StartOverrides(poi_values=[1.0, 2.0, -3.0, 4.0]))
    with pytest.raises(ValueError, match="unknown reset option 'rovers'"):
        StartOverrides.from_options({"rovers": 1})
    with pytest.raises(ValueError, match="one generator per team"):
        w.reset(_gens(1))


def test_scenario_does_not_change_the_random_stream():
    cfg = DomainConfig(n_rovers=3)
    w = RoverWorld(cfg, n_teams=1)
    g1, g2 = _gens(1), _gens(1)
    w.reset(g1, StartOverrides(rover_positions=np.zeros((3, 2))))
    w.reset(g2)
    assert g1[0].random() == g2[0].random()


def test_step_before_reset_is_an_error():
    with pytest.raises(RuntimeError, match="reset"):
        RoverWorld(DomainConfig(), 1).step(np.zeros((1, 15, 2)))
