"""Why idealised and physical motion score differently: how trained teams move under each.

    python experiments/motion_stats.py RUN_DIR [RUN_DIR ...] [--episodes 200] [--name NAME]

Plays each run's champion team on the same fresh episodes (the starts of ``physrover
evaluate``) under idealised motion and physical motion without and with rover collisions,
and records per episode: G; each rover's path length (world units, mean over rovers); the
step of the first capture (NaN if none); the mean number of rovers within d_cap of a POI
(mean over POIs and steps); the rover pairs in contact per step (centres closer than 1.01
times their radii summed, physics only), summed over the episode. Writes
``results/NAME.{csv,md}`` (one row per run and motion model: means with 95% CIs) and
``results/NAME.png`` (speed and rovers near POIs over the episode, per model) with its
numbers in ``results/NAME_profiles.csv`` (one row per run, model and step); NAME is
``motion_stats`` unless given.
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from physrover.core.stats import mean_ci  # noqa: E402
from physrover.experiment.evaluate import MOTION_MODELS, motion_model, play_champion  # noqa: E402
from physrover.experiment.store import load_run_config  # noqa: E402

OUT = Path(__file__).parent / "results"


def episode_stats(world, domain) -> dict[str, np.ndarray]:
    """Per-episode statistics (module docstring) and per-step profiles."""
    path = world.position_history  # (T + 1, E, R, 2)
    moves = np.linalg.norm(np.diff(path, axis=0), axis=-1)  # (T, E, R)
    captured = world.state.capture_step  # (E, K), -1 if never
    first = np.where(captured >= 0, captured, np.iinfo(np.int64).max).min(axis=1)
    first = np.where(first == np.iinfo(np.int64).max, np.nan, first).astype(float)
    near = world.state.in_range.sum(axis=2)  # (T + 1, E, K) rovers within d_cap of each POI
    radii = np.asarray(domain.physics.per_rover("rover_radius", domain.n_rovers))
    gaps = np.linalg.norm(path[:, :, :, None] - path[:, :, None], axis=-1)  # (T+1, E, R, R)
    touching = gaps < 1.01 * (radii[:, None] + radii[None, :])
    upper = np.triu(np.ones((domain.n_rovers,) * 2, dtype=bool), 1)
    contacts = (touching & upper).sum(axis=(2, 3))[1:].sum(axis=0)  # (E,)
    return {
        "G": world.G,
        "path_length": moves.sum(axis=0).mean(axis=1),
        "first_capture_step": first,
        "rovers_near_poi": near.mean(axis=(0, 2)),
        "contacts": contacts.astype(float),
        "speed_profile": moves.mean(axis=(1, 2)),  # (T,)
        "near_profile": near.mean(axis=(1, 2)),  # (T + 1,)
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", type=Path)
    parser.add_argument("--episodes", type=int, default=200)
    parser.add_argument("--name", default="motion_stats", help="the output files' name")
    args = parser.parse_args()
    OUT.mkdir(parents=True, exist_ok=True)
    columns = ["G", "path_length", "first_capture_step", "rovers_near_poi", "contacts"]
    rows, profiles = [], {}
    for run in args.runs:
        domain = load_run_config(run).domain
        trained = motion_model(domain.motion, domain.physics.collisions)
        for model, changes in MOTION_MODELS.items():
            _, env = play_champion(run, args.episodes, **changes)
            stats = episode_stats(env.world, env.config)
            row = {"run": run.name, "trained_under": trained, "played_under": model}
            for c in columns:
                values = stats[c][~np.isnan(stats[c])]
                mean, ci, n = mean_ci(values) if len(values) else (np.nan, np.nan, 0)
                row[c] = f"{float(mean):.3f}"
                row[f"{c}_ci95"] = f"{float(ci):.3f}"
            row["captured_any"] = f"{np.mean(~np.isnan(stats['first_capture_step'])):.3f}"
            rows.append(row)
            profiles[(run.name, trained, model)] = stats
    with open(OUT / f"{args.name}.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    head = ("| run | trained under | played under | G | path length | first capture (step) |"
            " rovers near a POI | contacts / episode | episodes with a capture |")  # fmt: skip
    lines = [head, "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        cells = [f"{r[c]} +- {r[c + '_ci95']}" for c in columns]
        lines.append(f"| {r['run']} | {r['trained_under']} | {r['played_under']} | "
                     + " | ".join(cells) + f" | {float(r['captured_any']):.0%} |")  # fmt: skip
    (OUT / f"{args.name}.md").write_text("\n".join(lines) + "\n")
    with open(OUT / f"{args.name}_profiles.csv", "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["run", "trained_under", "played_under", "step", "mean_move",
                         "rovers_near_poi"])  # fmt: skip
        for (run, trained, model), stats in profiles.items():
            for t, near in enumerate(stats["near_profile"]):  # the move into step t
                move = stats["speed_profile"][t - 1] if t else float("nan")
                writer.writerow([run, trained, model, t, f"{move:.5f}", f"{near:.5f}"])
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.8))
    trainings = {trained for _, trained, _ in profiles}
    by_training = len(args.runs) > 1 and len(trainings) == len(args.runs)
    runs = list(dict.fromkeys(run for run, _, _ in profiles))
    style = dict(zip(MOTION_MODELS, ("-", "--", ":"), strict=True))  # the model played under
    for (run, trained, model), stats in profiles.items():
        if len(args.runs) == 1:
            label = model
        elif by_training:  # one run per training model: colour = trained, line = played
            label = f"trained {trained}, played {model}"
        else:
            label = f"{run}: {model}"
        look = {"color": f"C{runs.index(run)}", "linestyle": style[model]} if by_training else {}
        axes[0].plot(np.arange(1, len(stats["speed_profile"]) + 1), stats["speed_profile"],
                     label=label, **look)  # fmt: skip
        axes[1].plot(stats["near_profile"], label=label, **look)
    axes[0].set(xlabel="step", ylabel="mean distance moved per step", title="speed")
    axes[1].set(xlabel="step", ylabel="rovers within d_cap of a POI (mean)",
                title="rovers near the POIs")  # fmt: skip
    axes[1].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(OUT / f"{args.name}.png", dpi=120)
    print(f"wrote {OUT / args.name}.md")


if __name__ == "__main__":
    main()
