"""Benchmarks (not tests): wall-clock timings reported as medians of repeated runs.

Run through the CLI, e.g. ``physrover bench world``; pin one thread for comparable numbers
(the CLI sets ``OMP_NUM_THREADS=1`` and ``torch.set_num_threads(1)`` unless told otherwise).
"""

from __future__ import annotations

import dataclasses
import math
import statistics
import time
from dataclasses import dataclass

import numpy as np

from physrover.config import DomainConfig
from physrover.envs.gymnasium_env import RoverVectorEnv


@dataclass(frozen=True)
class Timing:
    name: str
    median_ms: float
    runs_ms: tuple[float, ...]

    def line(self) -> str:
        lo, hi = min(self.runs_ms), max(self.runs_ms)
        return (
            f"{self.name}: median {self.median_ms:.2f} ms "
            f"(min {lo:.2f}, max {hi:.2f}, {len(self.runs_ms)} runs)"
        )


def world_episodes(config: DomainConfig, n_teams: int = 50):
    """``(env, play)``: a vector env of ``n_teams`` teams reset with seed 0, and ``play()``,
    which times one episode of it (reset + ``config.steps`` steps of uniform random actions,
    drawn once beforehand from seed 0) and returns its seconds."""
    env = RoverVectorEnv(n_teams, config=config)
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1, 1, (config.steps, n_teams, config.n_rovers, 2)).astype(np.float32)
    env.reset(seed=0)

    def play() -> float:
        start = time.perf_counter()
        env.reset()
        for a in actions:
            env.step(a)
        return time.perf_counter() - start

    return env, play


def bench_world(config: DomainConfig, n_teams: int = 50, repeats: int = 20) -> Timing:
    """Time reset + ``config.steps`` steps of the vector env with uniform random actions
    (:func:`world_episodes`)."""
    env, play = world_episodes(config, n_teams)
    play()  # warms caches; not counted
    runs = [1000.0 * play() for _ in range(repeats)]
    name = (
        f"world reset + {config.steps} steps, {n_teams} teams x {config.n_rovers} rovers, "
        f"motion={config.motion}"
    )
    if config.motion == "physics":
        stepper = "pymunk" if env.world.dynamics.uses_pymunk else "compiled"
        name += (f" (collisions={config.physics.collisions}, substeps={config.physics.substeps},"
                 f" stepped by {stepper})")  # fmt: skip
    return Timing(name, statistics.median(runs), tuple(runs))


def scaling_config(config: DomainConfig, n_rovers: int) -> DomainConfig:
    """``config`` with ``n_rovers`` rovers (n_req at most R); above 15 rovers they start in
    a disc of radius 40 sqrt(R / 1000) (the paper's 1.5 cannot hold them: 1000 rovers of
    radius 0.2 would start piled on each other)."""
    fields = {"n_rovers": n_rovers, "n_req": min(max(config.n_req_per_poi), n_rovers)}
    if n_rovers > 15:
        fields["scenario"] = {**config.scenario.table(), "spawn_radius": 40.0 * math.sqrt(
            n_rovers / 1000.0)}  # fmt: skip
    return config.replace(**fields)


def bench_scaling(config: DomainConfig, rovers: list[int], total: int = 1500,
                  repeats: int = 5) -> list[tuple[int, int, float]]:  # fmt: skip
    """For each team size R: (R, teams, M rover-steps per second) of reset + ``steps``
    steps of the vector env with random actions, about ``total`` rovers in all
    (max(1, total // R) teams), median of ``repeats`` timed episodes
    (:func:`scaling_config` spreads large teams)."""
    rows = []
    for n_rovers in rovers:
        teams = max(1, total // n_rovers)
        timing = bench_world(scaling_config(config, n_rovers), teams, repeats)
        rate = teams * n_rovers * config.steps / (timing.median_ms / 1000.0) / 1e6
        rows.append((n_rovers, teams, rate))
    return rows


def _warm_learner(config, method: str):
    """A CCEA of ``config`` under ``method``, two generations played (caches, the first
    critic updates)."""
    from physrover.learn.ccea import CCEA

    learner = CCEA(config.with_overrides({"method": method}))
    for _ in range(2):
        learner.run_generation()
    return learner


def _timed_generation(learner) -> dict[str, float]:
    """Seconds of one generation of ``learner``: ``"generation"`` whole, and each phase of
    its ``timings``."""
    before, start = dict(learner.timings), time.perf_counter()
    learner.run_generation()
    spans = {"generation": time.perf_counter() - start}
    spans.update((name, learner.timings[name] - before[name]) for name in learner.timings)
    return spans


def bench_train(config, methods, generations: int = 10) -> list[str]:
    """Median ms per generation for each method, with the fastest and slowest (how steady
    the machine is: compare medians only when they differ by more than the spread) and the
    mean time per phase (means: they add up to the mean generation, not to the median)."""
    lines = []
    for method in methods:
        learner = _warm_learner(config, method)
        spans = [_timed_generation(learner) for _ in range(generations)]
        runs = [1000.0 * span["generation"] for span in spans]
        parts = ", ".join(
            f"{name} {1000.0 * sum(span[name] for span in spans) / generations:.1f}"
            for name in learner.timings
        )
        lines.append(
            f"{method:20s} median {statistics.median(runs):6.1f} ms/generation (min "
            f"{min(runs):.1f}, max {max(runs):.1f}; mean per phase: {parts})"
        )
    return lines


def bench_train_against(config, baseline, methods, generations: int = 20) -> list[str]:
    """Each method's generations of ``config`` interleaved with those of ``baseline`` in one
    process, one of each in turn (after two warm-up generations of each): the medians (ms)
    of the generation and of each phase for both, and their ratio. Where the host's speed
    drifts from one process to the next (medians of the same command moved by a third on
    a shared 2-core VM), the ratio of interleaved generations holds still: the way to
    state a cost relative to the paper's team (``physrover bench train --against paper``).
    """
    lines = []
    for method in methods:
        learners = [_warm_learner(c, method) for c in (config, baseline)]
        rounds = [[_timed_generation(learner) for learner in learners]
                  for _ in range(generations)]  # fmt: skip
        parts = []
        for name in rounds[0][0]:
            ours, theirs = (1000.0 * statistics.median(pair[side][name] for pair in rounds)
                            for side in (0, 1))  # fmt: skip
            ratio = f" = {ours / theirs:.2f}x" if theirs >= 0.05 else ""
            parts.append(f"{name} {ours:.1f} / {theirs:.1f}{ratio}")
        lines.append(f"{method:20s} medians, ms (config / against): " + ", ".join(parts))
    return lines


def median_seconds(step, warm_up: int, repeats: int) -> float:
    """Median seconds of ``repeats`` calls of ``step()`` after ``warm_up`` untimed ones."""
    for _ in range(warm_up):
        step()
    runs = []
    for _ in range(repeats):
        start = time.perf_counter()
        step()
        runs.append(time.perf_counter() - start)
    return statistics.median(runs)


def time_generation(config, generations: int = 3) -> float:
    """Median seconds per generation of a run with ``config`` (after two warm-up ones)."""
    from physrover.learn.ccea import CCEA

    return median_seconds(CCEA(config).run_generation, 2, generations)


def time_iteration(config, iterations: int = 3) -> float:
    """Median seconds per iteration of a gradient-based trainer with ``config`` (after one
    warm-up iteration), its updates running from the first iteration (``warmup_steps`` 0
    where the trainer has a warm-up, which only collects): the steady state, where a run
    spends nearly all its time. Evaluation episodes are played as the config says, and a
    coupling curriculum followed."""
    from physrover.experiment.trainer_runs import build_trainer

    trainer_config = config.trainer
    if hasattr(trainer_config, "warmup_steps"):
        trainer_config = dataclasses.replace(trainer_config, warmup_steps=0)
    trainer = build_trainer(config, trainer_config)
    return median_seconds(trainer.iteration, 1, iterations)


def time_step(config, repeats: int = 3) -> float:
    """Seconds per generation (CCEA) or per iteration (a gradient-based trainer)."""
    if config.trainer is not None:
        return time_iteration(config, repeats)
    return time_generation(config, repeats)


@dataclass(frozen=True)
class CellEstimate:
    """One cell of a sweep: its label, seconds per generation, runs and their total time."""

    label: str
    seconds_per_generation: float
    runs: int
    generations: int
    unit: str = "gen"
    """What ``generations`` counts: "gen" (CCEA generations) or "it" (a trainer's iterations)."""

    @property
    def run_seconds(self) -> float:
        return self.seconds_per_generation * self.generations

    @property
    def total_seconds(self) -> float:
        return self.run_seconds * self.runs


def estimate_sweep(specs, timer=time_step) -> list[CellEstimate]:
    """Per cell (runs equal but for the seed), the time of one generation (a trainer's
    iteration) measured with ``timer(config)``, times the cell's generations (iterations)
    and seeds: what the sweep will cost."""
    from physrover.config import RunConfig

    cells: dict[str, list] = {}
    for spec in specs:
        config = RunConfig.from_toml(spec.config_toml)
        key = config.with_overrides({"seed": 0}).to_toml()
        cells.setdefault(key, []).append((spec, config))
    estimates = []
    for members in cells.values():
        spec, config = members[0]
        label = spec.name.rsplit("_seed=", 1)[0]
        seconds = timer(config.with_overrides({"seed": 0}))
        if config.trainer is None:
            count, unit = config.learn.generations, "gen"
        else:
            count, unit = config.trainer.total_iterations, "it"
        estimates.append(CellEstimate(label, seconds, len(members), count, unit))
    return estimates


def sweep_wall_time(estimates: list[CellEstimate], workers: int) -> float:
    """Wall time of the sweep on ``workers`` processes: the total spread over the workers,
    but never less than its longest single run (runs are not split between workers)."""
    total = sum(e.total_seconds for e in estimates)
    longest = max((e.run_seconds for e in estimates), default=0.0)
    return max(total / max(workers, 1), longest)
