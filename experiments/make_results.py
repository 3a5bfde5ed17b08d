"""Turn the experiment sweeps into the committed results (run from the repository root).

    python experiments/make_results.py [--root runs/sweeps] [--last 50]

Writes under experiments/results/: learning-curve PNGs with their CSVs (mean eval G and
95% CI half-width per generation, per group), final-score plots with CSVs, runs.csv (one
row per run: its config cell, seed, final score, wall time, the code and CPU that trained
it: :func:`provenance_columns`) and cells.md (the table of
final mean G +- 95% CI per cell that RESULTS.md quotes). Sweeps missing under ``--root``
keep their rows of runs.csv and their sections of cells.md, so sweeps can be re-made one
at a time. ``fig8-9-paper`` and ``physics-long-mean`` (:data:`POOLED`), final-score sweeps
run in chunks of seeds (``physrover sweep FILE --seeds 0:2``, ``2:4``, ...) on machines that
do not keep each other's run directories, keep the rows of their finished runs that are not
among the finished runs on disk, and their final-score figures and tables pool them with
the runs found (they draw no learning curves): the committed runs.csv is what carries them
across machines (with ``--last`` 50, the rows' own). Any other sweep
found on disk is made from what is there alone: chunking it would drop the other chunks.
"Final score" of a run is its mean eval G over its last ``--last`` generations; the CI is
over seeds (Student t).
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
from collections import defaultdict
from pathlib import Path

import numpy as np

from physrover.analysis import plots
from physrover.analysis.curve_data import Table, final_score, scores_table
from physrover.analysis.results import is_finished as _finished
from physrover.analysis.results import kept_rows as _kept_finals
from physrover.analysis.results import provenance_columns
from physrover.experiment.evaluate import motion_model
from physrover.experiment.store import find_runs, read_metrics

OUT = Path("experiments/results")


def variant(run: plots.Run, fields: tuple[str, ...]) -> str:
    """``field=value ...`` of the given fields of a run (booleans lower-case)."""
    parts = []
    for f in fields:
        value = run.fields[f]
        parts.append(f"{f}={str(value).lower() if isinstance(value, bool) else value}")
    return " ".join(parts)


def label(run: plots.Run, fields: tuple[str, ...]) -> str:
    return " ".join([run.fields["method"], *([variant(run, fields)] if fields else [])])


def regroup(runs: list[plots.Run], fields: tuple[str, ...]) -> list[plots.Run]:
    for run in runs:
        run.group = label(run, fields)
    return runs


def motion_label(run: plots.Run) -> str:
    return motion_model(run.fields["motion"], run.fields["collisions"])


ABLATED = ("method", "critic_lr", "critic_optimizer", "replay_pairs", "critic_hidden")
"""The fields the ablation changes, one at a time, from the paper's max critic."""


def ablation_table(sweep: Path, last: int) -> None:
    """results/ablation.{md,csv}: one row per variant (what differs from the paper's max
    critic), per n_req the final G (mean +- 95% CI over seeds) and the critic's loss (its
    mean squared error over the last ``last`` generations, mean over seeds)."""
    from physrover.config import LearnConfig
    from physrover.learn.configs import CriticConfig

    paper = {**LearnConfig(method="max-critic").to_dict(), **CriticConfig().to_dict()}
    # finished runs only: a run still going would be scored on its last generations so far
    runs = [
        r for r in plots.load_runs(find_runs([sweep]))
        if len(r.eval_G) and len(r.eval_G) >= r.fields["generations"]
    ]  # fmt: skip
    cells = defaultdict(lambda: {"final": [], "loss": [], "gens": []})
    for run in runs:
        changed = [f"{f}={run.fields[f]}" for f in ABLATED if run.fields[f] != paper[f]]
        variant = ", ".join(changed) or "the paper's max critic"
        rows = read_metrics(run.path / "metrics.csv")
        loss = np.array([r["critic_loss"] for r in rows[-last:]], dtype=float)
        cell = cells[(variant, run.fields["n_req"])]
        cell["final"].append(final_score(run, last))
        cell["loss"].append(float(np.nanmean(loss)) if np.isfinite(loss).any() else np.nan)
        cell["gens"].append(len(rows))
    n_reqs = sorted({n for _, n in cells})
    variants = sorted({v for v, _ in cells}, key=lambda v: (v != "the paper's max critic", v))
    head = " | ".join(f"n_req {n}: final G | loss | seeds, gens" for n in n_reqs)
    lines = [f"| variant | {head} |", "|---|" + "---|---|---|" * len(n_reqs)]
    csv_rows = []
    for v in variants:
        parts = []
        for n in n_reqs:
            c = cells.get((v, n))
            if not c:
                parts.append("| | ")
                continue
            mean, ci, k = plots.mean_ci(np.array(c["final"]))
            loss = float(np.nanmean(c["loss"])) if np.isfinite(c["loss"]).any() else np.nan
            gens = f"{min(c['gens'])}" + ("" if min(c["gens"]) == max(c["gens"]) else "+")
            parts.append(f"{float(mean):.2f} +- {float(ci):.2f} | {loss:.3g} | {k}, {gens}")
            csv_rows.append({"variant": v, "n_req": n, "final_G": float(mean),
                             "ci95": float(ci), "critic_loss": loss, "seeds": k,
                             "min_generations": min(c["gens"])})  # fmt: skip
        lines.append(f"| {v} | " + " | ".join(parts) + " |")
    (OUT / "ablation.md").write_text("\n".join(lines) + "\n")
    with open(OUT / "ablation.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(csv_rows[0]))
        writer.writeheader()
        writer.writerows(csv_rows)


def _max_critic_at(n_req: int, episodes: int) -> str:
    """The max critic's mean eval G after the generation at which it had played
    ``episodes`` training episodes (50 a generation): fig4-7-long's curves (10 seeds,
    100-generation moving mean) where they exist, else fig4-7's (5 seeds, 20)."""
    for name in (f"fig4-6_long_curves_nreq{n_req}.csv", f"fig4-6_curves_nreq{n_req}.csv"):
        if (OUT / name).exists():
            break
    else:
        return "n/a"
    with open(OUT / name, newline="") as f:
        rows = [r for r in csv.DictReader(f) if r["group"] == "max-critic"]
    generation = episodes // 50
    first = int(rows[0]["generation"]) if rows else 1  # 0 in files written by 0.1.0
    for row in rows:
        if int(row["generation"]) - first + 1 == generation:
            return f"{float(row['mean']):.2f} +- {float(row['ci95_half_width']):.2f}"
    return "n/a"


def _column(row: dict, field: str):
    """A runs.csv value as the config field's type (ints for n_req, n_rovers, seed)."""
    value = row[field]
    return int(value) if field in ("n_req", "n_rovers", "seed") else value


POOLED = ("fig8-9-paper", "physics-long-mean")
"""Final-score sweeps whose committed runs.csv rows are pooled with the runs found (module
docstring): the ones run in chunks of seeds across machines."""
POOLED_LAST = 50
"""The ``--last`` of the committed rows' final scores; another ``--last`` pools nothing."""


def _final_scores(runs: list[plots.Run], rows: list[dict], x: str, last: int,
                  g_max: float, row_group=lambda row: row["method"]) -> Table:  # fmt: skip
    """:func:`plots.final_table` of ``runs`` (grouped by their ``group``, the method in the
    fig8-9 sweeps) with the final scores of the kept runs.csv ``rows`` pooled in, by
    ``row_group(row)`` (the method); a group's G max is the largest of its runs found, or
    ``g_max`` if it has none."""
    if not rows:
        return plots.final_table(runs, x, last=last)
    scores: dict[str, dict[float, list[float]]] = defaultdict(lambda: defaultdict(list))
    for run in runs:
        scores[run.group][run.fields[x]].append(final_score(run, last))
    for row in rows:
        scores[row_group(row)][_column(row, x)].append(float(row["final_G"]))
    shared = {group: (max([r.g_max for r in runs if r.group == group], default=g_max), group)
              for group in scores}  # fmt: skip
    return scores_table(x, scores, shared)


def _twins(physical: list[plots.Run], *sources: list[plots.Run]) -> list[plots.Run]:
    """The idealised twins of ``physical`` runs: for each (method, n_req, seed) of theirs,
    the run of the first of ``sources`` that has it (none if no source has it)."""
    wanted = sorted({(r.fields["method"], r.fields["n_req"], r.fields["seed"]) for r in physical})
    by_cell = [{(r.fields["method"], r.fields["n_req"], r.fields["seed"]): r for r in source}
               for source in sources]  # fmt: skip
    twins = []
    for cell in wanted:
        found = next((runs[cell] for runs in by_cell if cell in runs), None)
        if found is not None:
            twins.append(found)
    return twins


def trainer_label(run: plots.Run) -> str:
    """A gradient-based run's row: its method and, for MADDPG, its warm-up; a MADDPG run
    whose config predates the pre-tanh penalty and gradient clipping (physrover 0.1: no
    ``action_penalty`` in its [maddpg] table; loading it would fill in today's defaults) is
    marked so, never pooled with the runs that had them."""
    method = run.fields["method"]
    if method != "maddpg":
        return method
    if "action_penalty" not in (run.path / "config.toml").read_text():
        return "maddpg (0.1: no penalty, no clipping)"
    return f"maddpg ({run.fields['maddpg.warmup_actions']} warm-up)"


def _first_episodes(run: plots.Run, episodes: int) -> plots.Run:
    """``run`` cut to its rows up to ``episodes`` training episodes."""
    keep = run.episodes <= episodes
    return dataclasses.replace(run, eval_G=run.eval_G[keep], generation=run.generation[keep],
                               episodes=run.episodes[keep])  # fmt: skip


def _budget(run: plots.Run) -> int:
    """A gradient-based run's budget of training episodes (its config's)."""
    return int(run.fields[f"{run.fields['method']}.total_episodes"])


def marl_table(sweeps: list[Path], last: int, ccea: list[plots.Run] = ()) -> None:
    """results/marl.{md,csv} and marl_curves_nreq*.png (finished runs of the gradient-based
    sweeps, ``marl``, ``maddpg-check``, ``maddpg-grid``, ``mappo-long``): each method's
    (:func:`trainer_label`, and its budget unless 25,000 episodes) final eval G (mean of
    the last ``last`` iterations, 95% CI over seeds), the share of seeds that learn, and
    the max critic after as many training episodes (:func:`_max_critic_at`). The curves
    are on training episodes, one figure per n_req and budget (``_250000`` appended for
    budgets other than 25,000), with the ``ccea`` runs of the same n_req (fig4-7-long's)
    over the same number of episodes."""
    runs = [r for r in plots.load_runs(find_runs(sweeps)) if len(r.eval_G)]
    runs = [r for r in runs if (r.path / "state.json").exists() and _finished(r.path)]
    cells = defaultdict(lambda: {"final": [], "episodes": []})
    for run in runs:
        run.group = trainer_label(run)
        if _budget(run) != 25000:  # the 25,000-episode runs are the default; others say so
            run.group += f", {_budget(run):,} episodes"
        cell = cells[(run.group, run.fields["n_req"])]
        cell["final"].append(final_score(run, last))
        cell["episodes"].append(int(run.episodes[-1]))
    for n_req, budget in sorted({(r.fields["n_req"], _budget(r)) for r in runs}):
        subset = [r for r in runs if r.fields["n_req"] == n_req and _budget(r) == budget]
        played = max(int(r.episodes[-1]) for r in subset)
        for run in ccea:
            if run.fields["n_req"] == n_req:
                subset.append(_first_episodes(run, played))
                subset[-1].group = f"{run.fields['method']} (CCEA)"
        smooth = 20 if budget == 25000 else 100
        table = plots.curve_table(subset, smooth=smooth)
        suffix = "" if budget == 25000 else f"_{budget}"
        plots.plot_curves(table, OUT / f"marl_curves_nreq{n_req}{suffix}.png",
                          f"15 rovers, 4 POIs, n_req = {n_req}", x="episodes")  # fmt: skip
    lines = [
        "| n_req | method | episodes | final G (mean +- 95% CI) | seeds that learn | "
        "max critic after as many episodes |",
        "|---|---|---|---|---|---|",
    ]
    csv_rows = []
    for (method, n_req), c in sorted(cells.items(), key=lambda kv: (kv[0][1], kv[0][0])):
        mean, ci, k = plots.mean_ci(np.array(c["final"]))
        episodes = min(c["episodes"])
        learned = float(np.mean(np.array(c["final"]) > 0.5))
        reference = _max_critic_at(n_req, episodes)
        lines.append(f"| {n_req} | {method} | {episodes} | {float(mean):.2f} +- {float(ci):.2f}"
                     f" | {learned:.0%} of {k} | {reference} |")  # fmt: skip
        csv_rows.append({"method": method, "n_req": n_req, "episodes": episodes,
                         "final_G": float(mean), "ci95": float(ci), "seeds": k,
                         "learned": learned, "max_critic_same_episodes": reference})  # fmt: skip
    (OUT / "marl.md").write_text("\n".join(lines) + "\n")
    with open(OUT / "marl.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(csv_rows[0]))
        writer.writeheader()
        writer.writerows(csv_rows)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--root", default="runs/sweeps")
    parser.add_argument("--last", type=int, default=50)
    args = parser.parse_args()
    root = Path(args.root)
    OUT.mkdir(parents=True, exist_ok=True)
    previous_rows = []
    if (OUT / "runs.csv").exists():
        with open(OUT / "runs.csv", newline="") as f:
            previous_rows = list(csv.DictReader(f))
        for row in previous_rows:  # written before runs.csv had these columns
            row.setdefault("feedback", "D")
            row.setdefault("variant", "")
            row.setdefault("code", "")  # (and before runs recorded their provenance)
            row.setdefault("cpu", "")
    summary_rows = []
    cell_sections: dict[str, list[str]] = {}  # sweep -> its lines of cells.md

    def summarise(name: str, runs: list[plots.Run], cell_fields: tuple[str, ...], key=None,
                  variant_fields: tuple[str, ...] = (), kept: list[dict] = ()):  # fmt: skip
        """Rows of runs.csv and a table of cells.md; the ``variant`` column names the
        ``variant_fields`` a sweep varies beyond the method. ``kept``: rows of runs.csv of
        runs not on disk, pooled into the cells (``cell_fields`` must be columns) and
        written again."""
        cells = defaultdict(list)
        first = len(summary_rows)
        for row in kept:
            cells[tuple(_column(row, f) for f in cell_fields)].append(float(row["final_G"]))
            summary_rows.append(row)
        for run in runs:
            rows = read_metrics(run.path / "metrics.csv")
            final = final_score(run, args.last)
            cell = key(run) if key else tuple(run.fields[f] for f in cell_fields)
            cells[cell].append(final)
            summary_rows.append(
                {
                    "sweep": name,
                    "run": run.path.name,
                    "method": run.fields["method"],
                    "variant": variant(run, variant_fields),
                    "feedback": run.fields["feedback"],
                    "n_req": run.fields["n_req"],
                    "n_rovers": run.fields["n_rovers"],
                    "motion": motion_label(run),
                    "seed": run.fields["seed"],
                    "generations": len(rows),
                    "final_G": round(final, 4),
                    "max_eval_G": float(run.eval_G.max()),
                    "wall_seconds": round(rows[-1]["wall_seconds"], 1),
                    **provenance_columns(run.path),
                }
            )
        if kept:  # kept and found runs in the order of a sweep found whole (find_runs')
            summary_rows[first:] = sorted(summary_rows[first:], key=lambda row: row["run"])
        cell_lines = cell_sections.setdefault(name, [])
        cell_lines.append(f"\n### {name}\n")
        header = " | ".join(cell_fields)
        cell_lines.append(f"| {header} | final G (mean +- 95% CI) | seeds |")
        cell_lines.append("|" + "---|" * (len(cell_fields) + 2))
        for cell in sorted(cells, key=lambda c: c if isinstance(c, tuple) else (c,)):
            mean, ci, n = plots.mean_ci(np.array(cells[cell]))
            cols = " | ".join(str(c) for c in cell) if isinstance(cell, tuple) else cell
            cell_lines.append(f"| {cols} | {float(mean):.2f} +- {float(ci):.2f} | {n} |")

    def pooled_rows(name: str, runs: list[plots.Run]) -> list[dict]:
        """The committed rows of a :data:`POOLED` sweep's finished runs not found on disk
        (none for another sweep)."""
        return _kept_finals(previous_rows, name, runs) if name in POOLED else []

    def left_as_committed(name: str) -> bool:
        """Whether a :data:`POOLED` sweep is skipped because ``--last`` is not its committed
        rows': their finals cannot be pooled with others, nor dropped (said so)."""
        if name not in POOLED or args.last == POOLED_LAST or not (root / name).exists():
            return False
        print(f"{name}: --last {args.last} is not the committed rows' {POOLED_LAST}: its "
              "rows, table and figures are left as they are")  # fmt: skip
        return True

    # fig4-7 (800 generations) and fig4-7-long (the paper's 5000): the same grid.
    for name, prefix, smooth in (("fig4-7", "", 20), ("fig4-7-long", "long_", 100)):
        fig = root / name
        if not fig.exists():
            continue
        runs = [r for r in plots.load_runs(find_runs([fig])) if len(r.eval_G)]  # started
        gens = max(len(r.eval_G) for r in runs)
        for n_req in sorted({r.fields["n_req"] for r in runs}):
            subset = regroup([r for r in runs if r.fields["n_req"] == n_req], ())
            table = plots.curve_table(subset, smooth=smooth)
            plots.plot_curves(
                table,
                OUT / f"fig4-6_{prefix}curves_nreq{n_req}.png",
                f"15 rovers, 4 POIs, n_req = {n_req}, {gens} generations "
                f"({smooth}-generation moving mean)",
            )
        regroup(runs, ())
        plots.plot_final(
            plots.final_table(runs, "n_req", last=args.last),
            OUT / f"fig7_{prefix}final_vs_nreq.png",
            "n_req",
            f"15 rovers, 4 POIs, {gens} generations: final score (last {args.last})",
        )
        summarise(name, runs, ("method", "n_req"))

    # fig8-9 (400 generations), fig8-9-long (2000) and fig8-9-paper (5000): the same grid.
    for name, prefix in (("fig8-9", ""), ("fig8-9-long", "long_"), ("fig8-9-paper", "paper_")):
        fig = root / name
        if not fig.exists() or left_as_committed(name):
            continue
        # finished runs only: their rows are final scores that later machines keep
        runs = [r for r in plots.load_runs(find_runs([fig])) if len(r.eval_G) and _finished(r.path)]
        if not runs:
            continue
        gens = max(len(r.eval_G) for r in runs)
        kept = pooled_rows(name, runs)
        gens = max([gens, *(int(row["generations"]) for row in kept)])
        regroup(runs, ())
        g_max = max(r.g_max for r in runs)
        for n_req in sorted(
            {r.fields["n_req"] for r in runs} | {_column(r, "n_req") for r in kept}
        ):
            subset = [r for r in runs if r.fields["n_req"] == n_req]
            rows = [row for row in kept if _column(row, "n_req") == n_req]
            plots.plot_final(
                _final_scores(subset, rows, "n_rovers", args.last, g_max),
                OUT / f"fig8-9_{prefix}final_vs_rovers_nreq{n_req}.png",
                "n_rovers",
                f"4 POIs, n_req = {n_req}, {gens} generations: final score (last {args.last})",
            )
        summarise(name, runs, ("method", "n_req", "n_rovers"), kept=kept)

    fig = root / "physics"
    if fig.exists():
        runs = plots.load_runs(find_runs([fig]))
        for run in runs:
            run.group = f"{run.fields['method']} {motion_label(run)}"
        for n_req in sorted({r.fields["n_req"] for r in runs}):
            subset = [r for r in runs if r.fields["n_req"] == n_req]
            table = plots.curve_table(subset, smooth=20)
            plots.plot_curves(
                table,
                OUT / f"physics_curves_nreq{n_req}.png",
                f"ideal vs physical motion, n_req = {n_req}",
            )
        plots.plot_final(
            plots.final_table(runs, "n_req", last=args.last),
            OUT / "physics_final_vs_nreq.png",
            "n_req",
            f"ideal vs physical motion: final score (last {args.last} gens)",
        )
        summarise(
            "physics",
            runs,
            ("method", "n_req", "motion"),
            key=lambda r: f"{r.fields['method']} | {r.fields['n_req']} | {motion_label(r)}",
        )

    def finished_runs(name: str) -> list[plots.Run]:
        """The finished runs of sweep ``name`` under --root ([] if it is not there)."""
        if not (root / name).exists():
            return []
        runs = [r for r in plots.load_runs(find_runs([root / name])) if len(r.eval_G)]
        return [r for r in runs if _finished(r.path)]

    def curves_and_finals(name: str, runs: list[plots.Run], curves: str | None, final: str,
                          smooth: int = 20):  # fmt: skip
        """``NAME_curves_nreqN.png`` per n_req (titled ``curves`` + n_req; none if None;
        ``smooth``-generation moving means) and ``NAME_final_vs_nreq.png`` (titled
        ``final``), with their CSVs."""
        if curves is not None:
            for n_req in sorted({r.fields["n_req"] for r in runs}):
                subset = [r for r in runs if r.fields["n_req"] == n_req]
                plots.plot_curves(
                    plots.curve_table(subset, smooth=smooth),
                    OUT / f"{name}_curves_nreq{n_req}.png",
                    f"{curves}, n_req = {n_req}",
                )
        plots.plot_final(
            plots.final_table(runs, "n_req", last=args.last),
            OUT / f"{name}_final_vs_nreq.png",
            "n_req",
            f"{final}: final score (last {args.last} generations)",
        )

    # Issue 14: idealised vs physical motion at 5000 generations. The idealised twins (same
    # method, n_req and seed) of a method are physics-long-ideal's runs where it has them
    # (the same commit and machine as the physical runs), else fig4-7-long's; they are
    # listed again under this sweep's name (motion "ideal") so its table compares the three
    # models on equal seeds.
    def motion_cell(run: plots.Run) -> tuple:
        """A physical run's cell, as runs.csv's method, n_req and motion columns read."""
        return run.fields["method"], run.fields["n_req"], motion_label(run)

    physical = finished_runs("physics-long")
    if physical:
        twins = _twins(physical, finished_runs("physics-long-ideal"), finished_runs("fig4-7-long"))
        runs = physical + twins
        for run in runs:
            run.group = f"{run.fields['method']} {motion_label(run)}"
        curves_and_finals("physics-long", runs, "ideal vs physical motion, 5000 generations",
                          "ideal vs physical motion", smooth=100)  # fmt: skip
        summarise("physics-long", runs, ("method", "n_req", "motion"), key=motion_cell)
    # Its third method, the mean critic, run later as a sweep of its own (physics-long's run
    # directories did not survive their machine): the paper-claims file sets its rows against
    # physics-long's max critic and fig4-7-long's idealised mean critic.
    # It runs in chunks of seeds across machines (POOLED): final scores only.
    runs = [] if left_as_committed("physics-long-mean") else finished_runs("physics-long-mean")
    if runs:
        for run in runs:
            run.group = f"{run.fields['method']} {motion_label(run)}"
        kept = pooled_rows("physics-long-mean", runs)
        plots.plot_final(
            _final_scores(runs, kept, "n_req", args.last, max(r.g_max for r in runs),
                          row_group=lambda row: f"{row['method']} {row['motion']}"),
            OUT / "physics-long-mean_final_vs_nreq.png",
            "n_req",
            f"the mean critic under physical motion: final score (last {args.last} generations)",
        )  # fmt: skip
        summarise("physics-long-mean", runs, ("method", "n_req", "motion"), key=motion_cell,
                  kept=kept)  # fmt: skip

    # Issue 13: D++ as the feedback (experiment 1) and random POI layouts (experiment 2).
    runs = finished_runs("dpp")
    if runs:
        for run in runs:
            run.group = f"{run.fields['method']} on {run.fields['feedback']}"
        curves_and_finals("dpp", runs, "D and the max critic on D or D++",
                          "D++ vs D as the feedback")  # fmt: skip
        summarise("dpp", runs, ("method", "feedback", "n_req"))
    runs = finished_runs("ring-random")
    if runs:
        regroup(runs, ())
        curves_and_finals("ring-random", runs, "random POI angles (one layout per generation)",
                          "random POI layouts")  # fmt: skip
        summarise("ring-random", runs, ("method", "n_req"))
    # Issue 16, part 3: the stronger-critic screen (compare with the ablation's paper row).
    runs = finished_runs("stronger-critic")
    if runs:
        regroup(runs, ("critic_step_input", "critic_top_k"))
        curves_and_finals("stronger-critic", runs, None, "max critic variants")
        summarise("stronger-critic", runs, ("critic_step_input", "critic_top_k", "n_req"))
    # Issue 16: the optimistic ensemble (part 3) and trained output weights (part 2), each
    # with variants of the paper's max critic (the latter with the paper's as its control).
    for name, fields in (("stronger-critic-ensemble", ("critic_ensemble", "critic_optimism")),
                         ("ablation-output-weights", ("critic_output_weights",))):  # fmt: skip
        runs = finished_runs(name)
        if runs:
            regroup(runs, fields)
            curves_and_finals(name, runs, None, "max critic variants")
            summarise(name, runs, (*fields, "n_req"), variant_fields=fields)

    if (root / "ablation").exists():
        ablation_table(root / "ablation", args.last)
    marl_sweeps = [root / n for n in ("marl", "maddpg-check", "maddpg-grid", "mappo-long")
                   if (root / n).exists()]  # fmt: skip
    if marl_sweeps:
        marl_table(marl_sweeps, args.last, finished_runs("fig4-7-long"))
    if not summary_rows:
        if (root / "ablation").exists() or marl_sweeps or any(map(left_as_committed, POOLED)):
            return
        raise SystemExit(f"no sweeps found under {root}")
    # Sweeps not present under --root keep their rows and tables from the previous run.
    kept_rows = [row for row in previous_rows if row["sweep"] not in cell_sections]
    if (OUT / "cells.md").exists():
        for section in (OUT / "cells.md").read_text().split("\n### ")[1:]:
            name, body = section.split("\n", 1)
            cell_sections.setdefault(name.strip(), [f"\n### {name.strip()}\n", body.strip("\n")])
    order = ["fig4-7", "fig4-7-long", "fig8-9", "fig8-9-long", "fig8-9-paper", "physics",
             "physics-long", "physics-long-mean", "dpp", "ring-random", "stronger-critic",
             "stronger-critic-ensemble", "ablation-output-weights"]  # fmt: skip
    rows = sorted(kept_rows + summary_rows, key=lambda r: order.index(r["sweep"]))
    with open(OUT / "runs.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(summary_rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    lines = [line for name in order for line in cell_sections.get(name, [])]
    (OUT / "cells.md").write_text("\n".join(lines) + "\n")
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()
