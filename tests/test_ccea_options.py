"""The CCEA options of the lab's later code (issue 33): softmax team formation, the n-elites
tournament with team elites, Gaussian mutation. Each against a plain-loop oracle or exact
probabilities; the paper's defaults are guarded by test_paper_unchanged.py."""

import itertools
import math
import re
from pathlib import Path

import numpy as np
import oracles
import pytest
from conftest import assert_same_run
from test_learning import EASY

from physrover.config import ConfigError, RunConfig
from physrover.experiment.training import train
from physrover.learn.ccea import CCEA
from physrover.learn.evolution import evolve, evolve_elites
from physrover.learn.team_elites import TeamElites
from physrover.learn.teams import rank_teams, softmax_teams, team_genomes

FITNESS = [0.0, 1.0, 2.5, 0.5]


CHI2_23_P001 = 49.73  # the chi-square quantile at 1 - 0.001 with 23 degrees of freedom


def _chi_square(orders, fitness, temperature):
    """Pearson's statistic of permutation counts against the exact Plackett-Luce law (23
    degrees of freedom for 4 policies)."""
    perms = list(itertools.permutations(range(len(fitness))))
    index = {p: i for i, p in enumerate(perms)}
    counts = np.zeros(len(perms))
    for order in orders:
        counts[index[tuple(int(x) for x in order)]] += 1
    expected = np.array([
        oracles.plackett_luce_probability(p, fitness, temperature) for p in perms
    ]) * len(orders)  # fmt: skip
    assert math.isclose(expected.sum(), len(orders))
    return float(((counts - expected) ** 2 / expected).sum())


@pytest.mark.parametrize("temperature", [1.0, 0.5])
def test_softmax_teams_follow_the_labs_sequential_softmax(temperature):
    # 20000 orders of one population of 4: the Gumbel sort has the law of the lab's draws
    # without replacement (24 permutations, chi-square against the exact probabilities).
    rng = np.random.default_rng(0)
    orders = softmax_teams(rng, np.array([FITNESS]), 20000, temperature)[:, 0]
    assert _chi_square(orders, FITNESS, temperature) < CHI2_23_P001
    # ...and so does the lab's own recursion (the oracle is right about the law), while the
    # reverse order (smallest first) is rejected: the test can fail.
    lab = [oracles.lab_softmax_order(np.array(FITNESS) / temperature, rng) for _ in range(20000)]
    assert _chi_square(lab, FITNESS, temperature) < CHI2_23_P001
    assert _chi_square(orders[:, ::-1], FITNESS, temperature) > 10 * CHI2_23_P001


def test_softmax_teams_are_permutations_and_nan_counts_as_zero():
    rng = np.random.default_rng(1)
    fitness = rng.normal(size=(5, 9))
    fitness[2] = np.nan
    order = softmax_teams(rng, fitness, 3)
    assert order.shape == (3, 5, 9)
    assert (np.sort(order, -1) == np.arange(9)).all()
    # a population of NaN is a population of zeros: the same draw
    a = softmax_teams(np.random.default_rng(2), np.full((1, 4), np.nan), 1)
    b = softmax_teams(np.random.default_rng(2), np.zeros((1, 4)), 1)
    assert (a == b).all()
    # a much fitter policy plays in team 0 nearly always, at temperature 1
    first = softmax_teams(rng, np.array([[0.0, 0.0, 20.0]]), 200)[:, 0, 0]
    assert (first == 2).all()


def _pool(rng, n_pop=3, n=12, P=7):
    pool = rng.normal(size=(n_pop, n, P)).astype(np.float32)
    fitness = rng.integers(0, 5, size=(n_pop, n)).astype(float)  # ties on purpose
    fitness[0, 3] = np.nan
    return pool, fitness


@pytest.mark.parametrize("noise", ["gauss", "cauchy"])
@pytest.mark.parametrize("by_team", [0, 2])
def test_evolve_elites_matches_the_plain_loop_oracle(noise, by_team):
    rng = np.random.default_rng(3)
    pool, fitness = _pool(rng)
    team_G = rng.integers(0, 5, fitness.shape).astype(float)  # ties on purpose
    team_G[0, 1] = np.nan
    k, n_elites, rate, scale = 10, 3, 0.5, 0.1
    got, carried = evolve_elites(pool, fitness, k, n_elites, np.random.default_rng(4), rate,
                                 scale, noise, team_G, by_team)  # fmt: skip
    draws = np.random.default_rng(4)  # the same draws, in evolve_elites' order
    n_pop, n, P = pool.shape
    n_tour = k - n_elites - by_team
    a = draws.integers(n, size=(n_pop, n_tour))
    b = draws.integers(n - 1, size=(n_pop, n_tour))
    b += b >= a
    coin = draws.random(a.shape)
    hit = draws.random((n_pop, n_tour, P)) < rate
    n_hit = int(hit.sum())
    draw = draws.standard_cauchy if noise == "cauchy" else draws.standard_normal
    noise_draws = draw(n_hit)
    want, want_carried = oracles.evolve_elites_loops(pool, fitness, k, n_elites, a, b, coin,
                                                     hit, noise_draws, scale, team_G,
                                                     by_team)  # fmt: skip
    np.testing.assert_array_equal(got, want)
    np.testing.assert_array_equal(carried, want_carried)
    assert (a != b).all()


def test_elites_are_the_best_unmutated_and_the_champion_comes_first():
    rng = np.random.default_rng(5)
    pool, fitness = _pool(rng)
    fitness[1] = np.arange(12.0)  # population 1: member 11 is the best, then 10, 9
    got, carried = evolve_elites(pool, fitness, 10, 3, rng, 1.0, 0.1)
    np.testing.assert_array_equal(got[1, :3], pool[1, [11, 10, 9]])
    assert list(carried[1, :3]) == [11.0, 10.0, 9.0]
    assert np.isnan(carried[:, 3:]).all()
    # rate 1: every offspring weight differs from every pool member's
    assert not (got[:, 3:, None, :] == pool[:, None, :, :]).any()
    # NaN is worst: population 0's member 3 is never an elite
    assert not (got[0, :3] == pool[0, 3]).all(-1).any()


def test_gaussian_mutation_has_the_rate_and_the_scale():
    rng = np.random.default_rng(6)
    genomes = np.zeros((20, 50, 300), dtype=np.float32)
    fitness = rng.normal(size=(20, 50))
    _, losers = evolve(genomes, fitness, rng, 0.5, 0.1, "gauss")
    changed = genomes[np.arange(20)[:, None], losers]
    assert abs((changed != 0).mean() - 0.5) < 0.01
    assert abs(changed[changed != 0].std() - 0.1) < 0.002
    assert abs(np.median(np.abs(changed[changed != 0])) - 0.0674) < 0.002  # normal, not Cauchy


def test_team_elites_keep_the_best_teams_as_the_oracle():
    rng = np.random.default_rng(7)
    n_pop, k, P, n = 4, 6, 5, 3
    population = rng.normal(size=(n_pop, k, P)).astype(np.float32)
    elites = TeamElites(n, population, rng)
    assert np.isnan(elites.fitness).all()
    assert all(
        any((elites.genomes[j, r] == population[r, p]).all() for p in range(k))
        for j in range(n)
        for r in range(n_pop)
    )  # generation 1: random picks of the populations
    elites.fitness = rng.normal(size=(n, n_pop))
    for _ in range(5):
        team_index = np.argsort(rng.random((n_pop, k)), 1).T  # (k, R)
        team_G = rng.integers(0, 4, size=k).astype(float)  # ties between teams
        elite_G = rng.integers(0, 4, size=n).astype(float)
        fitness = rng.normal(size=(n_pop, k))
        want = oracles.select_team_elites_loops(
            elites.genomes,
            elites.fitness,
            elite_G,
            population,
            team_index,
            team_G,
            fitness,
            elites.team_G,
        )
        elites.select(elite_G, population, team_index, team_G, fitness)
        np.testing.assert_array_equal(elites.genomes, want[0])
        np.testing.assert_array_equal(elites.fitness, want[1])
        np.testing.assert_array_equal(elites.team_G, want[2])  # stale: when it became one


def test_ccea_replays_elite_teams_and_never_loses_the_best():
    # Start states never redrawn and idealised motion: a team's G is the same every time it
    # plays, so the best elite team's G never falls, and it is at least the best training
    # team's G of the generation before.
    config = RunConfig().with_overrides({
        **EASY, "method": "D", "selection": "elites", "n_individual_elites": 4,
        "n_team_elites": 3, "team_formation": "softmax", "mutation": "gauss",
        "mutation_rate": 0.5, "mutation_scale": 0.3, "redraw": "never", "seed": 2,
    })  # fmt: skip
    ccea = CCEA(config)
    seen = []
    rollout = ccea.rollout

    def spy(index):
        G, credit = rollout(index)
        seen.append(G)
        return G, credit

    ccea.rollout = spy
    for _ in range(25):
        ccea.run_generation()
    n, k = ccea.n_elite_teams, ccea.k
    assert len(seen[0]) == k + n + config.learn.eval_episodes
    best_elite = [G[k : k + n].max() for G in seen]
    best_train = [G[:k].max() for G in seen]
    assert all(b >= a for a, b in zip(best_elite, best_elite[1:], strict=False))
    assert all(e >= t for t, e in zip(best_train, best_elite[1:], strict=False))
    assert best_elite[-1] > 0  # it found a scoring team
    assert (ccea.champion == 0).all()


@pytest.mark.parametrize("lab", [{}, {"n_team_fitness_elites": 2, "team_formation": "rank"}])
def test_resume_with_softmax_and_elites_is_bit_identical(tmp_path, lab):
    config = RunConfig().with_overrides({
        **EASY, "method": "max-critic", "selection": "elites", "n_individual_elites": 3,
        "n_team_elites": 2, "team_formation": "softmax", "softmax_temperature": 0.5,
        "mutation": "gauss", "checkpoint_every": 3, "seed": 4,
    })  # fmt: skip
    if lab:
        config = config.with_overrides({**lab, "softmax_temperature": 1.0})
    full = train(config, tmp_path / "full", generations=7, progress=False)
    part = train(config, tmp_path / "part", generations=4, progress=False)
    train(None, part, resume=True, generations=7, progress=False)
    assert_same_run(full, part)


def test_team_genomes_gather_as_the_plain_loop_and_reuse_their_array():
    rng = np.random.default_rng(3)
    n_rovers, k, size, n_teams = 4, 6, 5, 9
    table = rng.standard_normal((n_rovers, k, size)).astype(np.float32)
    index = rng.integers(0, k, (n_teams, n_rovers))
    expected = np.empty((n_teams, n_rovers, size), np.float32)
    for e in range(n_teams):
        for r in range(n_rovers):
            expected[e, r] = table[r, index[e, r]]
    out = team_genomes(table, index)
    np.testing.assert_array_equal(out, expected)
    again = team_genomes(table[:, ::-1], index, out)  # a strided table, the same array back
    assert again is out
    np.testing.assert_array_equal(again, table[:, ::-1][np.arange(n_rovers), index])
    assert team_genomes(table, index[:3], out).shape == (3, n_rovers, size)  # new shape, new
    for bad in (index + k, index - k, index[:, :3]):
        with pytest.raises(IndexError, match="out of range"):
            team_genomes(table, bad)


def test_rank_teams_zip_each_population_sorted_as_the_lab_does():
    """The lab's ``form_shaped_teams``, written as it is: each population sorted by shaped
    fitness (None as 0), largest first, and zipped into teams."""
    rng = np.random.default_rng(0)
    fitness = rng.integers(0, 4, (3, 6)).astype(float)  # ties on purpose
    fitness[1, 2] = np.nan  # a mutated copy, not yet scored
    order = rank_teams(fitness, rounds=2)
    assert order.shape == (2, 3, 6) and (order[0] == order[1]).all()
    pops = [[(p, None if np.isnan(f) else f) for p, f in enumerate(row)] for row in fitness]
    sorted_pops = [sorted(pop, key=lambda ind: ind[1] if ind[1] is not None else 0,
                          reverse=True) for pop in pops]  # fmt: skip
    teams = [[pop[i][0] for pop in sorted_pops] for i in range(6)]
    assert order[0].T.tolist() == teams  # order[q, r, m]: rover r's policy in team m
    ccea = CCEA(RunConfig().with_overrides({**EASY, "method": "D", "team_formation": "rank"}))
    ccea.run_generation()
    played, rollout = [], ccea.rollout
    ccea.rollout = lambda index: played.append(index.copy()) or rollout(index)
    expected = rank_teams(ccea.carried, 1)[0].T  # (team, rover): by last generation's fitness
    assert not np.isnan(ccea.carried).all() and len(set(expected[:, 0])) > 1
    ccea.run_generation()
    np.testing.assert_array_equal(played[0][: ccea.k], expected)


ELITES = {"selection": "elites"}
SOFTMAX = {"team_formation": "softmax"}


@pytest.mark.parametrize(
    ("fields", "message"),
    [
        ({"team_formation": "greedy"}, "team_formation: must be one of random, softmax, rank"),
        ({"team_formation": "rank", "method": "hall-of-fame"}, "rank needs a method with"),
        ({"selection": "elite"}, "selection: must be one of tournament, elites; got 'elite'"),
        ({"mutation": "normal"}, "mutation: must be one of cauchy, gauss"),
        ({"softmax_temperature": 2.0}, 'temperature: configures team_formation = "softmax"'),
        ({**SOFTMAX, "softmax_temperature": 0.0}, "softmax_temperature: must be > 0"),
        ({"n_team_elites": 3}, 'n_team_elites: configures selection = "elites"'),
        ({**ELITES, "n_individual_elites": 50}, "elites: must be in [1, population) = [1, 50)"),
        ({**ELITES, "n_individual_elites": 0}, "n_individual_elites: must be in [1, population)"),
        ({**ELITES, "n_team_elites": -1}, "n_team_elites: must be >= 0"),
        ({**ELITES, "n_team_fitness_elites": 40}, "n_team_fitness_elites: must be >= 0 and"),
        ({"n_team_fitness_elites": 2}, 'n_team_fitness_elites: configures selection = "el'),
        ({**SOFTMAX, "method": "hall-of-fame"}, "'hall-of-fame' plans its own teams"),
    ],
)
def test_option_errors_are_one_line(fields, message):
    with pytest.raises(ConfigError) as error:
        RunConfig().with_overrides(fields)
    assert message in str(error.value)
    assert "\n" not in str(error.value)


def test_the_paper_defaults_are_unchanged():
    learn = RunConfig().learn
    chosen = (learn.team_formation, learn.selection, learn.mutation)
    assert chosen == ("random", "tournament", "cauchy")
    assert CCEA(RunConfig().with_overrides({**EASY, "method": "D"})).team_elites is None


def test_the_documented_lab_configuration_runs():
    page = (Path(__file__).parent.parent / "docs" / "user-guide" / "training.md").read_text()
    block = next(b for b in re.findall(r"^```toml\n(.*?)^```", page, re.S | re.M) if "elites" in b)
    config = RunConfig.from_toml(block)
    learn = config.learn
    assert (learn.team_formation, learn.selection, learn.mutation) == ("softmax", "elites", "gauss")
    assert (learn.n_individual_elites, learn.n_team_elites) == (10, 10)
    assert (learn.mutation_rate, learn.mutation_scale) == (0.5, 0.1)
    ccea = CCEA(config.with_overrides({**EASY, "method": "D"}))
    ccea.run_generation()
    assert ccea.env.num_envs == 20 + 10 + learn.eval_episodes
