"""Exploration at the start of learning: does anything capture before learning begins?

    python experiments/exploration.py [--episodes 500]

Plays fresh episodes (``RoverVectorEnv(N, n_req=...)``, ``reset(seed=123)``, the paper's
task otherwise) under untrained behaviours: uniform random actions every step (MADDPG's
uniform warm-up), the CCEA's initial random policies (one per rover, drawn as the CCEA
draws its first population) and MAPPO's initial shared policy as it samples its first
episodes (its network as the trainer initialises it, one per 10 episodes, N(mean, std)
clipped to [-1, 1]), at its default std (``init_log_std = -0.5``) and at a wider one
(``init_log_std = 1``). Writes ``results/exploration.{csv,md}``: per n_req and
behaviour, the share of episodes with a capture, the mean G, and the median over rovers
of each rover's farthest distance from its start (world units).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch

from physrover import RoverVectorEnv
from physrover.analysis.tables import write_csv
from physrover.learn.policies import PolicyLayout
from physrover.marl.common import torch_generator
from physrover.marl.mappo import Agent, MAPPOConfig

OUT = Path(__file__).parent / "results"


def play(env: RoverVectorEnv, act) -> tuple[np.ndarray, np.ndarray]:
    """G of each episode and each rover's farthest distance from its start, (E,), (E, R)."""
    obs, _ = env.reset(seed=123)
    start = env.world.rover_positions.copy()
    farthest = np.zeros(start.shape[:2])
    for _ in range(env.config.steps):
        obs, *_ = env.step(act(obs))
        reach = np.linalg.norm(env.world.rover_positions - start, axis=-1)
        farthest = np.maximum(farthest, reach)
    return env.world.G.copy(), farthest


def mappo_start(env: RoverVectorEnv, init_log_std: float, rng, group: int = 10):
    """MAPPO's first sampled actions: a freshly initialised agent per ``group`` teams."""
    shape = env.single_observation_space.shape  # (R, n_obs)
    n = -(-env.num_envs // group)  # the last agent plays the remainder
    agents = [Agent(*shape, MAPPOConfig(), torch_generator(i)) for i in range(n)]

    def act(obs):
        with torch.no_grad():
            chunks = torch.from_numpy(obs).split(group)
            mean = torch.cat([a.mean(x) for a, x in zip(agents, chunks, strict=True)]).numpy()
        return np.clip(mean + rng.normal(0, np.exp(init_log_std), mean.shape), -1, 1)

    return act


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=500)
    args = parser.parse_args()
    rows = []
    for n_req in (1, 2, 3, 4, 5, 6):
        env = RoverVectorEnv(args.episodes, n_req=n_req)
        shape = (args.episodes, env.config.n_rovers)
        rng = np.random.default_rng(0)
        layout = PolicyLayout(32, env.single_observation_space.shape[-1])
        policy = layout.prepare(layout.init(shape, np.random.default_rng(1)))
        behaviours = {
            "uniform random actions": lambda obs, rng=rng, shape=shape: rng.uniform(
                -1, 1, (*shape, 2)
            ),
            "initial CCEA policies": policy,
            "initial MAPPO policy, std 0.61": mappo_start(env, -0.5, rng),
            "initial MAPPO policy, std 2.72": mappo_start(env, 1.0, rng),
        }
        for name, act in behaviours.items():
            G, farthest = play(env, act)
            rows.append({"n_req": n_req, "behaviour": name,
                         "episodes_with_a_capture": round(float(np.mean(G > 0)), 4),
                         "mean_G": round(float(G.mean()), 4),
                         "median_farthest": round(float(np.median(farthest)), 2)})  # fmt: skip
    OUT.mkdir(parents=True, exist_ok=True)
    write_csv(rows, list(rows[0]), OUT / "exploration.csv")
    lines = ["| n_req | behaviour | episodes with a capture | mean G | median farthest (units) |",
             "|---|---|---|---|---|"]  # fmt: skip
    for r in rows:
        lines.append(f"| {r['n_req']} | {r['behaviour']} | {r['episodes_with_a_capture']:.1%} |"
                     f" {r['mean_G']:.3f} | {r['median_farthest']:.1f} |")  # fmt: skip
    (OUT / "exploration.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
