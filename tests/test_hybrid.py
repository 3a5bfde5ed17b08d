"""The MERL-style hybrid ([hybrid], physrover.learn.hybrid): the migrant is the learner's
actor, it lands in a slot selection did not keep and nowhere else, only in migration
generations, and a run with it resumes bit for bit."""

import csv
import json

import numpy as np
import pytest

from physrover.config import ConfigError, RunConfig
from physrover.experiment.training import train
from physrover.learn.ccea import CCEA

SMALL = """
[domain]
n_rovers = 4
poi_values = [1.0, 2.0]
n_req = 1
steps = 12
[learn]
method = "D"
population = 8
eval_episodes = 2
generations = 4
seed = {seed}
[hybrid]
episodes = 3
mutate = {mutate}
"""


def small(seed: int = 0, mutate: bool = False, **overrides) -> RunConfig:
    config = RunConfig.from_toml(SMALL.format(seed=seed, mutate=str(mutate).lower()))
    return config.with_overrides(overrides) if overrides else config


def without_hybrid(config: RunConfig) -> RunConfig:
    return RunConfig(config.domain, config.learn, config.settings, None)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_migrant_is_the_learners_actor_in_one_overwritten_slot(seed):
    config = small(seed)
    hybrid, plain = CCEA(config), CCEA(without_hybrid(config))
    hybrid.run_generation()
    plain.run_generation()
    rows = np.arange(config.domain.n_rovers)
    slots = hybrid.hybrid.slots
    learner = hybrid.hybrid.learner
    # mutate = false: the genome is the learner's actor, bit for bit
    np.testing.assert_array_equal(hybrid.genomes[rows, slots], learner.policy_genomes())
    # the hybrid draws from its own stream: every other slot is the plain run's, and the
    # migrant's slot is one the plain run's tournament overwrote (NaN carried: a loser)
    differs = (hybrid.genomes != plain.genomes).any(axis=-1)
    expected = np.zeros_like(differs)
    expected[rows, slots] = True
    np.testing.assert_array_equal(differs, expected)
    assert np.isnan(plain.carried[rows, slots]).all()
    assert plain.champion.tolist() == hybrid.champion.tolist()
    # the genome plays the learner's deterministic actions (torch vs the compiled forward)
    obs = np.random.default_rng(seed).uniform(0, 3, (5, config.domain.n_rovers, 8))
    policy = hybrid.layout.prepare(
        np.broadcast_to(hybrid.genomes[rows, slots], (5, *slots.shape, hybrid.genomes.shape[-1]))
    )
    np.testing.assert_allclose(policy(obs.astype(np.float32)), learner.act(obs), atol=2e-6)


def test_mutated_migrant_differs_from_the_actor_in_few_weights():
    config = small(0, mutate=True, mutation_rate=0.05)
    ccea = CCEA(config)
    ccea.run_generation()
    rows = np.arange(config.domain.n_rovers)
    migrant = ccea.genomes[rows, ccea.hybrid.slots]
    actor = ccea.hybrid.learner.policy_genomes()
    changed = (migrant != actor).mean()
    assert 0.0 < changed < 0.2  # about mutation_rate of the weights


def test_slots_are_drawn_at_random_among_the_losers():
    config = small(3)
    ccea = CCEA(config)
    seen = set()
    for _ in range(4):
        ccea.run_generation()
        seen.update(ccea.hybrid.slots.tolist())
    assert len(seen) >= 3  # not one fixed slot (the worst, the last)


def test_elites_selection_never_overwrites_an_elite():
    config = small(0, selection="elites", n_individual_elites=3, n_team_elites=0,
                   mutation="gauss", mutation_rate=0.5, mutation_scale=0.1)  # fmt: skip
    ccea = CCEA(config)
    for _ in range(4):
        ccea.run_generation()
        assert (ccea.hybrid.slots >= 3).all()


def test_period_trains_and_migrates_only_every_period_th_generation():
    ccea = CCEA(small(0, **{"hybrid.period": 3, "hybrid.iterations": 2}))
    learner_G = [ccea.run_generation().learner_G for _ in range(6)]
    assert np.isnan(learner_G[0]) and np.isnan(learner_G[1]) and np.isnan(learner_G[3])
    assert not np.isnan(learner_G[2]) and not np.isnan(learner_G[5])
    assert ccea.hybrid.learner.iterations == 4  # 2 migrations x 2 iterations


def test_run_resumes_bit_identically(tmp_path):
    config = small(1, mutate=True, **{"hybrid.together": True})  # resumes a fresh migration
    whole = train(config, tmp_path / "whole", progress=False)
    part = train(config, tmp_path / "part", generations=2, progress=False)
    train(None, part, resume=True, generations=4, progress=False)
    read = [list(csv.DictReader(open(run / "metrics.csv"))) for run in (whole, part)]
    assert "learner_G" in read[0][0]
    drop = {"wall_seconds"}
    assert [{k: v for k, v in r.items() if k not in drop} for r in read[0]] == [
        {k: v for k, v in r.items() if k not in drop} for r in read[1]
    ]
    a, b = (np.load(run / "state.npz") for run in (whole, part))
    assert sorted(a.files) == sorted(b.files)
    assert any(name.startswith("hybrid/module/") for name in a.files)
    for name in a.files:
        if name != "__meta__":  # its wall_seconds differ; everything else is below
            np.testing.assert_array_equal(a[name], b[name], err_msg=name)
    meta = [json.loads(bytes(m["__meta__"])) for m in (a, b)]
    for m in meta:
        m.pop("wall_seconds")
        m["hybrid"]["learner"].pop("wall_seconds")
    assert meta[0] == meta[1]


def test_without_hybrid_no_learner_column():
    from physrover.learn.stats import stats_header

    assert "learner_G" not in stats_header()
    assert stats_header(hybrid=True)[-1] == "learner_G"


@pytest.mark.parametrize(
    "toml, field",
    [
        ("[hybrid]\nperiod = 0", "hybrid.period"),
        ('[hybrid]\nlearner = "td3"', "hybrid.learner"),
        ("[hybrid]\nperod = 2", "hybrid.perod"),
        ('[hybrid]\nreward = "nearness"', "hybrid.reward"),
        ('[learn]\nmethod = "mappo"\n[hybrid]', "hybrid"),
        ('[learn]\nactivation = "tanh"\n[hybrid]', "hybrid"),
        ('[[agents]]\nname = "rover"\ncount = 15\n[hybrid]', "hybrid"),
    ],
)
def test_bad_tables_are_one_line_errors(toml, field):
    with pytest.raises(ConfigError) as info:
        RunConfig.from_toml(toml)
    assert info.value.field == field
    assert "\n" not in str(info.value)


def test_table_round_trips_and_overrides():
    config = RunConfig.from_toml("[hybrid]\nperiod = 4\nmutate = false")
    assert RunConfig.from_toml(config.to_toml()) == config
    assert config.with_overrides({"hybrid.episodes": 7}).hybrid.episodes == 7
    assert RunConfig().with_overrides({"hybrid.period": 2}).hybrid.period == 2
    assert RunConfig().hybrid is None
    # hybrid = "mappo" | "none": a sweep's variants and comparisons switch the table
    assert (
        RunConfig().with_overrides({"hybrid": "mappo"}).hybrid
        == RunConfig.from_toml("[hybrid]").hybrid
    )
    assert config.with_overrides({"hybrid": "none"}).hybrid is None
    with pytest.raises(ConfigError, match="hybrid"):
        config.with_overrides({"hybrid": "none", "hybrid.period": 2})


def test_results_tell_hybrid_runs_apart():
    from physrover.analysis.curve_data import run_fields

    plain, hybrid = RunConfig(), RunConfig.from_toml("[hybrid]\nperiod = 5")
    assert run_fields(plain)["hybrid"] == "none" and "hybrid.period" not in run_fields(plain)
    assert run_fields(hybrid)["hybrid"] == "mappo" and run_fields(hybrid)["hybrid.period"] == 5


def test_together_puts_the_migrants_in_one_team_of_the_next_generation():
    ccea = CCEA(small(2, **{"hybrid.together": True, "hybrid.period": 2}))
    played = []
    rollout = ccea.rollout
    ccea.rollout = lambda index: played.append(index.copy()) or rollout(index)
    for _ in range(4):
        ccea.run_generation()
    k = ccea.k
    for index in played:
        teams = index[:k]  # the training teams of round 0, (k, R)
        assert (np.sort(teams, axis=0) == np.arange(k)[:, None]).all()  # still permutations
    # generation 3 teamed up generation 2's migrants: re-run to read them
    again = CCEA(small(2, **{"hybrid.together": True, "hybrid.period": 2}))
    again.run_generation()
    again.run_generation()
    np.testing.assert_array_equal(played[2][0], again.hybrid.slots)


def test_team_up_swaps_each_migrant_into_team_zero():
    config = small(0, **{"hybrid.together": True})
    ccea = CCEA(config)
    ccea.hybrid.slots = np.array([3, 0, 7, 5])
    order = np.argsort(np.random.default_rng(0).random((2, 4, 8)), axis=-1)
    before = order.copy()
    ccea.hybrid.team_up(order, 0)  # no generation run yet: nothing migrated
    np.testing.assert_array_equal(order, before)
    ccea.hybrid.team_up(order, 1)  # generation 1 migrated (period 1)
    np.testing.assert_array_equal(order[0, :, 0], [3, 0, 7, 5])
    np.testing.assert_array_equal(np.sort(order, axis=-1), np.sort(before, axis=-1))
    np.testing.assert_array_equal(order[1], before[1])  # other rounds untouched
    assert ((order != before).sum(axis=-1)[0] <= 2).all()  # one swap per rover
