"""Cross-evaluation: a run's champion team on fresh episodes, under any motion model.

``evaluate_run`` is what ``physrover evaluate`` calls. It loads the champion team saved at a
checkpoint, plays ``episodes`` episodes at once on the vector env (episode i starts like
``RoverEnv().reset(seed=seed + i)``, so ``physrover render --seed`` shows the same starts) and
returns each episode's G with the mean and its Student-t 95% CI. Any domain field may be
changed for the evaluation (``motion``, ``collisions``, ...); the policies are the run's.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from physrover.config import ConfigError
from physrover.core.stats import mean_ci
from physrover.envs.gymnasium_env import RoverVectorEnv
from physrover.experiment.store import load_champions, load_run_config
from physrover.learn.classes import team_layout

EVAL_SEED = 1_000_000
"""Default seed of the first evaluation episode: far from the seeds training runs use, so the
starts are fresh for any run."""

MOTION_MODELS = {
    "ideal": {"motion": "ideal"},
    "physics": {"motion": "physics", "collisions": False},
    "physics+collisions": {"motion": "physics", "collisions": True},
}
"""The domain changes of the three motion models a champion is cross-evaluated under."""


def motion_model(motion: str, collisions: bool) -> str:
    """The name in :data:`MOTION_MODELS` of a domain's ``motion`` and its physics'
    ``collisions`` (which only matter under physics)."""
    if motion == "ideal":
        return "ideal"
    return "physics+collisions" if collisions else "physics"


@dataclass(frozen=True)
class Evaluation:
    """The champion team of ``run_dir`` after ``generation`` generations, played on
    ``len(G)`` episodes (seeds ``seed``, ``seed + 1``, ...) with the domain ``changes``."""

    run_dir: Path
    generation: int
    changes: dict[str, Any]
    seed: int
    G: np.ndarray
    """(episodes,) the team score of each episode."""

    @property
    def mean(self) -> float:
        return float(self.G.mean())

    @property
    def ci95(self) -> float:
        """Half-width of the Student-t 95% CI of the mean (NaN for one episode)."""
        return float(mean_ci(self.G)[1])

    def line(self) -> str:
        what = ", ".join(f"{k}={v}" for k, v in self.changes.items()) or "its own domain"
        ci = "" if math.isnan(self.ci95) else f" +- {self.ci95:.2f} (95% CI)"
        return (
            f"{self.run_dir} (champion after generation {self.generation}) under {what}: "
            f"mean G {self.mean:.2f}{ci} over {len(self.G)} episode{'s' * (len(self.G) != 1)}"
        )

    def write_csv(self, path: str | Path) -> Path:
        """One row per episode: ``episode, seed, G`` plus the changed fields."""
        path = Path(path)
        with open(path, "w", newline="") as f:
            writer = csv.writer(f)
            writer.writerow(["episode", "seed", "G", *self.changes])
            for i, g in enumerate(self.G):
                writer.writerow([i, self.seed + i, f"{g:g}", *self.changes.values()])
        return path


def evaluate_run(
    run_dir: str | Path,
    *,
    episodes: int = 100,
    seed: int = EVAL_SEED,
    checkpoint: int | None = None,
    **changes: Any,
) -> Evaluation:
    """Play the champion team of ``run_dir`` on ``episodes`` fresh episodes.

    ``changes``: domain fields to set for the evaluation (e.g. ``motion="physics"``,
    ``collisions=False``); None values are ignored. ``checkpoint``: the generation whose
    champion plays (default: the last).
    """
    run_dir = Path(run_dir)
    changes = {k: v for k, v in changes.items() if v is not None}
    generation, env = play_champion(run_dir, episodes, seed, checkpoint, **changes)
    return Evaluation(run_dir, generation, changes, seed, env.world.G)


def play_champion(
    run_dir: Path, episodes: int, seed: int = EVAL_SEED, checkpoint: int | None = None,
    **changes: Any,
) -> tuple[int, RoverVectorEnv]:  # fmt: skip
    """Play the champion of ``run_dir`` (after generation ``checkpoint``, default the last)
    on ``episodes`` fresh episodes (episode i starts like ``RoverEnv().reset(seed=seed +
    i)``) with the domain ``changes``, step by step on the vector env; returns the
    champion's generation and the env, at the episodes' end (its world holds their
    records)."""
    if episodes < 1:
        raise ConfigError("episodes", f"must be >= 1, got {episodes}")
    config = load_run_config(run_dir)
    domain = config.domain.replace(**changes)
    generation, genomes = load_champions(run_dir, checkpoint)
    env = RoverVectorEnv(episodes, config=domain, fresh_teams=episodes)  # each its own start
    act = team_layout(config.learn, domain).prepare(
        np.broadcast_to(genomes, (episodes, *genomes.shape))
    )
    obs, _ = env.reset(seed=seed)
    for _ in range(domain.steps):
        obs, *_ = env.step(act(obs))
    return generation, env
