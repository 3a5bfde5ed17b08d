"""``physrover benchmarl``: a BenchMARL experiment on a physrover task, from Hydra overrides.

It runs what BenchMARL's ``benchmarl/run.py algorithm=... task=...`` runs, with physrover's
tasks registered and a few defaults a first run needs (``algorithm=mappo``,
``task=physrover/rover_domain``, the csv logger only: BenchMARL's default also asks for
wandb), writes into a run folder of physrover's naming, and ends with the evaluation
return (the team's G, Eq. 11) next to a random policy's on the same task.
"""

from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

import numpy as np

from physrover.cli.commands import Interrupted, UsageError, next_free
from physrover.config import DomainConfig
from physrover.core.threads import pin_threads

DEFAULTS = {"algorithm": "mappo", "task": "physrover/rover_domain",
            "experiment.loggers": "[csv]"}  # fmt: skip
INSTALL = (
    "pip install 'physrover[benchmarl]', in a venv of its own with the CPU builds of "
    "torch and torchvision (the docs' page 'TorchRL and BenchMARL' says how)"
)


def with_defaults(overrides: list[str]) -> list[str]:
    """``overrides`` plus each of :data:`DEFAULTS` whose key they do not set."""
    keys = {o.split("=", 1)[0].lstrip("+~") for o in overrides}
    for text in overrides:
        if "=" not in text:
            raise UsageError(f"{text!r}: expected a Hydra override KEY=VALUE, e.g. "
                             "task.n_req=1 or experiment.max_n_iters=20")  # fmt: skip
    return [*overrides, *(f"{k}={v}" for k, v in DEFAULTS.items() if k not in keys)]


def random_return(domain: DomainConfig, episodes: int = 200, seed: int = 0) -> float:
    """Mean G (Eq. 11) of uniformly random actions in [-1, 1] over ``episodes`` teams: the
    floor a trained policy has to beat."""
    from physrover.envs.gymnasium_env import RoverVectorEnv

    env = RoverVectorEnv(episodes, domain)
    env.reset(seed=seed)
    rng, total = np.random.default_rng(seed), np.zeros(episodes)
    for _ in range(domain.steps):
        action = rng.uniform(-1.0, 1.0, env.action_space.shape).astype(np.float32)
        total += env.step(action)[1]
    return float(total.mean())


def scalar_values(folder: Path, metric: str) -> list[float]:
    """The values BenchMARL's csv logger wrote for ``metric`` under ``folder``, in order."""
    files = sorted(folder.rglob(f"scalars/{metric}.csv"))
    if not files:
        return []
    return [float(row[-1]) for row in csv.reader(files[-1].open()) if row]


def last_value(folder: Path, metric: str) -> float | None:
    """The last value BenchMARL's csv logger wrote for ``metric`` (None if none)."""
    values = scalar_values(folder, metric)
    return values[-1] if values else None


def _one_line(exc: BaseException) -> str:
    """Hydra's error in one line: its first line, and its cause's (which names the key)."""
    lines = [str(exc).strip().splitlines()[0]]
    if exc.__cause__ is not None and str(exc.__cause__).strip():
        lines.append(str(exc.__cause__).strip().splitlines()[0])
    return " ".join(lines)


LONG_DEFAULT = (
    "this is BenchMARL's own default experiment (millions of frames: hours on a laptop's "
    "CPU, about 5 h on 2 cores for MAPPO); experiment=physrover_quick runs 20 iterations, "
    "experiment.max_n_iters=N caps it"
)


def runs_default_experiment(overrides: list[str]) -> bool:
    """Whether ``overrides`` leave BenchMARL's default experiment as it is (no
    ``experiment=...`` and no ``experiment.FIELD=...``)."""
    return not any(o.split("=", 1)[0].lstrip("+~").split(".")[0] == "experiment"
                   for o in overrides)  # fmt: skip


def run_experiment(experiment) -> None:
    """``experiment.run()``; Ctrl-C ends it in one line naming its folder (what BenchMARL
    wrote so far stays there), not BenchMARL's and TorchRL's tracebacks."""
    try:
        experiment.run()
    except KeyboardInterrupt:
        raise Interrupted(f"interrupted; what BenchMARL wrote so far is in "
                          f"{experiment.folder_name}") from None  # fmt: skip


def cmd_benchmarl(args: argparse.Namespace) -> int:
    try:
        from hydra.errors import HydraException
        from omegaconf.errors import OmegaConfBaseException

        from physrover.envs import benchmarl_task
    except ImportError as exc:
        raise UsageError(
            f"this command needs BenchMARL ({exc.name} is missing): {INSTALL}"
        ) from None
    pin_threads(args.threads)
    overrides = with_defaults(list(args.overrides))
    out = next_free(Path(args.out))
    try:
        experiment = benchmarl_task.compose_experiment(overrides, save_folder=out)
    except (HydraException, OmegaConfBaseException, ValueError) as exc:
        raise UsageError(_one_line(exc)) from None
    task = experiment.task
    print(f"benchmarl: {experiment.algorithm_name} on {task.env_name()}/{task.name.lower()} "
          f"({experiment.config.get_max_n_iters(experiment.on_policy)} iterations) -> "
          f"{experiment.folder_name}")  # fmt: skip
    if runs_default_experiment(overrides):
        print(f"physrover: note: {LONG_DEFAULT}", file=sys.stderr)
    run_experiment(experiment)
    trained = last_value(Path(experiment.folder_name), "eval_reward_episode_reward_mean")
    floor = random_return(task.domain)
    shown = "no evaluation ran" if trained is None else f"{trained:.3f}"
    print(f"evaluation G (mean episode return): {shown}; random policy: {floor:.3f}")
    return 0
