"""D++, per-POI coupling and the scoring window: hand-worked episodes and a plain-loop oracle.

Every episode here places rovers with ``reset(options=...)`` and holds them still (zero
actions) or moves them by hand, so each value can be worked out on paper.
"""

import numpy as np
import pytest

from physrover import RoverEnv
from physrover.config import ConfigError, DomainConfig
from physrover.domain.scoring.difference import d_plus_plus
from physrover.domain.world import RoverWorld, StartOverrides
from tests.oracles import coupled_score_loops, wandering_world

# POI 0 (value 3) at the origin, POI 1 (value 5) at (20, 0); capture radius 1.
POIS = [[0.0, 0.0], [20.0, 0.0]]
AT_0, AT_1, FAR = [0.5, 0.0], [20.0, 0.5], [-40.0, 0.0]


def _still_episode(n_req, rovers, steps=2, **fields):
    """A world of one team, rovers at ``rovers``, held still for ``steps`` steps."""
    config = DomainConfig(n_rovers=len(rovers), n_req=n_req, poi_values=(3.0, 5.0), d_cap=1.0,
                          steps=steps, **fields)  # fmt: skip
    world = RoverWorld(config, 1)
    world.reset([np.random.default_rng(0)], StartOverrides(rover_positions=rovers,
                                                           poi_positions=POIS))  # fmt: skip
    for _ in range(steps):
        world.step(np.zeros((1, len(rovers), 2)))
    return world


def test_dpp_hand_worked_pairs():
    # n_req 2: rovers 0 and 1 complete POI 0; rover 2 is alone at POI 1; rover 3 is nowhere.
    world = _still_episode(2, [AT_0, AT_0, AT_1, FAR])
    assert world.G[0] == 3.0
    np.testing.assert_array_equal(world.D[0], [3.0, 3.0, 0.0, 0.0])
    # One partner (N = 1): rovers 0 and 1 gain nothing from a copy (D++(1) = 0 <= D = 3,
    # so D++ is D); rover 2 with a copy captures POI 1: (8 - 3) / 1 = 5.
    np.testing.assert_array_equal(d_plus_plus(world.state, world.n_req)[0], [3, 3, 5, 0])


def test_dpp_hand_worked_triples():
    # n_req 3: rovers 0 and 1 at POI 0 (2 of 3, nothing captured); rover 2 alone at POI 1.
    world = _still_episode(3, [AT_0, AT_0, AT_1, FAR])
    assert world.G[0] == 0.0 and not world.D.any()
    # N = 2. Rover 0: D++(2) = 3 / 2 > D = 0, and already D++(1) = (3 - 0) / 1 = 3 > 0: 3.
    # Rover 2: D++(1) = 0 (2 of 3), D++(2) = 5 / 2 = 2.5: 2.5. Rover 3 was never near: 0.
    np.testing.assert_array_equal(d_plus_plus(world.state, world.n_req)[0], [3, 3, 2.5, 0])


def test_dpp_with_coupling_one_is_D():
    world = _still_episode(1, [AT_0, AT_0, AT_1, FAR])
    np.testing.assert_array_equal(d_plus_plus(world.state, world.n_req), world.D)


def _dpp_oracle(world) -> np.ndarray:
    """D++ by plain loops over the recorded positions (Eq. 13 recomputed from scratch)."""
    cfg = world.config
    n_req = cfg.n_req_per_poi
    T = world.position_history.shape[0] - (cfg.scored_states != "all")
    E, R = world.n_teams, world.n_rovers

    def score(e, extra_rover, copies, removed):
        return coupled_score_loops(world, e, range(T), extra_rover, copies, removed)

    out = np.zeros((E, R))
    for e in range(E):
        G = score(e, -1, 1, -1)
        for i in range(R):
            D = G - score(e, -1, 1, i)
            N = max(n_req) - 1
            gain = {n: (score(e, i, 1 + n, -1) - G) / n for n in range(1, N + 1)}
            out[e, i] = D
            if N >= 1 and gain[N] > D:
                out[e, i] = next(gain[n] for n in range(1, N + 1) if gain[n] > D)
    return out


@pytest.mark.parametrize(("n_req", "scored"), [(2, "all"), (3, "all"), ((1, 4, 2), "all"),
                                               (3, "before-steps")])  # fmt: skip
def test_dpp_matches_the_plain_loop_oracle_on_random_episodes(n_req, scored):
    world = wandering_world(n_req, scored, action_seed=1)
    got = d_plus_plus(world.state, world.n_req)
    np.testing.assert_array_equal(got, _dpp_oracle(world))
    assert (got != world.D).any()  # the episodes are ones where partners matter


def test_per_poi_coupling_captures_each_poi_at_its_own_n_req():
    # One rover at each POI: POI 0 needs 1 (captured), POI 1 needs 2 (not).
    world = _still_episode((1, 2), [AT_0, AT_1])
    assert world.G[0] == 3.0
    np.testing.assert_array_equal(world.state.capture_step[0], [0, -1])
    world = _still_episode((1, 1), [AT_0, AT_1])
    assert world.G[0] == 8.0


def test_per_poi_coupling_is_validated():
    with pytest.raises(ConfigError, match="n_req: a list needs one coupling per POI"):
        DomainConfig(n_req=(1, 2))
    with pytest.raises(ConfigError, match=r"n_req: must be in \[1, n_rovers=15\], got 16"):
        DomainConfig(n_req=(1, 2, 3, 16))
    assert DomainConfig(n_req=[2, 3, 2, 1]).n_req_per_poi == (2, 3, 2, 1)
    assert DomainConfig(n_req=4).n_req_per_poi == (4, 4, 4, 4)


@pytest.mark.parametrize("scored", ["all", "before-steps"])
def test_scoring_window_changes_G_only_for_a_capture_at_the_final_step(scored):
    # Two rovers step into POI 0's range at the last of 2 steps and stay until then only.
    config = DomainConfig(n_rovers=2, n_req=2, poi_values=(3.0, 5.0), d_cap=1.0, steps=2,
                          scored_states=scored)  # fmt: skip
    world = RoverWorld(config, 1)
    start = [[-2.5, 0.0], [-2.5, 0.0]]
    world.reset([np.random.default_rng(0)], StartOverrides(start, [0.0, 0.0], POIS))
    world.step(np.array([[[1.0, 0.0], [1.0, 0.0]]]))  # at x = -1.5: out of range
    assert world.G[0] == 0.0
    world.step(np.array([[[1.0, 0.0], [1.0, 0.0]]]))  # at x = -0.5: in range, final state
    assert world.G[0] == (3.0 if scored == "all" else 0.0)
    # A capture before the final step counts either way.
    world.reset([np.random.default_rng(0)], StartOverrides([[-1.5, 0.0]] * 2, [0.0, 0.0], POIS))
    world.step(np.array([[[1.0, 0.0], [1.0, 0.0]]]))  # at x = -0.5 after step 1 of 2
    world.step(np.array([[[-1.0, 0.0], [-1.0, 0.0]]]))  # back out
    assert world.G[0] == 3.0


def test_the_options_through_the_env_the_ccea_and_config_errors():
    from gymnasium.utils.env_checker import check_env

    from physrover.config import RunConfig
    from physrover.learn.ccea import CCEA

    env = RoverEnv(n_rovers=3, n_req=[1, 2, 3, 2], scored_states="before-steps")
    check_env(env, skip_render_check=True)
    with pytest.raises(ConfigError, match="scored_states: must be one of all, before-steps"):
        DomainConfig(scored_states="final")
    with pytest.raises(ConfigError, match=r"unknown credit signal 'D\+' \(did you mean 'D\+\+'"):
        RunConfig().with_overrides({"feedback": "D+"})
    # Method D's fitness is the feedback: with D++ it is each policy's D++.
    config = RunConfig().with_overrides({"feedback": "D++", "method": "D", "n_rovers": 4,
                                         "n_req": 2, "population": 4, "steps": 10,
                                         "eval_episodes": 1, "poi_ring_radius": 3.0})  # fmt: skip
    ccea = CCEA(config)
    ccea.run_generation()
    world = ccea.env.world
    G, credit = ccea.rollout(np.zeros((5, 4), dtype=np.int64))
    np.testing.assert_array_equal(credit, d_plus_plus(world.state, world.n_req))


def test_the_options_on_the_command_line(capsys):
    from physrover.cli.main import main

    sets = ["feedback=D++", "n_req=[1, 2, 3, 2]", "scored_states=before-steps", "sectors=6",
            "radius=9"]  # fmt: skip
    args = ["info", *(x for s in sets for x in ("--set", s))]
    assert main(args) == 0
    out = capsys.readouterr().out
    for line in ('feedback = "D++"', "n_req = [1, 2, 3, 2]", 'scored_states = "before-steps"',
                 "sectors = 6", "radius = 9.0"):  # fmt: skip
        assert line in out
    assert main(["info", "--set", "n_req=[1, 2]"]) == 2
    assert "n_req: a list needs one coupling per POI (4), got 2" in capsys.readouterr().err


def test_dpp_copies_of_a_rover_help_only_where_it_went():
    # Per-POI coupling (1, 2): rover 0 sits at POI 0 (captured alone); POI 1 sees nobody.
    # Copies of rover 0 add nobody at POI 1, so D++ is D = 3 (a first compact version
    # counted a never-visited POI as reachable with n_req copies).
    world = _still_episode((1, 2), [AT_0, FAR])
    np.testing.assert_array_equal(world.D[0], [3.0, 0.0])
    np.testing.assert_array_equal(d_plus_plus(world.state, world.n_req)[0], [3.0, 0.0])
