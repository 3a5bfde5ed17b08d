"""The learning-algorithm seam takes a researcher's own trainer without touching the package.

A (1+1) hill climber on the team's policy genomes is defined here only, registered with
``register_trainer``, and trained through ``physrover train``: its config table, run
directory, checkpoints, crash-and-resume, ``evaluate`` and ``physrover methods`` are the
package's, and each is checked against what the climber must do.
"""

import dataclasses
import math
from typing import ClassVar

import numpy as np
import pytest
import torch
from conftest import assert_same_run

from physrover.analysis.plots import load_runs
from physrover.cli.main import main
from physrover.config import ConfigError, RunConfig, check
from physrover.experiment.evaluate import evaluate_run
from physrover.experiment.store import read_metrics
from physrover.learn.policies import PolicyLayout
from physrover.marl.common import Trainer, run_episodes
from physrover.marl.configs import MAPPOConfig, MARLConfig, register_trainer


@dataclasses.dataclass(frozen=True)
class HillClimbConfig(MARLConfig):
    section: ClassVar[str] = "test-hill-climb"

    sigma: float = 0.1
    """Standard deviation of the Gaussian step added to every weight."""

    def __post_init__(self) -> None:
        super().__post_init__()
        check(self.sigma > 0, "sigma", f"must be > 0, got {self.sigma}")


class HillClimb(Trainer):
    """(1+1) hill climbing: each iteration perturbs every weight of the incumbent team by
    N(0, sigma^2), plays the candidate on ``num_envs`` training episodes and keeps it when its
    mean G is at least the incumbent's (measured when it was accepted)."""

    def __init__(self, config: HillClimbConfig, domain=None):
        super().__init__(config, domain)
        self.layout = PolicyLayout(config.hidden, self.n_obs)
        seed = int(torch.randint(2**62, (1,), generator=self.init_gen))
        self.genomes = self.layout.init((self.n_rovers,), np.random.default_rng(seed))
        self.best = -math.inf
        self.accepted = 0

    def _policy(self, genomes):
        teams = np.broadcast_to(genomes, (self.config.num_envs, *genomes.shape))
        return self.layout.prepare(teams)

    def _train(self, stats):
        step = torch.randn(self.genomes.shape, generator=self.gen).numpy()
        candidate = (self.genomes + self.config.sigma * step).astype(np.float32)
        policy = self._policy(candidate)
        G = run_episodes(self.env, lambda obs, t: policy(obs)).G
        if G.mean() >= self.best:
            self.genomes, self.best = candidate, float(G.mean())
            self.accepted += 1
        return G

    def act(self, obs):
        teams = np.broadcast_to(self.genomes, (obs.shape[0], *self.genomes.shape))
        return self.layout.prepare(teams)(obs)

    def policy_genomes(self):
        return self.genomes

    def _extra_state(self):
        return {"genomes": self.genomes}, {"best": self.best, "accepted": self.accepted}

    def _load_extra_state(self, arrays, meta):
        self.genomes = arrays["genomes"]
        self.best, self.accepted = float(meta["best"]), int(meta["accepted"])


register_trainer("test-hill-climb", HillClimbConfig, HillClimb, "(1+1) hill climber", "tests")

FIELDS = {"n_rovers": 3, "n_req": 1, "steps": 10, "poi_ring_radius": 5.0, "num_envs": 4,
          "total_episodes": 24, "eval_episodes": 2, "hidden": 4, "checkpoint_every": 2,
          "sigma": 0.5}  # fmt: skip
TINY = ["--method", "test-hill-climb", "--quiet"]
TINY += [arg for name, value in FIELDS.items() for arg in ("--set", f"{name}={value}")]


def test_a_registered_trainer_trains_through_the_run_directory(tmp_path, capsys):
    out = tmp_path / "climb"
    assert main(["train", *TINY, "--out", str(out)]) == 0
    assert "[test-hill-climb]\nnum_envs = 4\ntotal_episodes = 24\n" in (
        (out / "config.toml").read_text()
    )
    config = RunConfig.load(out / "config.toml")
    assert isinstance(config.trainer, HillClimbConfig) and config.trainer.sigma == 0.5
    assert config.trainer.hidden == 4 == config.learn.hidden  # shared with [learn]
    rows = read_metrics(out / "metrics.csv")
    assert [r["generation"] for r in rows] == [1, 2, 3, 4, 5, 6]
    assert [r["episodes"] for r in rows] == [4, 8, 12, 16, 20, 24]
    header = (out / "metrics.csv").read_text().splitlines()[0].split(",")
    assert header[0] == "iteration" and "fitness_mean" not in header  # its own columns
    state = np.load(out / "state.npz")
    champion = np.load(out / "champions" / "gen_000006.npy")
    np.testing.assert_array_equal(champion, state["extra/genomes"])  # what render plays
    assert champion.shape == (3, PolicyLayout(4, 8).size)
    assert len(evaluate_run(out, episodes=3).G) == 3
    assert load_runs([out])[0].episodes.tolist() == [4, 8, 12, 16, 20, 24]  # curves --x episodes
    capsys.readouterr()
    assert main(["methods"]) == 0
    assert "test-hill-climb" in capsys.readouterr().out


def test_the_incumbent_is_the_latest_best_candidate(tmp_path):
    overrides = {**FIELDS, "method": "test-hill-climb", "total_episodes": 40}
    config = RunConfig().with_overrides(overrides)
    climber = HillClimb(config.trainer, config.domain)
    incumbent, best = climber.genomes.copy(), -math.inf
    for _ in range(config.trainer.total_iterations):
        before = climber.gen.get_state()
        G = climber.iteration()["train_G_mean"]
        climber.gen.set_state(before)  # the same step again, worked out here
        step = torch.randn(incumbent.shape, generator=climber.gen).numpy()
        if G >= best:
            incumbent, best = (incumbent + 0.5 * step).astype(np.float32), G
        np.testing.assert_array_equal(climber.genomes, incumbent)
    assert climber.accepted >= 1 and climber.best == pytest.approx(best, rel=1e-6)


def test_a_crashed_run_of_a_registered_trainer_resumes_bit_identically(tmp_path, monkeypatch):
    full, crashed = tmp_path / "full", tmp_path / "crashed"
    assert main(["train", *TINY, "--out", str(full)]) == 0
    real = HillClimb.iteration

    def crash_after_3(self):
        if self.iterations == 3:
            raise KeyboardInterrupt
        return real(self)

    monkeypatch.setattr(HillClimb, "iteration", crash_after_3)
    assert main(["train", *TINY, "--out", str(crashed)]) == 130
    monkeypatch.setattr(HillClimb, "iteration", real)
    assert main(["train", "--resume", str(crashed), "--quiet"]) == 0
    assert_same_run(full, crashed)


def test_register_trainer_refuses_what_a_run_could_not_hold():
    @dataclasses.dataclass(frozen=True)
    class Clash(MARLConfig):
        section: ClassVar[str] = "scenario"  # a domain table's name

    with pytest.raises(ValueError, match=r"section \[scenario\] is taken"):
        register_trainer("test-clash", Clash, HillClimb, "")
    with pytest.raises(ValueError, match=r"section \[mappo\] is taken"):
        register_trainer("test-clash", MAPPOConfig, HillClimb, "")
    with pytest.raises(TypeError, match="MARLConfig subclass"):
        register_trainer("test-clash", dict, HillClimb, "")
    with pytest.raises(TypeError, match="module:Class"):
        register_trainer("test-clash", HillClimbConfig, "no_colon", "")
    with pytest.raises(ValueError, match="'D' is a fitness method"):
        register_trainer("D", HillClimbConfig, HillClimb, "")
    with pytest.raises(ValueError, match="already registered"):
        register_trainer("test-hill-climb", HillClimbConfig, HillClimb, "")
    with pytest.raises(ConfigError, match="sigma"):
        RunConfig().with_overrides({"method": "test-hill-climb", "sigma": -1.0})
