"""Exploration at the start of learning: does anything capture before learning begins?

    python experiments/exploration.py [--episodes 500]

Plays fresh episodes (``RoverVectorEnv(N, n_req=...)``, ``reset(seed=123)``, the paper's
task otherwise) under two untrained behaviours: uniform random actions every step (MADDPG's
uniform warm-up) and the CCEA's initial random policies (one per rover, drawn as the CCEA
draws its first population). Writes ``results/exploration.{csv,md}``: per n_req and
behaviour, the share of episodes with at least one capture, the mean G, and the median
over rovers of each rover's farthest distance from its start (world units).
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

import numpy as np

from physrover import RoverVectorEnv
from physrover.learn.policies import PolicyLayout

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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=500)
    args = parser.parse_args()
    rows = []
    for n_req in (1, 3, 4, 5, 6):
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
        }
        for name, act in behaviours.items():
            G, farthest = play(env, act)
            rows.append({"n_req": n_req, "behaviour": name,
                         "episodes_with_a_capture": round(float(np.mean(G > 0)), 4),
                         "mean_G": round(float(G.mean()), 4),
                         "median_farthest": round(float(np.median(farthest)), 2)})  # fmt: skip
    OUT.mkdir(parents=True, exist_ok=True)
    with open(OUT / "exploration.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    lines = ["| n_req | behaviour | episodes with a capture | mean G | median farthest (units) |",
             "|---|---|---|---|---|"]  # fmt: skip
    for r in rows:
        lines.append(f"| {r['n_req']} | {r['behaviour']} | {r['episodes_with_a_capture']:.1%} |"
                     f" {r['mean_G']:.3f} | {r['median_farthest']:.1f} |")  # fmt: skip
    (OUT / "exploration.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
