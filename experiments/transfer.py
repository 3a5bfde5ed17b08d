"""The transfer matrix: champions trained under each motion model, played under each.

    python experiments/transfer.py SWEEP_DIR [SWEEP_DIR ...] [--episodes 100]

For every finished run under the sweep directories (e.g. ``physics-long-ideal`` for
idealised training and ``physics-long`` for physical training), plays the champion on the
same fresh episodes (the starts of ``physrover evaluate``) under idealised motion and
physical motion without and with rover collisions. Writes ``results/transfer.csv`` (one
row per run and model played under: mean G of its episodes) and ``results/transfer.md``:
per method and n_req, the mean over seeds (+- 95% CI over seeds) of each (trained under,
played under) cell, then the change from a champion's own model to each other one, paired
by champion.
"""

from __future__ import annotations

import argparse
import csv
from collections import defaultdict
from pathlib import Path

import numpy as np

from physrover.core.stats import mean_ci
from physrover.experiment.evaluate import MOTION_MODELS, evaluate_run, motion_model
from physrover.experiment.store import find_runs, load_run_config

OUT = Path(__file__).parent / "results"
MODELS = MOTION_MODELS


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("sweeps", nargs="+", type=Path)
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--methods", default="D,max-critic")
    args = parser.parse_args()
    methods = args.methods.split(",")
    rows = []
    for run in find_runs(args.sweeps):
        config = load_run_config(run)
        if config.learn.method not in methods or not (run / "champions").exists():
            continue
        metrics = (run / "metrics.csv").read_text().strip().splitlines()
        if len(metrics) - 1 < config.learn.generations:  # unfinished
            continue
        trained = motion_model(config.domain.motion, config.domain.physics.collisions)
        for model, changes in MODELS.items():
            result = evaluate_run(run, episodes=args.episodes, **changes)
            rows.append({
                "run": run.name, "method": config.learn.method, "n_req": config.domain.n_req,
                "seed": config.learn.seed, "trained_under": trained,
                "played_under": model, "mean_G": f"{result.mean:.4f}",
            })  # fmt: skip
    if not rows:
        raise SystemExit("no finished runs of the methods under the sweep directories")
    OUT.mkdir(parents=True, exist_ok=True)
    with open(OUT / "transfer.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    cells = defaultdict(list)
    for r in rows:
        cells[(r["method"], r["n_req"], r["trained_under"], r["played_under"])].append(
            float(r["mean_G"])
        )
    lines = ["| method | n_req | trained under | " + " | ".join(f"played {m}" for m in MODELS)
             + " | seeds |", "|---|---|---|" + "---|" * (len(MODELS) + 1)]  # fmt: skip
    for method, n_req, trained in sorted({k[:3] for k in cells}):
        out = []
        for model in MODELS:
            values = np.array(cells.get((method, n_req, trained, model), []))
            mean, ci, n = mean_ci(values) if len(values) else (np.nan, np.nan, 0)
            out.append(f"{float(mean):.2f} +- {float(ci):.2f}")
        lines.append(f"| {method} | {n_req} | {trained} | " + " | ".join(out) + f" | {n} |")
    lines += ["", *paired_changes(rows)]
    (OUT / "transfer.md").write_text("\n".join(lines) + "\n")
    print(f"wrote {OUT / 'transfer.md'}")


def paired_changes(rows: list[dict]) -> list[str]:
    """A table of what playing under another model does to a champion: per method, n_req
    and (trained under, played under), the mean over champions (seeds) of G played minus G
    under its own training model on the same starts, +- 95% CI (paired by champion)."""
    own = {(r["run"], r["trained_under"]): float(r["mean_G"]) for r in rows
           if r["played_under"] == r["trained_under"]}  # fmt: skip
    diffs = defaultdict(list)
    for r in rows:
        if r["played_under"] != r["trained_under"] and (r["run"], r["trained_under"]) in own:
            key = (r["method"], r["n_req"], r["trained_under"], r["played_under"])
            diffs[key].append(float(r["mean_G"]) - own[(r["run"], r["trained_under"])])
    lines = ["| method | n_req | trained under | played under | G played - G own (mean +- 95% CI)"
             " | champions |", "|---|---|---|---|---|---|"]  # fmt: skip
    for key in sorted(diffs):
        mean, ci, n = mean_ci(np.array(diffs[key]))
        lines.append("| " + " | ".join(map(str, key)) + f" | {float(mean):+.2f} +- {float(ci):.2f}"
                     f" | {n} |")  # fmt: skip
    return lines


if __name__ == "__main__":
    main()
