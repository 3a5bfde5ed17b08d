"""The team the learning curve plays (``[learn] eval_team``, issue 43): the lab's test team,
the previous generation's best team by G, as it played; by hand, inside a running CCEA,
across a resume, and from import-lab."""

import numpy as np
import pytest
import yaml
from test_vanish import EXAMPLE

from physrover.config import ConfigError, LearnConfig, RunConfig
from physrover.config.lab_run import lab_run
from physrover.learn.ccea import CCEA
from physrover.learn.eval_team import BestTeam

CONFIG = """
[domain]
n_rovers = 3
n_req = 1
steps = 12
scenario = {{ kind = "uniform", half_size = 5.0 }}  # random teams score apart
[learn]
method = "D"
population = 6
hidden = 4
eval_episodes = 2
eval_team = "best-team"
{learn}
"""


def test_pick_takes_the_highest_G_elites_first_on_ties():
    genomes = np.arange(2 * 3 * 1, dtype=float).reshape(2, 3, 1)  # R = 2, k = 3, P = 1
    team_index = np.array([[0, 2], [1, 1], [2, 0]])  # three training teams
    elites = np.full((1, 2, 1), -1.0)
    best = BestTeam()
    # training G 1, 5, 2, then the elite's 3: the second training team, policies 1 and 1
    best.pick(np.array([1.0, 5.0, 2.0, 3.0]), 3, 1, genomes, team_index, elites)
    assert best.genomes[:, 0].tolist() == [1.0, 4.0]  # rover 0's policy 1, rover 1's policy 1
    best.pick(np.array([1.0, 5.0, 2.0, 5.0]), 3, 1, genomes, team_index, elites)
    assert best.genomes[:, 0].tolist() == [-1.0, -1.0]  # a tie: the elite team, as the lab's max
    best.pick(np.array([7.0, 5.0, 7.0]), 3, 0, genomes, team_index, None)
    assert best.genomes[:, 0].tolist() == [0.0, 5.0]  # the first of equal training teams
    assert BestTeam().state() == {}


def _recording(ccea):
    """Each rollout's (E, R, P) genomes and G, as the CCEA plays them."""
    played = []
    prepare, rollout = ccea.layout.prepare, ccea.rollout

    def record_prepare(genomes):
        played.append([np.array(genomes)])
        return prepare(genomes)

    def record_rollout(index):
        G, credit = rollout(index)
        played[-1].append(G.copy())
        return G, credit

    ccea.layout.prepare, ccea.rollout = record_prepare, record_rollout
    return played


@pytest.mark.parametrize("learn", ["", 'selection = "elites"\nn_individual_elites = 2\n'
                                        "n_team_elites = 2"])  # fmt: skip
def test_each_generation_evaluates_the_previous_generations_best_team(learn):
    ccea = CCEA(RunConfig.from_toml(CONFIG.format(learn=learn)))
    played = _recording(ccea)
    curve = [ccea.run_generation().eval_G for _ in range(4)]
    n_played = ccea.n_played
    for before, after in zip(played, played[1:], strict=False):
        genomes, G = before
        assert np.ptp(G[:n_played]) > 0  # one best team, not the first of equals
        best = int(np.argmax(np.concatenate([G[ccea.n_train : n_played], G[: ccea.n_train]])))
        row = ccea.n_train + best if best < ccea.n_elite_teams else best - ccea.n_elite_teams
        evaluated = after[0][n_played:]  # (eval_episodes, R, P)
        assert (evaluated == genomes[row]).all()
    # the curve is those episodes' G
    assert curve[1:] == [float(G[n_played:].mean()) for _, G in played[1:]]
    # the checkpoint's champion is the team the next generation evaluates
    assert (ccea.champion_genomes() == ccea.best_team.genomes).all()


def test_generation_one_evaluates_the_untrained_champion():
    ccea = CCEA(RunConfig.from_toml(CONFIG.format(learn="")))
    played = _recording(ccea)
    untrained = ccea.genomes[np.arange(3), 0].copy()  # policy 0 of each population
    ccea.run_generation()
    assert (played[0][0][ccea.n_played :] == untrained).all()
    assert ccea.best_team.genomes is not None


def test_a_resumed_run_continues_bit_identically():
    config = RunConfig.from_toml(CONFIG.format(learn=""))
    whole = CCEA(config)
    curve = [whole.run_generation().eval_G for _ in range(5)]
    first = CCEA(config)
    for _ in range(2):
        first.run_generation()
    arrays, meta = first.state()
    assert "best_team" in arrays
    resumed = CCEA(config)
    resumed.load_state({k: np.array(v) for k, v in arrays.items()}, meta)
    assert curve[2:] == [resumed.run_generation().eval_G for _ in range(3)]
    assert (resumed.genomes == whole.genomes).all()


def test_the_champion_is_the_default_and_bad_values_are_one_line():
    assert LearnConfig().eval_team == "champion"
    with pytest.raises(ConfigError, match="eval_team: must be one of champion, best-team"):
        LearnConfig(eval_team="best")


def test_import_lab_asks_for_the_labs_test_team():
    lab = yaml.safe_load(EXAMPLE.read_text())
    assert lab_run(lab)[0].learn.eval_team == "best-team"  # the lab's default
    lab["ccea"]["evaluation"]["test_adhoc_team_switch"] = True
    run, notes = lab_run(lab)
    assert run.learn.eval_team == "champion"
    assert not any("learning curve" in note for note in notes)
