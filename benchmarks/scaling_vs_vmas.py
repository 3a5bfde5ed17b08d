"""Team-size scaling of physrover and of VMAS ``discovery``, in one script (issue 32).

    pip install vmas
    python benchmarks/scaling_vs_vmas.py [--rovers 15,100,400,1000] [--repeats 5]
                                          [--vmas-steps 50] [--no-vmas]

For each team size R, about 1500 agents in all (max(1, 1500 // R) teams): M agent-steps per
second of reset + 50 steps with random actions, median of ``repeats`` episodes after a
warm-up one, one thread, for physrover under idealised motion (the paper's sensor, and a
sensor of radius 5), under physics with collisions (the paper's sensor, and radius 5), and
for VMAS ``discovery`` (R agents, 4 targets, 3 agents per target, its world widened with R
so its spawn fits: semidim sqrt(R / 15)) through its own vectorised env on the CPU
(``--vmas-steps K``: episodes of K steps; VMAS takes 9 s a step at 400 agents and a minute
at 1000, so use 1-3 there).
physrover's large teams start spread as ``physrover bench world --rovers`` spreads them
(:func:`physrover.experiment.bench.scaling_config`). Prints a Markdown table.
"""

from __future__ import annotations

import argparse
import math

from physrover.config import DomainConfig
from physrover.core.threads import pin_threads
from physrover.experiment.bench import bench_scaling, median_seconds

COLUMNS = {
    "idealised, paper's sensor": DomainConfig(n_req=3),
    "idealised, radius 5": DomainConfig(n_req=3, sensor={"kind": "density", "radius": 5.0}),
    "physics, paper's sensor": DomainConfig(n_req=3, motion="physics"),
    "physics, radius 5": DomainConfig(
        n_req=3, motion="physics", sensor={"kind": "density", "radius": 5.0}
    ),  # fmt: skip
}


def vmas_rate(n_agents: int, repeats: int, steps: int = 50, total: int = 1500) -> float:
    """M agent-steps per second of VMAS discovery (see the module docstring)."""
    import torch
    import vmas

    envs = max(1, total // n_agents)
    semidim = max(1.0, math.sqrt(n_agents / 15.0))
    env = vmas.make_env("discovery", num_envs=envs, device="cpu", continuous_actions=True,
                        seed=0, n_agents=n_agents, n_targets=4, agents_per_target=3,
                        x_semidim=semidim, y_semidim=semidim)  # fmt: skip
    generator = torch.Generator().manual_seed(0)
    actions = [[torch.rand((envs, 2), generator=generator) * 2 - 1 for _ in range(n_agents)]
               for _ in range(steps)]  # fmt: skip

    def episode():
        env.reset()
        for step in actions:
            env.step(step)

    return envs * n_agents * steps / median_seconds(episode, 1, repeats) / 1e6


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rovers", default="15,100,400,1000")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--no-vmas", action="store_true", help="physrover's columns only")
    parser.add_argument("--vmas-steps", type=int, default=50, help="steps of a VMAS episode")
    args = parser.parse_args()
    pin_threads(1)
    rovers = [int(r) for r in args.rovers.split(",")]
    table = {name: bench_scaling(config, rovers, repeats=args.repeats)
             for name, config in COLUMNS.items()}  # fmt: skip
    names = list(COLUMNS) + ([] if args.no_vmas else ["VMAS discovery"])
    print("| rovers per team (teams) | " + " | ".join(names) + " |")
    print("|---|" + "---|" * len(names))
    for i, n in enumerate(rovers):
        cells = [f"{table[name][i][2]:.2f}" for name in COLUMNS]
        if not args.no_vmas:
            rate = vmas_rate(n, max(1, args.repeats // 2), steps=args.vmas_steps)
            cells.append(f"{rate:.2g}")
        teams = table[next(iter(COLUMNS))][i][1]
        print(f"| {n} ({teams}) | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
