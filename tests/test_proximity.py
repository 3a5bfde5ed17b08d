"""MERL's proximity reward ("proximity"): hand-worked values, a plain-loop oracle over whole
episodes with captures, and the dense per-step reward a learner gets."""

import math

import numpy as np
import pytest

from physrover import RoverVectorEnv
from physrover.config import DomainConfig
from physrover.core.registry import CREDITS
from physrover.domain.scoring.credit import step_rewards
from physrover.domain.scoring.proximity import proximity


def test_hand_worked_values():
    # one team, three rovers, two POIs; d_cap = 4
    rovers = np.array([[[0.0, 0.0], [5.0, 0.0], [2.0, 3.0]]])
    pois = np.array([[[8.0, 0.0], [2.0, 0.0]]])
    both = np.array([[True, True]])
    first_closed = np.array([[True, False]])
    none_open = np.array([[False, False]])
    # rover 0: nearest open is (2, 0) at 2 -> min(1, 4/2) = 1; with it closed, (8, 0) at 8
    np.testing.assert_allclose(proximity(rovers, pois, both, 4.0)[0], [1.0, 1.0, 1.0])
    # rover 1 is 3 from (8, 0): min(1, 4/3) = 1; rover 2 is sqrt(36 + 9) from it
    got = proximity(rovers, pois, first_closed, 4.0)[0]
    np.testing.assert_allclose(got, [0.5, 1.0, 4 / math.sqrt(45)])
    np.testing.assert_array_equal(proximity(rovers, pois, none_open, 4.0)[0], [0.0, 0.0, 0.0])


def _oracle(world) -> np.ndarray:
    """(T + 1, E, R) with plain loops: min(1, d_cap / d) to the nearest POI not captured at
    step t or before, 0 with none open."""
    st, d_cap = world.state, world.config.d_cap
    out = np.zeros((world.t + 1, world.n_teams, world.n_rovers))
    for t in range(world.t + 1):
        for e in range(world.n_teams):
            for i in range(world.n_rovers):
                best = math.inf
                for k in range(st.poi_positions.shape[1]):
                    first = st.capture_step[e, k]
                    if first != -1 and first <= t:
                        continue
                    x, y = world.position_history[t, e, i]
                    px, py = st.poi_positions[e, k]
                    best = min(best, math.hypot(x - px, y - py))
                out[t, e, i] = 0.0 if best == math.inf else min(1.0, d_cap / best)
    return out


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_episode_against_the_oracle_and_dense_rewards(seed):
    # n_req 1, POIs near the start: POIs are captured during the episode, so the open set shrinks
    domain = DomainConfig(n_rovers=6, n_req=1, scenario={"kind": "ring", "poi_ring_radius": 5.0})
    env = RoverVectorEnv(4, config=domain)
    env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    dense = []
    for t in range(domain.steps):
        _, reward, *_ = env.step(rng.uniform(-1, 1, (4, 6, 2)).astype(np.float32))
        dense.append(step_rewards("proximity", env.world, t == domain.steps - 1, reward))
    world = env.world
    assert (world.state.capture_step > 0).any()  # the oracle's closed branch is exercised
    expected = _oracle(world)
    got = CREDITS["proximity"].per_step(world)
    np.testing.assert_allclose(got, expected, rtol=1e-12, atol=0)
    # the reward at step t is the state after it (row t + 1), every step, not only the last
    np.testing.assert_allclose(np.array(dense), expected[1:], rtol=1e-12, atol=0)
    np.testing.assert_allclose(CREDITS["proximity"](world), expected[1:].sum(axis=0),
                               rtol=1e-12)  # fmt: skip
