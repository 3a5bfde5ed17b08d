"""The coupling curriculum (issue 46): the rescoring at another coupling against plain loops
and against the same episodes played at that coupling, the tightening rule worked by hand,
the world's coupling switch, config errors, and a curriculum run that resumes bit for bit;
the same for a gradient-based trainer (MAPPO), its every iteration against plain loops."""

import numpy as np
import pytest
from conftest import assert_same_run, checkpoint_meta, play_alike
from test_learning import EASY

from physrover.config import ConfigError, DomainConfig, RunConfig
from physrover.core.registry import TRAINERS
from physrover.domain.scoring.rules import PoiRules
from physrover.domain.world import RoverWorld
from physrover.experiment.store import read_metrics
from physrover.experiment.training import train
from physrover.learn.ccea import CCEA
from physrover.learn.curriculum import CouplingCurriculum, score_at_coupling

# Six rovers spawned among four POIs: random commands capture at every coupling 1-4.
CROWDED = {"n_rovers": 6, "scenario": {"kind": "uniform", "half_size": 4.0,
                                       "min_separation": 1.0}}  # fmt: skip


def _loop_G(in_range, values, n_req, last_step):
    """Eqs. 11-12 at coupling ``n_req`` (K,), one step, team and POI at a time."""
    n_steps, n_teams, n_agents, n_pois = in_range.shape
    out = np.zeros(n_teams)
    for e in range(n_teams):
        for k in range(n_pois):
            for t in range(last_step + 1):
                if sum(bool(in_range[t, e, i, k]) for i in range(n_agents)) >= n_req[k]:
                    out[e] += values[e, k]
                    break
    return out


def _rules(world):
    """The POI rules a world's captures are replayed under (the paper's POIs: none built)."""
    return world.plan.step.rules or PoiRules.build(world.config, world.n_teams, always=True)


def _crowded_world(n_req, n_teams=8, **fields):
    return RoverWorld(DomainConfig().replace(**CROWDED, n_req=n_req, **fields), n_teams)


@pytest.mark.parametrize("seed", range(4))
def test_rescoring_is_the_episode_played_at_that_coupling(seed):
    rng = np.random.default_rng(seed)
    worlds = {n: _crowded_world(n) for n in (1, 2, 3, 4)}
    actions = rng.uniform(-1, 1, (worlds[1].config.steps, 8, 6, 2))
    play_alike(list(worlds.values()), actions)
    loose = worlds[1].state
    seen = set()
    for n, world in worlds.items():
        target = np.full(4, n)
        got = score_at_coupling(loose.in_range, loose.poi_values, target, world.plan.step.t_final,
                                _rules(worlds[1]))  # fmt: skip
        np.testing.assert_array_equal(got, world.G)  # played at n: the same G, bit for bit
        np.testing.assert_array_equal(got, _loop_G(loose.in_range, loose.poi_values, target,
                                                   world.plan.step.t_final))  # fmt: skip
        seen |= {n} if world.G.any() else set()
    assert seen >= {1, 2, 3}  # the case is not all zeros


def test_rescoring_counts_only_the_scored_steps_and_each_poi_once():
    in_range = np.zeros((4, 1, 3, 2), bool)
    in_range[1, 0, :2, 0] = True  # two agents at POI 0 at step 1
    in_range[2, 0, :2, 0] = True  # and again at step 2: counted once
    in_range[3, 0, :, 1] = True  # three at POI 1 at step 3
    values = np.array([[2.0, 5.0]])
    rules = PoiRules.build(DomainConfig(n_rovers=3, poi_values=(2.0, 5.0)), 1, always=True)
    assert score_at_coupling(in_range, values, np.array([2, 3]), 3, rules)[0] == 7.0
    assert score_at_coupling(in_range, values, np.array([2, 3]), 2, rules)[0] == 2.0  # 3: unscored
    assert score_at_coupling(in_range, values, np.array([3, 4]), 3, rules)[0] == 0.0
    assert score_at_coupling(in_range, values, np.array([1, 1]), 0, rules)[0] == 0.0


def test_the_coupling_tightens_after_patience_generations_at_the_threshold():
    curriculum = CouplingCurriculum(np.array([3, 2, 3]), start=1, threshold=0.5, patience=2)
    np.testing.assert_array_equal(curriculum.n_req, [1, 1, 1])
    # total value 10: G >= 5 twice in a row tightens; a miss resets the streak
    steps = [(5.0, False), (4.9, False), (5.0, False), (6.0, True),  # -> 2
             (9.0, False), (9.0, True),  # -> 3
             (10.0, False), (10.0, False)]  # done: stays at the domain's  # fmt: skip
    for G, tightens in steps:
        assert curriculum.observe(G, 10.0) is tightens
    np.testing.assert_array_equal(curriculum.n_req, [3, 2, 3])  # each POI's own at most
    assert curriculum.done
    state = curriculum.state()
    again = CouplingCurriculum(np.array([3, 2, 3]), start=1, threshold=0.5, patience=2)
    again.load(state)
    assert (again.coupling, again.streak) == (curriculum.coupling, curriculum.streak)


def test_a_world_switched_to_a_coupling_plays_as_one_built_with_it():
    rng = np.random.default_rng(7)
    built, switched = _crowded_world(2), _crowded_world(4)
    switched.set_coupling(2)
    actions = rng.uniform(-1, 1, (built.config.steps, 8, 6, 2))
    play_alike([built, switched], actions)
    np.testing.assert_array_equal(switched.G, built.G)
    np.testing.assert_array_equal(switched.D, built.D)
    assert built.G.any()


def test_the_coupling_does_not_change_mid_episode_or_to_nonsense():
    world = _crowded_world(3, n_teams=1)
    world.reset([np.random.default_rng(0)])
    world.step(np.zeros((1, 6, 2)))
    with pytest.raises(RuntimeError, match="between episodes, not at step 1"):
        world.set_coupling(2)
    with pytest.raises(ValueError, match=r"ints in 1 \.\. 6"):
        _crowded_world(3).set_coupling(7)
    with pytest.raises(ValueError, match=r"ints in 1 \.\. 6"):
        _crowded_world(3).set_coupling(2.5)


@pytest.mark.parametrize(
    ("fields", "message"),
    [
        ({"curriculum_start": 4, "n_req": 4}, "must be below the domain's coupling (n_req 4)"),
        ({"curriculum_start": -1}, "curriculum_start: must be >= 0 (0: off)"),
        ({"curriculum_patience": 3}, "configures the coupling curriculum: set curriculum_start"),
        ({"curriculum_start": 1, "curriculum_threshold": 0.0}, "must be in (0, 1]"),
    ],
)
def test_curriculum_errors_are_one_line(fields, message):
    with pytest.raises(ConfigError) as error:
        RunConfig().with_overrides(fields)
    assert message in str(error.value)
    assert "\n" not in str(error.value)


def test_a_vanishing_poi_is_refused():
    toml = """
[domain]
n_req = 2
[[pois]]
value = 1.0
disappear = "captured"
[[agents]]
name = "rover"
count = 3
sensor = { kind = "lidar" }
[learn]
curriculum_start = 1
"""
    with pytest.raises(ConfigError, match=r"pois\[0\] vanishes once captured"):
        RunConfig.from_toml(toml)


CURRICULUM = {**EASY, "n_req": 3, "method": "D", "curriculum_start": 1,
              "curriculum_threshold": 0.2, "curriculum_patience": 2}  # fmt: skip


def test_a_curriculum_run_trains_loose_evaluates_tight_and_resumes_bit_for_bit(tmp_path):
    config = RunConfig().with_overrides({**CURRICULUM, "checkpoint_every": 4, "seed": 1})
    full = train(config, tmp_path / "full", generations=12, progress=False)
    rows = read_metrics(full / "metrics.csv")
    couplings = [row["train_n_req"] for row in rows]
    assert couplings[0] == 1 and couplings == sorted(couplings) and couplings[-1] > 1
    part = train(config, tmp_path / "part", generations=5, progress=False)
    train(None, part, resume=True, generations=12, progress=False)
    assert_same_run(full, part)
    # the learning curve is at the domain's coupling: a fresh CCEA replaying generation 1
    ccea = CCEA(config)
    first = ccea.run_generation()
    state = ccea.env.world.state
    evaluated = slice(ccea.n_played, None)
    tight = _loop_G(state.in_range[:, evaluated], state.poi_values[evaluated], np.full(4, 3),
                    ccea.env.world.plan.step.t_final)  # fmt: skip
    assert first.eval_G == tight.mean()
    assert first.train_n_req == 1


def test_without_a_curriculum_metrics_have_the_paper_columns(tmp_path):
    run = train(RunConfig().with_overrides({**EASY, "method": "D"}), tmp_path / "r",
                generations=2, progress=False)  # fmt: skip
    assert "train_n_req" not in (run / "metrics.csv").read_text().splitlines()[0]


# MAPPO on the crowded layout: its untrained (near still) policy captures at couplings 1-2
TRAINER = {**CROWDED, "n_req": 3, "steps": 20, "method": "mappo", "num_envs": 6,
           "eval_episodes": 5, "init_log_std": 1.0, "curriculum_start": 1,
           "curriculum_threshold": 0.2, "curriculum_patience": 2}  # fmt: skip


@pytest.mark.parametrize("seed", [3, 4, 5])
@pytest.mark.parametrize("method", ["mappo", "maddpg"])
def test_a_trainer_trains_at_the_curriculum_s_coupling_and_tightens_by_its_rule(method, seed):
    """Each iteration against plain loops: the training episodes scored at the training
    coupling, the learning curve at the domain's, and the coupling tightened by a second
    curriculum fed the evaluation episodes' G at the training coupling by hand."""
    fields = {**TRAINER, "seed": seed}
    if method == "maddpg":  # its own table: no init_log_std; updates from iteration 2
        fields.pop("init_log_std")
        fields.update(method="maddpg", warmup_steps=100, batch_size=32, update_every=20)
    config = RunConfig().with_overrides(fields)
    trainer = TRAINERS[method].load()(config.trainer, config.domain)
    trainer.follow_curriculum(CouplingCurriculum.of(config))
    by_hand = CouplingCurriculum.of(config)
    t_final, target, couplings = trainer.env.world.plan.step.t_final, np.full(4, 3), []
    for _ in range(8):
        stats = trainer.iteration()
        assert stats["train_n_req"] == by_hand.coupling
        played = trainer.env.world.state
        G = _loop_G(played.in_range, played.poi_values, by_hand.n_req, t_final)
        assert stats["train_G_mean"] == G.mean()
        evaluated = trainer.eval_env.world.state
        G = _loop_G(evaluated.in_range, evaluated.poi_values, target, t_final)
        assert stats["eval_G"] == G.mean()
        G = _loop_G(evaluated.in_range, evaluated.poi_values, by_hand.n_req, t_final)
        by_hand.observe(G.mean(), evaluated.poi_values.sum(axis=1).mean())
        assert trainer.curriculum.coupling == by_hand.coupling
        couplings.append(by_hand.coupling)
    assert couplings[0] == 1 and couplings[-1] > 1  # it did tighten


def test_a_trainer_s_curriculum_run_resumes_bit_for_bit(tmp_path):
    """The curriculum's coupling and streak are in the checkpoint: a run split after a
    tightening and in the middle of a streak resumes as the unbroken run (a resume at
    coupling 1, or with the streak lost, tightens later)."""
    config = RunConfig().with_overrides({**TRAINER, "total_episodes": 60, "checkpoint_every": 4})
    full = train(config, tmp_path / "full", progress=False)
    couplings = [row["train_n_req"] for row in read_metrics(full / "metrics.csv")]
    assert couplings == [1, 1, 2, 2, 3, 3, 3, 3, 3, 3]
    part = train(config, tmp_path / "part", iterations=3, progress=False)
    assert checkpoint_meta(part)["curriculum"] == {"coupling": 2, "streak": 1}
    train(None, part, resume=True, iterations=10, progress=False)
    assert_same_run(full, part)


def test_the_sweep_estimate_times_a_trainer_at_its_curriculum_s_coupling(monkeypatch):
    """`physrover bench paper` times a trainer's iteration as its run trains it: under the
    curriculum, at the curriculum's first coupling (build_trainer, shared with the run)."""
    from physrover.experiment import bench

    timed = []
    monkeypatch.setattr(bench, "median_seconds", lambda step, *_: timed.append(step.__self__))
    bench.time_iteration(RunConfig().with_overrides(TRAINER))
    (trainer,) = timed
    assert trainer.curriculum.coupling == 1
    np.testing.assert_array_equal(trainer.env.world.plan.step.n_req, [1, 1, 1, 1])
    np.testing.assert_array_equal(trainer.eval_env.world.plan.step.n_req, [3, 3, 3, 3])
