"""The regret credit ``D-regret`` (issue 46, after the plateau reading): hand-worked
episodes and a plain-loop oracle from the recorded positions."""

from types import SimpleNamespace

import numpy as np
import pytest

from physrover.config import ConfigError, RunConfig
from physrover.core.registry import CREDITS
from physrover.domain.scoring.difference import difference, regret
from tests.oracles import wandering_world


def _episode(rows, values, n_req):
    """One team's record ``rows`` (T + 1, R, K) and values (K,) under the paper's rule:
    captures, captures without each rover and G counted from the rows."""
    near = np.array(rows, dtype=bool)  # (T + 1, R, K)
    need = np.array(n_req)
    count = near.sum(axis=1)  # (T + 1, K)
    captured = (count >= need).any(axis=0)
    without = ((count[:, None, :] - near) >= need).any(axis=0)  # (R, K)
    values = np.array(values, dtype=float)
    state = SimpleNamespace(in_range=near[:, None], poi_values=values[None],
                            score=np.array([values @ captured]), captured=captured[None],
                            captured_without=without[None])  # fmt: skip
    return state, need


def test_hand_worked_surplus_rover_and_a_poi_one_short():
    # Coupling 2, POIs of value 4 and 3. Step 1: rovers 0, 1, 2 at POI 0 (captured with one
    # to spare), rover 3 alone at POI 1 (one short). Rover 4 never near a POI.
    rows = [
        [[0, 0]] * 5,
        [[1, 0], [1, 0], [1, 0], [0, 1], [0, 0]],
    ]
    state, n_req = _episode(rows, [4.0, 3.0], [2, 2])
    # G = 4; D = 0 for everyone (POI 0 keeps 2 without any one of rovers 0-2).
    # Rovers 0-2, 4: relocated to POI 1 (1 other there) it is captured: G_k = 4 + 3 = 7,
    # regret 3. Rover 3: without it POI 1 has nobody (0 + 1 < 2), POI 0 is captured
    # already: regret 0.
    np.testing.assert_allclose((difference(state) - regret(state, n_req))[0], [-3, -3, -3, 0, -3])


def test_a_needed_rover_keeps_its_d():
    # Coupling 2, POIs of value 4 and 3: rovers 0, 1 capture POI 0; rover 2 alone at POI 1.
    rows = [[[0, 0]] * 3, [[1, 0], [1, 0], [0, 1]]]
    state, n_req = _episode(rows, [4.0, 3.0], [2, 2])
    # Rover 0: D = 4; moved to POI 1 the team scores 0 + 3 = 3 < 4: no regret. Rover 2:
    # D = 0, relocated anywhere it completes nothing new (POI 0 is captured without it,
    # POI 1 has no one else): no regret.
    np.testing.assert_allclose((difference(state) - regret(state, n_req))[0], [4, 4, 0])


def _regret_oracle(world):
    """D-regret by plain loops over the recorded positions."""
    cfg = world.config
    hist, pois, values = world.position_history, world.poi_positions, world.poi_values
    n_req = cfg.n_req_per_poi
    scored = hist.shape[0] - (cfg.scored_states != "all")

    def others_near(e, k, t, i):
        return sum(1 for j in range(world.n_rovers) if j != i
                   and (d := hist[t, e, j] - pois[e, k]) @ d <= cfg.d_cap**2)  # fmt: skip

    out = np.zeros((world.n_teams, world.n_rovers))
    for e in range(world.n_teams):
        for i in range(world.n_rovers):
            captured_without = [any(others_near(e, k, t, i) >= n_req[k] for t in range(scored))
                                for k in range(world.n_pois)]  # fmt: skip
            g_without = sum(values[e, k] for k in range(world.n_pois) if captured_without[k])
            best = g_without
            for k in range(world.n_pois):
                most = max(others_near(e, k, t, i) for t in range(scored))
                if not captured_without[k] and most + 1 >= n_req[k]:
                    best = max(best, g_without + values[e, k])
            G = world.G[e]
            out[e, i] = (G - g_without) - max(0.0, best - G)
    return out


@pytest.mark.parametrize(("n_req", "scored"), [(2, "all"), (3, "all"), ((2, 4, 3), "all"),
                                               (3, "before-steps")])  # fmt: skip
def test_regret_credit_matches_the_plain_loop_oracle(n_req, scored):
    world = wandering_world(n_req, scored, action_seed=5)
    got = CREDITS["D-regret"](world)
    want = _regret_oracle(world)
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12)
    assert (got <= world.D).all() and (got < world.D).any()  # some rover has a regret
    # D++-regret: the same regret taken from D++ (tested on its own in test_credit_variants)
    dpp = CREDITS["D++"](world)
    np.testing.assert_allclose(CREDITS["D++-regret"](world), dpp - (world.D - want),
                               rtol=1e-12, atol=1e-12)  # fmt: skip


def test_the_ccea_takes_it_as_feedback_and_the_options_are_checked():
    from physrover.learn.ccea import CCEA

    config = RunConfig().with_overrides({"feedback": "D-regret", "method": "max-critic",
                                         "n_rovers": 4, "n_req": 2, "population": 4,
                                         "steps": 10, "eval_episodes": 1,
                                         "poi_ring_radius": 3.0})  # fmt: skip
    ccea = CCEA(config)
    ccea.run_generation()
    G, credit = ccea.rollout(np.zeros((5, 4), dtype=np.int64))
    world = ccea.env.world
    np.testing.assert_array_equal(credit, world.D - regret(world.state, world.n_req))
    with pytest.raises(ConfigError, match="D-regret is not defined for POIs with after"):
        RunConfig.from_toml('[learn]\nfeedback = "D-regret"\n[[pois]]\nvalue = 1.0\n'
                            "[[pois]]\nvalue = 2.0\nafter = [0]\n")  # fmt: skip
    with pytest.raises(ConfigError, match="agents that never capture"):
        RunConfig.from_toml('[learn]\nfeedback = "D-regret"\n[[agents]]\nname = "rover"\n'
                            'count = 3\n[[agents]]\nname = "uav"\ncount = 1\n'
                            "captures = false\n")  # fmt: skip
