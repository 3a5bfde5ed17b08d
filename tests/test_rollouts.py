"""Several episodes per team and generation (``[learn] rollouts``, the lab's num_rollouts,
issue 43): start states shared by rollout index, fitness the mean over a team's rollouts
(against a plain loop over the recorded episodes), checks, and import-lab."""

import numpy as np
import pytest
import yaml
from test_vanish import EXAMPLE

from physrover.analysis.curve_data import training_episodes
from physrover.config import ConfigError, DomainConfig, LearnConfig, RunConfig
from physrover.config.lab_run import lab_run
from physrover.domain.world import RoverWorld
from physrover.learn.ccea import CCEA

CONFIG = """
[domain]
n_rovers = 3
n_req = 1
steps = 12
scenario = {{ kind = "uniform", half_size = 5.0, redraw = "generation" }}
[learn]
method = "D"
population = 4
hidden = 4
eval_episodes = 2
rollouts = 3
{learn}
"""


def test_start_groups_share_a_draw_by_rollout_index():
    domain = DomainConfig.from_toml(
        '[domain]\nn_rovers = 3\nscenario = { kind = "uniform", redraw = "generation" }\n'
        "[failures]\nn_failing = 1\n"
    )
    world = RoverWorld(domain, 8)
    world.fresh_teams, world.start_groups = 2, 3
    world.reset([np.random.default_rng(e) for e in range(8)])
    start = world.position_history[0]  # (E, R, 2)
    pois, failing = world.state.poi_positions, world.plan.step.failures.at
    for e in range(6):  # the shared teams: team e % 3's draw
        np.testing.assert_array_equal(start[e], start[e % 3])
        np.testing.assert_array_equal(pois[e], pois[e % 3])
        np.testing.assert_array_equal(failing[e], failing[e % 3])
    for a, b in ((0, 1), (0, 2), (1, 2), (0, 6), (6, 7)):  # distinct draws
        assert not np.array_equal(start[a], start[b])


@pytest.mark.parametrize("learn", ["", 'selection = "elites"\nn_individual_elites = 1\n'
                                        "n_team_elites = 2"])  # fmt: skip
def test_fitness_is_the_mean_feedback_over_a_teams_rollouts(learn):
    ccea = CCEA(RunConfig.from_toml(CONFIG.format(learn=learn)))
    calls = []
    rollout = ccea.rollout

    def record(index):
        G, credit = rollout(index)
        calls.append((np.array(index), G.copy(), credit.copy(), ccea.genomes.copy(),
                      ccea.env.world.position_history[0].copy()))  # fmt: skip
        return G, credit

    ccea.rollout = record
    stats = ccea.run_generation()
    index, G, credit, _, start = calls[0]
    k, n, played = ccea.k, 3, ccea.n_played
    assert len(G) == played * n + 2
    train = index[: k * n : n]  # each training team's policies, its rows consecutive
    assert (index[: played * n].reshape(played, n, -1) == index[: played * n : n, None]).all()
    if not learn:  # binary tournament: the generation's fitness is each policy's feedback
        for m in range(k):  # plain loops: policy train[m, r] of rover r played rows m*n..
            for r in range(3):
                expected = sum(credit[m * n + j, r] for j in range(n)) / n
                assert ccea.fitness[r, train[m, r]] == pytest.approx(expected, abs=1e-12)
    means = [sum(G[m * n + j] for j in range(n)) / n for m in range(k)]
    assert stats.train_G_mean == pytest.approx(np.mean(means))
    assert stats.eval_G == pytest.approx(G[played * n :].mean())
    for e in range(played * n):  # rollout j of every team starts alike
        np.testing.assert_array_equal(start[e], start[e % n])
    assert not np.array_equal(start[0], start[1])
    assert np.ptp(G[: played * n]) > 0  # the episodes differ: the means are not vacuous


def test_rollouts_are_checked_and_counted():
    with pytest.raises(ConfigError, match="rollouts: must be >= 1, got 0"):
        LearnConfig(method="D", rollouts=0)
    with pytest.raises(ConfigError, match='rollouts: averages one-episode fitness: method "D"'):
        LearnConfig(method="max-critic", rollouts=2)
    run = RunConfig.from_toml(CONFIG.format(learn=""))
    assert training_episodes(run) == 4 * 3


def test_import_lab_plays_the_labs_rollouts():
    lab = yaml.safe_load(EXAMPLE.read_text())
    lab["ccea"]["evaluation"]["multi_rollout"]["num_rollouts"] = 3
    learn = lab_run(lab)[0].learn
    assert (learn.rollouts, learn.eval_episodes, learn.method) == (3, 3, "D")
