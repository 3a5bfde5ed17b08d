"""What a trained fitness critic has learned (issue 16, part 2): its value along the trained
team's own trajectories, against the situation of the rover.

    python experiments/critic_reading.py RUN_DIR [RUN_DIR ...] [--episodes 50] [--out DIR]

For each run (a critic method's run directory with its ``state.npz``: the critics of the
last generation) the champion team plays ``--episodes`` fresh episodes; every state-action
pair (s_t, a_t) of every rover gets its intermediate critic's value C(s_t, a_t) (Eq. 2), and
two facts about the state the pair leads to, s_{t+1}: the distance from the rover to its
nearest POI, and how many rovers (itself included) are within d_cap of that POI. Writes
``critic_reading.csv`` (per run, count of rovers near and 1-unit distance bin: the pairs'
mean critic value and their number), ``critic_reading.md`` (Spearman rank correlations of
the value with the distance, the rovers near, whether that POI was already captured, and
the rover's final D) and ``critic_reading.png`` (the binned means, one line per count). A
reading, not a test: the numbers say what the critic ranks high, not why evolution profits
from it.
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

import numpy as np

from physrover.envs.gymnasium_env import RoverVectorEnv
from physrover.experiment.store import load_run_config, load_state
from physrover.learn.ccea import CCEA

OUT = Path("experiments/results")


def read_run(run_dir: Path, episodes: int, seed: int) -> dict[str, np.ndarray]:
    """The pairs of ``episodes`` episodes of the run's champion team, with their critic
    values and situations; arrays of shape (episodes, steps, rovers)."""
    config = load_run_config(run_dir)
    ccea = CCEA(config)
    load_state(run_dir, ccea)
    critic = getattr(ccea.method, "critic", None)
    if critic is None:
        raise SystemExit(f"{run_dir}: method {config.learn.method!r} has no critic")
    d = config.domain
    env = RoverVectorEnv(episodes, config=d, fresh_teams=episodes)
    policy = ccea.layout.prepare(np.broadcast_to(ccea.champion_genomes(), (episodes,
                                                 *ccea.champion_genomes().shape)))  # fmt: skip
    obs, _ = env.reset(seed=seed)
    for _ in range(d.steps):
        obs, *_ = env.step(policy(obs))
    world = env.world
    o, a = world.trajectories()  # (T, E, R, n_obs), (T, E, R, 2)
    pairs = np.concatenate([o, a], axis=-1).transpose(2, 1, 0, 3)  # (R, E, T, D)
    n_rovers, n_eps, steps, width = pairs.shape
    values = critic.values(pairs.reshape(n_rovers, n_eps * steps, width))
    values = values.reshape(n_rovers, n_eps, steps).transpose(1, 2, 0)  # (E, T, R)
    after = world.position_history[1:].transpose(1, 0, 2, 3)  # (E, T, R, 2): s_{t+1}
    pois = world.poi_positions[:, None, None, :, :]  # (E, 1, 1, K, 2)
    dist = np.linalg.norm(after[:, :, :, None, :] - pois, axis=-1)  # (E, T, R, K)
    nearest = dist.argmin(-1)
    in_range = world.state.in_range[1:].transpose(1, 0, 2, 3)  # (E, T, R, K)
    near_count = in_range.sum(axis=2)  # (E, T, K): rovers near each POI at s_{t+1}
    captured_by = np.maximum.accumulate(
        near_count >= world.n_req[None, None, :], axis=1
    )  # (E, T, K): captured at or before t + 1
    take = np.take_along_axis
    return {
        "value": values,
        "distance": take(dist, nearest[..., None], -1)[..., 0],
        "rovers_near": take(near_count[:, :, None, :].repeat(n_rovers, 2), nearest[..., None], -1)[
            ..., 0
        ],  # fmt: skip
        "captured": take(captured_by[:, :, None, :].repeat(n_rovers, 2), nearest[..., None], -1)[
            ..., 0
        ],  # fmt: skip
        "final_feedback": np.broadcast_to(world.D[:, None, :], values.shape),
        "n_req": np.int64(d.n_req_per_poi[0]),
        "d_cap": np.float64(d.d_cap),
    }


def _ranks(x: np.ndarray) -> np.ndarray:
    """Ranks 0..n-1 of ``x``, ties given their average rank."""
    ranks = np.empty(len(x))
    ranks[np.argsort(x, kind="mergesort")] = np.arange(len(x))
    _, inverse, counts = np.unique(x, return_inverse=True, return_counts=True)
    return (np.bincount(inverse, weights=ranks) / counts)[inverse]


def spearman(x: np.ndarray, y: np.ndarray) -> float:
    """Spearman's rank correlation (Pearson's on average ranks)."""
    return float(np.corrcoef(_ranks(x), _ranks(y))[0, 1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("runs", nargs="+", type=Path)
    parser.add_argument("--episodes", type=int, default=50)
    parser.add_argument("--seed", type=int, default=12345)
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(args.runs), figsize=(6 * len(args.runs), 4.5), squeeze=False)
    table, lines = [], ["| run | n_req | pairs | value ~ distance | ~ rovers near | ~ captured "
                        "| ~ final D |", "|---|---|---|---|---|---|---|"]  # fmt: skip
    bins = np.arange(0.0, 21.0)
    centres = 0.5 * (bins[1:] + bins[:-1])
    for ax, run_dir in zip(axes[0], args.runs, strict=True):
        r = read_run(run_dir, args.episodes, args.seed)
        n_req, d_cap = int(r["n_req"]), float(r["d_cap"])
        flat = {k: np.asarray(v).ravel() for k, v in r.items() if np.ndim(v) == 3}
        name = run_dir.name
        rho = [spearman(flat["value"], flat[k].astype(float))
               for k in ("distance", "rovers_near", "captured", "final_feedback")]  # fmt: skip
        lines.append(f"| {name} | {n_req} | {flat['value'].size} | "
                     + " | ".join(f"{x:+.2f}" for x in rho) + " |")  # fmt: skip
        print(lines[-1])
        for count in range(0, n_req + 1):
            sel = flat["rovers_near"] >= count if count == n_req else flat["rovers_near"] == count
            which = np.digitize(flat["distance"][sel], bins) - 1
            means = []
            for b, centre in enumerate(centres):
                values = flat["value"][sel][which == b]
                means.append(values.mean() if len(values) >= 20 else np.nan)
                if len(values):
                    near = f">={count}" if count == n_req else str(count)
                    table.append([name, n_req, near, centre, f"{values.mean():.6g}", len(values)])
            label = f"{count} rovers near its POI" if count < n_req else f">= {n_req} (capture)"
            ax.plot(centres, means, marker="o", ms=3, label=label)
        ax.axvline(d_cap, color="grey", ls=":", lw=1)
        ax.set_xlabel("distance to the nearest POI after the step (world units)")
        ax.set_ylabel("critic value C(s, a), mean per 1-unit bin (>= 20 pairs)")
        ax.set_title(f"{name}: n_req {n_req}, {args.episodes} episodes")
        ax.legend(fontsize=8)
    with open(args.out / "critic_reading.csv", "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["run", "n_req", "rovers_near", "distance_bin_centre", "mean_value",
                         "pairs"])  # fmt: skip
        writer.writerows(table)
    (args.out / "critic_reading.md").write_text(
        "Spearman rank correlation of the critic's value with each quantity\n\n"
        + "\n".join(lines)
        + "\n"
    )
    fig.tight_layout()
    fig.savefig(args.out / "critic_reading.png", dpi=120)
    print(f"wrote {args.out / 'critic_reading.png'}")


if __name__ == "__main__":
    main()
