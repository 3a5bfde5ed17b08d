"""Issue 46's standing table, BenchMARL's row: BenchMARL's MAPPO on physrover's task.

    python experiments/benchmarl_table.py run --root DIR [--seeds 0:3] [--n-req 1,2,3,4,5,6]
    python experiments/benchmarl_table.py report --root DIR [--out DIR]

``run`` trains one BenchMARL experiment per cell (n_req x seed) with the ``physrover
benchmarl`` of the Python running this script (run it from a non-editable install of a
pinned commit, in a venv with ``physrover[benchmarl]``), one after the other, each into
``DIR/n_req=N_seed=S``. A cell whose ``result.json`` exists is done and skipped; a cell
left without one (an interrupted run) is trained again from the start, so the command
resumes where it stopped.

Each cell is the paper's domain (15 rovers, POIs of value 1-4 on the ring, 50 steps) at
coupling N, ``experiment=physrover_quick`` (BenchMARL's base experiment, learning rate
3e-4, 6000 frames an iteration in 60 batched teams, 10 epochs of mini-batches of 1000)
for :data:`ITERATIONS` iterations: 25,200 training episodes, the budget of the
``marl``/``maddpg-grid`` rows (the max critic's first 500 generations). Every
:data:`EVAL_EVERY` iterations BenchMARL evaluates the deterministic policy on 100 fresh
episodes; the cell's final G is the mean of the last :data:`LAST` evaluations (the
episode return is the team's G, Eq. 11: each step's reward is its increase).

``report`` writes into ``--out`` (default ``experiments/results/standing-table-benchmarl``)
``runs.csv`` (a row per finished cell; ``code`` is the digest of the
installed package's sources, as in a sweep's ``runs.csv``) and ``cells.md`` (mean and 95%
interval over seeds per n_req, the mean alone for one seed, and how many seeds learned:
final G above 0.5).
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

OUT = Path(__file__).parent / "results" / "standing-table-benchmarl"
ITERATIONS = 210
"""Training iterations of 6000 frames (120 episodes): 25,200 episodes."""
EVAL_EVERY = 10
"""Iterations between evaluations (of 100 episodes each): 21 evaluations a run."""
LAST = 5
"""Evaluations averaged into a cell's final G (its last ~6000 training episodes)."""
FIELDS = ("sweep", "run", "method", "n_req", "seed", "episodes", "final_G", "max_eval_G",
          "evaluations", "wall_seconds", "code", "benchmarl", "cpu")  # fmt: skip


def cell_name(n_req: int, seed: int) -> str:
    return f"n_req={n_req}_seed={seed}"


def overrides(n_req: int, seed: int) -> list[str]:
    """The Hydra overrides of one cell (``physrover benchmarl`` adds algorithm=mappo and
    task=physrover/rover_domain)."""
    return ["experiment=physrover_quick", f"task.n_req={n_req}", f"seed={seed}",
            f"experiment.max_n_iters={ITERATIONS}",
            f"experiment.evaluation_interval={EVAL_EVERY * 6000}",
            "experiment.evaluation_episodes=100"]  # fmt: skip


def evaluations(folder: Path) -> list[float]:
    """The evaluation returns BenchMARL's csv logger wrote, in order."""
    from physrover.cli.benchmarl_cmd import scalar_values

    return scalar_values(folder, "eval_reward_episode_reward_mean")


def train_cell(root: Path, n_req: int, seed: int) -> dict:
    """Train one cell into ``root/<cell>`` (from the start) and write its result.json."""
    from importlib import metadata

    from physrover.experiment.provenance import code_fingerprint, cpu_model

    folder = root / cell_name(n_req, seed)
    if folder.exists():  # an interrupted run: BenchMARL's own restore is not used
        shutil.rmtree(folder)
    exe = Path(sys.executable).parent / "physrover"
    start = time.perf_counter()
    subprocess.run([str(exe), "benchmarl", "--out", str(folder / "benchmarl"),
                    *overrides(n_req, seed)], check=True)  # fmt: skip
    wall = time.perf_counter() - start
    returns = evaluations(folder / "benchmarl")
    if len(returns) < LAST:
        raise RuntimeError(f"{folder}: {len(returns)} evaluations, expected >= {LAST}")
    result = {
        "sweep": "standing-table-benchmarl", "run": cell_name(n_req, seed),
        "method": "benchmarl-mappo", "n_req": n_req, "seed": seed,
        "episodes": ITERATIONS * 120, "final_G": float(np.mean(returns[-LAST:])),
        "max_eval_G": float(max(returns)), "evaluations": len(returns),
        "wall_seconds": round(wall, 1), "code": (code_fingerprint() or "?")[:12],
        "benchmarl": metadata.version("benchmarl"), "cpu": cpu_model(),
        "returns": returns, "overrides": overrides(n_req, seed),
    }  # fmt: skip
    (folder / "result.json").write_text(json.dumps(result, indent=1))
    return result


def cmd_run(args: argparse.Namespace) -> None:
    first, last = (int(x) for x in args.seeds.split(":"))
    cells = [(n, s) for s in range(first, last) for n in args.n_req]
    todo = [c for c in cells if not (args.root / cell_name(*c) / "result.json").exists()]
    print(f"benchmarl table: {len(cells)} cells, {len(cells) - len(todo)} done, "
          f"{len(todo)} to train under {args.root}", flush=True)  # fmt: skip
    for i, (n_req, seed) in enumerate(todo, 1):
        print(f"[{i}/{len(todo)}] {cell_name(n_req, seed)}", flush=True)
        result = train_cell(args.root, n_req, seed)
        print(f"  final G {result['final_G']:.3f}, {result['wall_seconds']:.0f} s", flush=True)


def cmd_report(args: argparse.Namespace) -> None:
    from physrover.analysis.tables import write_csv
    from physrover.core.stats import mean_ci

    results = [json.loads(p.read_text()) for p in sorted(args.root.glob("*/result.json"))]
    if not results:
        raise SystemExit(f"no finished cell under {args.root}")
    args.out.mkdir(parents=True, exist_ok=True)
    rows = [
        {k: r[k] for k in FIELDS} for r in sorted(results, key=lambda r: (r["n_req"], r["seed"]))
    ]
    write_csv(rows, list(FIELDS), args.out / "runs.csv")
    lines = ["| n_req | final G (mean +- 95% CI) | seeds | seeds that learn | best evaluation |",
             "|---|---|---|---|---|"]  # fmt: skip
    for n_req in sorted({r["n_req"] for r in results}):
        finals = np.array([r["final_G"] for r in results if r["n_req"] == n_req])
        best = max(r["max_eval_G"] for r in results if r["n_req"] == n_req)
        mean, half, n = mean_ci(finals)
        cell = f"{mean:.2f} +- {half:.2f}" if n > 1 else f"{mean:.2f}"  # no interval of 1
        lines.append(f"| {n_req} | {cell} | {n} | {int((finals > 0.5).sum())} | {best:.2f} |")
    (args.out / "cells.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run", help="train the cells not yet done")
    run.add_argument("--root", type=Path, required=True)
    run.add_argument("--seeds", default="0:3", help="A:B, seeds A to B - 1 (default 0:3)")
    run.add_argument("--n-req", type=lambda s: [int(x) for x in s.split(",")],
                     default=[1, 2, 3, 4, 5, 6])  # fmt: skip
    run.set_defaults(func=cmd_run)
    report = sub.add_parser("report", help="runs.csv and cells.md of the finished cells")
    report.add_argument("--root", type=Path, required=True)
    report.add_argument("--out", type=Path, default=OUT)
    report.set_defaults(func=cmd_report)
    args = parser.parse_args()
    args.func(args)


if __name__ == "__main__":
    main()
