"""Gradient-based trainers through the run directory: `physrover train --method mappo|maddpg`."""

import pytest
from conftest import assert_same_run

from physrover.analysis.plots import load_runs
from physrover.cli.main import main
from physrover.config import ConfigError, RunConfig
from physrover.experiment.evaluate import evaluate_run
from physrover.experiment.provenance import code_fingerprint, read_provenance
from physrover.experiment.store import read_metrics
from physrover.marl.common import Trainer

TINY = ["--set", "n_rovers=3", "--set", "n_req=1", "--set", "steps=10",
        "--set", "poi_ring_radius=5.0", "--set", "num_envs=4", "--set", "total_episodes=16",
        "--set", "eval_episodes=2", "--set", "checkpoint_every=2", "--quiet"]  # fmt: skip
MADDPG = ["--set", "warmup_steps=40", "--set", "batch_size=32", "--set", "buffer_capacity=200",
          "--set", "update_every=10"]  # fmt: skip


@pytest.mark.parametrize("method", ["mappo", "maddpg"])
def test_train_writes_a_run_directory_the_other_commands_read(method, tmp_path, capsys):
    out = tmp_path / method
    extra = MADDPG if method == "maddpg" else []
    assert main(["train", "--method", method, *TINY, *extra, "--out", str(out)]) == 0
    header = (out / "metrics.csv").read_text().splitlines()[0].split(",")
    losses = {
        "mappo": ["policy_loss", "value_loss", "entropy", "approx_kl", "clip_fraction", "std"],
        "maddpg": ["critic_loss", "actor_loss", "q_mean", "updates"],
    }
    assert header == ["iteration", "eval_G", "train_G_mean", *losses[method], "wall_seconds",
                      "episodes", "env_steps"]  # fmt: skip
    rows = read_metrics(out / "metrics.csv")
    assert [r["iteration"] for r in rows] == [1, 2, 3, 4]
    assert [r["generation"] for r in rows] == [1, 2, 3, 4]  # every reader's position
    assert [r["episodes"] for r in rows] == [4, 8, 12, 16]
    assert [r["env_steps"] for r in rows] == [40, 80, 120, 160]
    assert sorted(p.name for p in (out / "champions").iterdir()) == [
        "gen_000002.npy",
        "gen_000004.npy",
    ]
    config = RunConfig.load(out / "config.toml")
    assert config.learn.method == method and config.trainer.num_envs == 4
    assert config.trainer.seed == config.learn.seed and config.trainer.eval_episodes == 2
    assert load_runs([out])[0].episodes.tolist() == [4, 8, 12, 16]  # curves --x episodes
    assert len(evaluate_run(out, episodes=3).G) == 3  # the policies as CCEA genomes
    (segment,) = read_provenance(out)  # the trainer's run records its code too
    assert segment["from_generation"] == 0 and segment["code"] == code_fingerprint()
    capsys.readouterr()
    assert main(["train", "--resume", str(out)]) == 0
    assert "is already at 4 iterations; to extend it: " in capsys.readouterr().out


@pytest.mark.parametrize("method", ["mappo", "maddpg"])
def test_a_crashed_run_resumes_bit_identically(method, tmp_path, monkeypatch):
    extra = MADDPG if method == "maddpg" else []
    full = tmp_path / "full"
    assert main(["train", "--method", method, *TINY, *extra, "--out", str(full)]) == 0
    real = Trainer.iteration

    def crash_after_3(self):
        if self.iterations == 3:
            raise KeyboardInterrupt
        return real(self)

    crashed = tmp_path / "crashed"
    monkeypatch.setattr(Trainer, "iteration", crash_after_3)
    assert main(["train", "--method", method, *TINY, *extra, "--out", str(crashed)]) == 130
    monkeypatch.setattr(Trainer, "iteration", real)
    assert main(["train", "--resume", str(crashed), "--quiet"]) == 0
    assert_same_run(full, crashed)


def test_trainer_tables_in_the_config():
    config = RunConfig().with_overrides({"method": "mappo", "mappo.lr": 1e-3, "clip": 0.1})
    assert (config.trainer.lr, config.trainer.clip) == (1e-3, 0.1)
    assert RunConfig.from_toml(config.to_toml()) == config
    assert "[mappo]" in config.to_toml() and "\nseed" not in config.to_toml().split("[mappo]")[1]
    # critic_lr is the trainer's own (the CCEA's critics have theirs in [critic])
    maddpg = RunConfig().with_overrides({"method": "maddpg", "critic_lr": 2e-3})
    assert maddpg == RunConfig().with_overrides({"method": "maddpg", "maddpg.critic_lr": 2e-3})
    assert maddpg.trainer.critic_lr == 2e-3 and maddpg.settings is maddpg.trainer
    with pytest.raises(ConfigError, match="critic_lr: unknown LearnConfig field"):
        RunConfig().with_overrides({"method": "maddpg", "learn.critic_lr": 2e-3})
    with pytest.raises(ConfigError, match="set seed in \\[learn\\]"):
        RunConfig.from_toml('[learn]\nmethod = "mappo"\n[mappo]\nseed = 3\n')
    with pytest.raises(ConfigError, match="but method is 'max-critic'"):
        RunConfig.from_toml("[mappo]\nlr = 0.1\n")
    with pytest.raises(ConfigError, match="lr: unknown config field"):
        RunConfig().with_overrides({"lr": 0.1})  # the CCEA has no such field


def test_a_sweep_runs_trainers_and_then_skips_them(tmp_path):
    from physrover.experiment.execute import run_sweep
    from physrover.experiment.sweep import Sweep, run_status

    path = tmp_path / "marl.toml"
    path.write_text(
        '[sweep]\nname = "m"\nseeds = 1\n[base.domain]\nn_rovers = 3\nn_req = 1\nsteps = 10\n'
        "[base.learn]\neval_episodes = 2\ncheckpoint_every = 1\n[grid]\nn_req = [1]\n"
        '[[variants]]\nmethod = "mappo"\ntotal_episodes = 8\nnum_envs = 4\n'
    )
    specs = Sweep.load(path).runs(tmp_path / "sweeps")
    report = run_sweep(specs, workers=1, progress=False)
    assert not report.failed and len(report.finished) == 1
    assert [run_status(s) for s in specs] == ["done"]
    assert run_sweep(specs, workers=1, progress=False).skipped == 1


def test_curves_never_pool_trainer_runs_of_different_hyper_parameters(tmp_path):
    from physrover.analysis.plots import curve_table

    runs = []
    for lr in ("0.001", "0.003"):
        out = tmp_path / f"lr{lr}"
        argv = ["train", "--method", "mappo", *TINY, "--set", f"lr={lr}", "--out", str(out)]
        assert main(argv) == 0
        runs.append(out)
    table = curve_table(load_runs(runs))
    assert sorted(table) == ["mappo mappo.lr=0.001", "mappo mappo.lr=0.003"]


def test_a_run_of_physrover_0_5_resumes_in_its_own_columns(tmp_path, monkeypatch):
    """Trainer runs of 0.4-0.5 wrote the CCEA's columns (generation = iteration,
    critic_loss = the value loss, fitness_mean NaN): they resume in them, to the same
    numbers as a new run's."""
    from physrover.experiment import trainer_runs

    new = tmp_path / "new"
    assert main(["train", "--method", "mappo", *TINY, "--out", str(new)]) == 0
    old = tmp_path / "old"
    real = Trainer.iteration

    def crash_after_2(self):
        if self.iterations == 2:
            raise KeyboardInterrupt
        return real(self)

    legacy = trainer_runs.LEGACY_COLUMNS
    monkeypatch.setattr(trainer_runs, "trainer_columns", lambda *_: legacy)  # 0.5's writer
    monkeypatch.setattr(Trainer, "iteration", crash_after_2)
    assert main(["train", "--method", "mappo", *TINY, "--out", str(old)]) == 130
    monkeypatch.undo()
    assert (old / "metrics.csv").read_text().startswith(",".join(legacy))
    assert main(["train", "--resume", str(old), "--quiet"]) == 0
    assert (old / "metrics.csv").read_text().splitlines()[0] == ",".join(legacy)
    got, want = read_metrics(old / "metrics.csv"), read_metrics(new / "metrics.csv")
    assert [r["generation"] for r in got] == [1, 2, 3, 4]
    for a, b in zip(got, want, strict=True):
        assert (a["eval_G"], a["train_G_mean"], a["episodes"]) == \
            (b["eval_G"], b["train_G_mean"], b["episodes"])  # fmt: skip
        assert a["critic_loss"] == b["value_loss"]
