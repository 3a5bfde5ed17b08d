"""The partial-coupling credit ``D-partial`` (issue 46, lever 4): hand-worked episodes and
a plain-loop oracle from the recorded positions."""

from types import SimpleNamespace

import numpy as np
import pytest

from physrover.config import ConfigError, RunConfig
from physrover.core.registry import CREDITS
from physrover.domain.scoring.difference import partial_difference
from tests.oracles import wandering_world


def _episode(rows, values, n_req, score=0.0, D=None):
    """One team's record ``rows`` (T + 1, R, K), values (K,), G ``score``, and D if G > 0."""
    near = np.array(rows, dtype=bool)[:, None]
    n_rovers, n_pois = near.shape[2:]
    captured_without = np.zeros((1, n_rovers, n_pois), dtype=bool)
    state = SimpleNamespace(in_range=near, poi_values=np.array([values], dtype=float),
                            score=np.array([score]), captured=np.zeros((1, n_pois), bool),
                            captured_without=captured_without)  # fmt: skip
    return state, np.array(n_req)


def test_hand_worked_without_a_capture():
    # Coupling 3 at POIs of value 6 and 3. Step 1: rover 0 alone at POI 0. Step 2: rovers 1
    # and 2 at POI 0 (2 of 3), rover 3 alone at POI 1. No capture: G = 0, D = 0 for all.
    rows = [
        [[0, 0], [0, 0], [0, 0], [0, 0]],
        [[1, 0], [0, 0], [0, 0], [0, 0]],
        [[0, 0], [1, 0], [1, 0], [0, 1]],
    ]
    state, n_req = _episode(rows, [6.0, 3.0], [3, 3])
    # Soft score: POI 0 progress 2/3 (step 2), POI 1 1/3: 6 * 2/3 + 3 * 1/3 = 5.
    # Without rover 0: POI 0 still 2/3 at step 2: credit 0 (its step-1 visit is dominated).
    # Without rover 1 (or 2): POI 0 max(1/3, 1/3) = 1/3: 6 * (2/3 - 1/3) = 2.
    # Without rover 3: POI 1 progress 0: 3 * 1/3 = 1.
    np.testing.assert_allclose(partial_difference(state, n_req)[0], [0.0, 2.0, 2.0, 1.0])


def test_a_team_that_captures_gets_d_itself():
    rows = [[[0], [0]], [[1], [1]]]
    state, n_req = _episode(rows, [4.0], [2], score=4.0)
    state.captured[0] = True  # captured by both: without either it is not
    np.testing.assert_array_equal(partial_difference(state, n_req)[0], [4.0, 4.0])


def _partial_oracle(world):
    """D-partial by plain loops over the recorded positions."""
    cfg = world.config
    hist, pois, values = world.position_history, world.poi_positions, world.poi_values
    n_req = cfg.n_req_per_poi
    scored = hist.shape[0] - (cfg.scored_states != "all")

    def soft(e, removed):
        total = 0.0
        for k in range(world.n_pois):
            best = 0.0
            for t in range(scored):
                n = sum(1 for i in range(world.n_rovers) if i != removed
                        and (d := hist[t, e, i] - pois[e, k]) @ d <= cfg.d_cap**2)  # fmt: skip
                best = max(best, min(1.0, n / n_req[k]))
            total += values[e, k] * best
        return total

    out = np.zeros((world.n_teams, world.n_rovers))
    for e in range(world.n_teams):
        for i in range(world.n_rovers):
            out[e, i] = world.D[e, i] if world.G[e] > 0 else soft(e, -1) - soft(e, i)
    return out


@pytest.mark.parametrize(("n_req", "scored"), [(3, "all"), (4, "all"), ((2, 5, 3), "all"),
                                               (5, "before-steps")])  # fmt: skip
def test_partial_credit_matches_the_plain_loop_oracle(n_req, scored):
    world = wandering_world(n_req, scored, action_seed=3)
    got = CREDITS["D-partial"](world)
    np.testing.assert_allclose(got, _partial_oracle(world), rtol=1e-12, atol=1e-12)
    captured = world.G > 0
    np.testing.assert_array_equal(got[captured], world.D[captured])
    assert (got[~captured] > 0).any() or captured.all()


def test_the_ccea_takes_it_as_feedback_and_the_options_are_checked():
    from physrover.learn.ccea import CCEA

    config = RunConfig().with_overrides({"feedback": "D-partial", "method": "D", "n_rovers": 4,
                                         "n_req": 3, "population": 4, "steps": 10,
                                         "eval_episodes": 1, "poi_ring_radius": 3.0})  # fmt: skip
    ccea = CCEA(config)
    ccea.run_generation()
    G, credit = ccea.rollout(np.zeros((5, 4), dtype=np.int64))
    np.testing.assert_array_equal(credit, partial_difference(ccea.env.world.state,
                                                             ccea.env.world.n_req))  # fmt: skip
    with pytest.raises(ConfigError, match="D-partial is not defined for POIs with after"):
        RunConfig.from_toml('[learn]\nfeedback = "D-partial"\n[[pois]]\nvalue = 1.0\n'
                            "[[pois]]\nvalue = 2.0\nafter = [0]\n")  # fmt: skip
