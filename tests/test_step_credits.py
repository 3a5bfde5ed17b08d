"""Per-step credits (``step_credits``) and the critic fitted step by step
(``[learn] critic_target = "step"``, issue 46 lever 1): hand-worked steps, a plain-loop
oracle from the recorded positions, and what the CCEA stores in the critic's replay."""

from types import SimpleNamespace

import numpy as np
import pytest

from physrover.config import ConfigError, DomainConfig, RunConfig
from physrover.core.registry import CREDITS
from physrover.domain.scoring.difference import d_plus_plus, step_credits
from physrover.domain.world import RoverWorld
from tests.oracles import coupled_score_loops, wandering_world


def _record(rows, values, n_req):
    """A state whose record ``in_range`` is ``rows`` (T + 1, R, K) of one team."""
    near = np.array(rows, dtype=bool)[:, None]  # (T + 1, 1, R, K)
    return SimpleNamespace(in_range=near, poi_values=np.array([values], dtype=float)), \
        np.array(n_req)  # fmt: skip


def test_hand_worked_steps():
    # 3 rovers, POIs of value 3 and 5, coupling 2 for both. Step 0: nobody near anything.
    # Step 1: rovers 0 and 1 at POI 0 (captured), rover 2 alone at POI 1.
    # Step 2: rover 0 alone at POI 0.
    rows = [
        [[0, 0], [0, 0], [0, 0]],
        [[1, 0], [1, 0], [0, 1]],
        [[1, 0], [0, 0], [0, 0]],
    ]
    state, n_req = _record(rows, [3.0, 5.0], [2, 2])
    G = step_credits(state, n_req, "G")[:, 0]
    np.testing.assert_array_equal(G, [[0, 0, 0], [3, 3, 3], [0, 0, 0]])
    D = step_credits(state, n_req, "D")[:, 0]
    np.testing.assert_array_equal(D, [[0, 0, 0], [3, 3, 0], [0, 0, 0]])
    # D++ (one partner): at step 1 rovers 0 and 1 gain nothing from a copy, D++ = D = 3;
    # rover 2 with a copy captures POI 1: 5. At step 2 rover 0 with a copy captures POI 0: 3,
    # though the episode's D of rover 0 is 3 for every step.
    Dpp = step_credits(state, n_req, "D++")[:, 0]
    np.testing.assert_array_equal(Dpp, [[0, 0, 0], [3, 3, 5], [3, 0, 0]])
    with pytest.raises(ValueError, match="step credits are G, D or D"):
        step_credits(state, n_req, "ID")


def test_coupling_three_takes_the_fewest_partners_that_help():
    # coupling 3 at a POI of value 6: rover 0 alone needs two partners: (6 - 0) / 2 = 3;
    # rovers 1 and 2 together need one: 6 / 1 = 6.
    rows = [[[0], [0], [0]], [[1], [0], [0]], [[0], [1], [1]]]
    state, n_req = _record(rows, [6.0], [3])
    np.testing.assert_array_equal(step_credits(state, n_req, "D++")[:, 0],
                                  [[0, 0, 0], [3, 0, 0], [0, 6, 6]])  # fmt: skip


def _step_oracle(world, signal):
    """(T + 1, E, R) each step's credit by plain loops over the recorded positions."""
    cfg = world.config
    n_req = cfg.n_req_per_poi
    steps = world.position_history.shape[0]
    scored = steps - (cfg.scored_states != "all")
    out = np.zeros((steps, world.n_teams, world.n_rovers))

    def score(t, e, extra_rover, copies, removed):
        return coupled_score_loops(world, e, range(t, min(t + 1, scored)), extra_rover, copies,
                                   removed)  # fmt: skip

    for t in range(steps):
        for e in range(world.n_teams):
            G = score(t, e, -1, 1, -1)
            for i in range(world.n_rovers):
                D = G - score(t, e, -1, 1, i)
                out[t, e, i] = {"G": G, "D": D}.get(signal, D)
                N = max(n_req) - 1
                if signal != "D++" or N < 1:
                    continue
                gain = {n: (score(t, e, i, 1 + n, -1) - G) / n for n in range(1, N + 1)}
                if gain[N] > D:
                    out[t, e, i] = next(gain[n] for n in range(1, N + 1) if gain[n] > D)
    return out


@pytest.mark.parametrize("signal", ["G", "D", "D++"])
@pytest.mark.parametrize(("n_req", "scored"), [(2, "all"), (3, "all"), ((1, 4, 2), "all"),
                                               (3, "before-steps")])  # fmt: skip
def test_step_credits_match_the_plain_loop_oracle(signal, n_req, scored):
    world = wandering_world(n_req, scored, action_seed=2)
    got = step_credits(world.state, world.n_req, signal)
    np.testing.assert_array_equal(got, _step_oracle(world, signal))
    np.testing.assert_array_equal(got, CREDITS[signal].per_step(world))
    assert got.any()  # the episodes are ones where something was near


def test_an_episode_of_one_scored_step_has_the_episode_credits():
    # When only one step has anyone near a POI, that step's credits are the episode's.
    config = DomainConfig(n_rovers=4, n_req=2, poi_values=(3.0, 5.0), d_cap=1.0, steps=3)
    world = RoverWorld(config, 1)
    world.reset([np.random.default_rng(0)])
    state = world.state
    state.in_range[:] = False
    state.in_range[2, 0] = [[1, 0], [1, 1], [0, 1], [0, 0]]
    alone = step_credits(state, world.n_req, "D++")
    assert not alone[[0, 1, 3]].any()
    # the episode's captures as the record says: POI 0 by rovers 0 and 1, POI 1 by 1 and 2
    state.captured[0] = [True, True]
    state.captured_without[0] = [[False, True], [False, False], [True, False], [True, True]]
    state.score[0] = 8.0
    np.testing.assert_array_equal(alone[2], d_plus_plus(state, world.n_req))
    np.testing.assert_array_equal(alone[2, 0], [3, 8, 5, 0])


def _step_config(**learn):
    fields = {"method": "max-critic", "feedback": "D++", "critic_target": "step",
              "n_rovers": 4, "n_req": 2, "population": 4, "steps": 10, "eval_episodes": 1,
              "poi_ring_radius": 3.0, **learn}  # fmt: skip
    return RunConfig().with_overrides(fields)


@pytest.mark.parametrize("signal", ["D", "D++"])
def test_the_ccea_stores_each_pair_with_its_own_steps_credit(signal):
    from physrover.learn.ccea import CCEA

    ccea = CCEA(_step_config(feedback=signal))
    ccea.run_generation()
    world, critic = ccea.env.world, ccea.method.critic
    # The replay holds round 0's pairs: policy p of rover r played in team where[r, p];
    # its pair t carries the credit of its step t + 1, by the plain-loop oracle.
    per_step = _step_oracle(world, signal)
    R, k, T = 4, 4, 10
    stored = critic.buffer.feedback[:, : k * T].reshape(R, k, T)
    obs, act = world.trajectories()
    pairs = critic.buffer.items[:, : k * T].reshape(R, k, T, -1)
    for r in range(R):
        for p in range(k):
            same = (obs[:, :, r] == pairs[r, p, None, :, :-2].swapaxes(0, 1)).all(axis=(0, 2))
            team = int(np.flatnonzero(same)[0])
            np.testing.assert_array_equal(pairs[r, p, :, -2:], act[:, team, r])
            np.testing.assert_allclose(stored[r, p], per_step[1:, team, r].astype(np.float32))
    assert stored.any() or not per_step.any()


def test_the_episode_target_is_unchanged_and_the_options_are_checked():
    from physrover.learn.ccea import CCEA

    ccea = CCEA(_step_config(critic_target="episode"))
    assert not ccea.method.needs_step_feedback
    ccea.run_generation()
    stored = ccea.method.critic.buffer.feedback[:, :40].reshape(4, 4, 10)
    assert (stored == stored[..., :1]).all()  # every pair carries its trajectory's feedback
    with pytest.raises(ConfigError, match="critic_target: must be one of episode, step"):
        _step_config(critic_target="pair")
    with pytest.raises(ConfigError, match="per-step targets are defined for feedback"):
        _step_config(feedback="ID")
    with pytest.raises(ConfigError, match="critic_target: is a setting of .*not of method 'D'"):
        _step_config(method="D")
    with pytest.raises(ConfigError, match="critic_target: per-step targets need a critic that"):
        _step_config(method="mean-critic")
    with pytest.raises(ConfigError, match="critic_target: per-step targets need POIs"):
        RunConfig.from_toml(
            '[critic]\ncritic_target = "step"\n[[pois]]\nvalue = 1.0\n[[pois]]\nvalue = 2.0\n'
            'after = [0]\n')  # fmt: skip
