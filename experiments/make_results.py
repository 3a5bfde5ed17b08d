"""Turn the paper's sweeps into the committed results (run from the repository root).

    python experiments/make_results.py [--root runs/sweeps] [--last 50]

This file holds this project's figure choices only: :data:`SWEEPS` says, per sweep, which
runs, grouped how, go into which figures with which titles, and which columns name its
cells; the ablation and MARL tables are the two tables of their own. What any sweep needs
(final scores, the code and CPU columns, the finished check, rows pooled across machines)
is the package's :mod:`physrover.analysis.results`; newer sweeps go through ``physrover
results`` alone.

Writes under experiments/results/: learning-curve PNGs with their CSVs (mean eval G and
95% CI half-width per generation, per group), final-score plots with CSVs, runs.csv (one
row per run: its cell, seed, final score, wall time, code and CPU) and cells.md (final mean
G +- 95% CI per cell, which RESULTS.md quotes). Sweeps missing under ``--root`` keep their
rows of runs.csv and their sections of cells.md, so sweeps can be re-made one at a time.
The ``pooled`` sweeps (fig8-9-paper, physics-long-mean: final scores only, run in chunks of
seeds on machines that do not keep each other's run directories) keep the committed rows
of their finished runs not on disk and pool them into their tables and figures (only with
``--last`` 50, the rows' own); any other sweep found on disk is made from what is there
alone. "Final score" is a run's mean eval G over its last ``--last`` generations; the CI is
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
from physrover.analysis.curve_data import Run, final_score, scores_table
from physrover.analysis.results import is_finished, kept_rows, provenance_columns
from physrover.analysis.tables import write_csv
from physrover.experiment.evaluate import motion_model
from physrover.experiment.store import find_runs, read_metrics

OUT = Path("experiments/results")
POOLED_LAST = 50
"""The ``--last`` of the committed rows' final scores; another ``--last`` pools nothing."""


def column(run: Run, field: str):
    """A run's value of a runs.csv column (``motion``: the motion model's name)."""
    if field == "motion":
        return motion_model(run.fields["motion"], run.fields["collisions"])
    return run.fields[field]


class _Values(dict):
    """Values a label template reads: a run's columns, or a runs.csv row's (booleans
    lower-case, as labels write them)."""

    def __init__(self, get):
        super().__init__()
        self.get_value = get

    def __missing__(self, field: str):
        value = self.get_value(field)
        return str(value).lower() if isinstance(value, bool) else value


def label(template: str, run: Run | dict) -> str:
    """``template`` filled with a run's (or a row's) values."""
    get = run.get if isinstance(run, dict) else lambda f: column(run, f)
    return template.format_map(_Values(get))


def fields_label(fields: tuple[str, ...]) -> str:
    """The template ``field={field} ...``."""
    return " ".join(f"{f}={{{f}}}" for f in fields)


@dataclasses.dataclass(frozen=True)
class Figures:
    """One sweep's outputs. Templates read a run's columns (:func:`column`); file names and
    titles also ``{n}`` (the n_req: one figure per n_req), ``{gens}`` (the sweep's most
    generations), ``{smooth}`` and ``{last}``."""

    name: str
    cells: tuple[str, ...]
    """cells.md's columns (runs.csv's), one cell per distinct value."""
    group: str = "{method}"
    """Figures' group label."""
    curves: str | None = None
    """Learning curves' file, one per n_req (none if None)."""
    curves_title: str = ""
    smooth: int = 20
    final: str = ""
    """Final-score figure's file, over ``final_x``."""
    final_x: str = "n_req"
    final_title: str = ""
    variant: tuple[str, ...] = ()
    """runs.csv's ``variant`` column: the fields a sweep varies beyond the method."""
    started: bool = False
    """Runs still going count too (their curves so far): fig4-7's."""
    twins: tuple[str, ...] = ()
    """Sweeps whose finished runs give this sweep's runs their idealised twins (same
    method, n_req and seed), the first sweep that has a twin giving it."""
    pooled: bool = False


def generic(name: str, group: str, curves: str | None, final: str, **kw) -> Figures:
    """A sweep's ``NAME_curves_nreqN.png`` and ``NAME_final_vs_nreq.png``."""
    return Figures(
        name, group=group, curves=curves and f"{name}_curves_nreq{{n}}.png",
        curves_title=f"{curves}, n_req = {{n}}", final=f"{name}_final_vs_nreq.png",
        final_title=f"{final}: final score (last {{last}} generations)", **kw,
    )  # fmt: skip


MOTION = "{method} {motion}"
CELLS_MOTION = ("method", "n_req", "motion")
STRONGER = ("critic_step_input", "critic_top_k")
ENSEMBLE = ("critic_ensemble", "critic_optimism")
SWEEPS = [
    *[Figures(name, ("method", "n_req"), started=True, smooth=smooth,
              curves=f"fig4-6_{p}curves_nreq{{n}}.png", curves_title="15 rovers, 4 POIs, "
              "n_req = {n}, {gens} generations ({smooth}-generation moving mean)",
              final=f"fig7_{p}final_vs_nreq.png",
              final_title="15 rovers, 4 POIs, {gens} generations: final score (last {last})")
      for name, p, smooth in (("fig4-7", "", 20), ("fig4-7-long", "long_", 100))],
    *[Figures(name, ("method", "n_req", "n_rovers"), pooled=name == "fig8-9-paper",
              final=f"fig8-9_{p}final_vs_rovers_nreq{{n}}.png", final_x="n_rovers",
              final_title="4 POIs, n_req = {n}, {gens} generations: final score (last {last})")
      for name, p in (("fig8-9", ""), ("fig8-9-long", "long_"), ("fig8-9-paper", "paper_"))],
    Figures("physics", CELLS_MOTION, MOTION, "physics_curves_nreq{n}.png",
            "ideal vs physical motion, n_req = {n}", final="physics_final_vs_nreq.png",
            started=True,
            final_title="ideal vs physical motion: final score (last {last} gens)"),
    # Issue 14: idealised vs physical motion at 5000 generations, the idealised twins listed
    # again under this sweep's name (motion "ideal") to compare the models on equal seeds;
    # its mean critic ran later as physics-long-mean (paper-claims sets the two side by side).
    generic("physics-long", MOTION, "ideal vs physical motion, 5000 generations",
            "ideal vs physical motion", cells=CELLS_MOTION, smooth=100,
            twins=("physics-long-ideal", "fig4-7-long")),
    generic("physics-long-mean", MOTION, None, "the mean critic under physical motion",
            cells=CELLS_MOTION, pooled=True),
    # Issue 13: D++ as the feedback, random POI layouts; issue 16: the stronger critics.
    generic("dpp", "{method} on {feedback}", "D and the max critic on D or D++",
            "D++ vs D as the feedback", cells=("method", "feedback", "n_req")),
    generic("ring-random", "{method}", "random POI angles (one layout per generation)",
            "random POI layouts", cells=("method", "n_req")),
    generic("stronger-critic", "{method} " + fields_label(STRONGER), None,
            "max critic variants", cells=(*STRONGER, "n_req")),
    *[generic(name, "{method} " + fields_label(fields), None, "max critic variants",
              cells=(*fields, "n_req"), variant=fields)
      for name, fields in (("stronger-critic-ensemble", ENSEMBLE),
                           ("ablation-output-weights", ("critic_output_weights",)))],
]  # fmt: skip


def load(root: Path, name: str, started: bool = False) -> list[Run]:
    """The finished runs of sweep ``name`` under ``root`` (with ``started``, every run that
    has a row); [] if the sweep is not there."""
    if not (root / name).exists():
        return []
    runs = [r for r in plots.load_runs(find_runs([root / name])) if len(r.eval_G)]
    return runs if started else [r for r in runs if is_finished(r.path)]


def twins(physical: list[Run], sources: list[list[Run]]) -> list[Run]:
    """For each (method, n_req, seed) of ``physical``, the run of the first source with it."""
    key = lambda r: (r.fields["method"], r.fields["n_req"], r.fields["seed"])  # noqa: E731
    by_cell = [{key(r): r for r in source} for source in sources]
    found = [next((runs[c] for runs in by_cell if c in runs), None)
             for c in sorted({key(r) for r in physical})]  # fmt: skip
    return [run for run in found if run is not None]


def as_column(row: dict, field: str):
    """A runs.csv value as the config field's type (ints for n_req, n_rovers, seed)."""
    return int(row[field]) if field in ("n_req", "n_rovers", "seed") else row[field]


def run_row(sweep: Figures, run: Run, last: int) -> dict:
    rows = read_metrics(run.path / "metrics.csv")
    return {
        "sweep": sweep.name, "run": run.path.name, "method": run.fields["method"],
        "variant": label(fields_label(sweep.variant), run), "feedback": run.fields["feedback"],
        "n_req": run.fields["n_req"], "n_rovers": run.fields["n_rovers"],
        "motion": column(run, "motion"), "seed": run.fields["seed"],
        "generations": len(rows), "final_G": round(final_score(run, last), 4),
        "max_eval_G": float(run.eval_G.max()), "wall_seconds": round(rows[-1]["wall_seconds"], 1),
        **provenance_columns(run.path),
    }  # fmt: skip


def make(sweep: Figures, runs: list[Run], kept: list[dict], last: int) -> tuple[list, list]:
    """One sweep's figures; its rows of runs.csv and its lines of cells.md."""
    for run in runs:
        run.group = label(sweep.group, run)
    g_max = max(r.g_max for r in runs)
    gens = max([len(r.eval_G) for r in runs] + [int(row["generations"]) for row in kept])
    text = {"gens": gens, "smooth": sweep.smooth, "last": last}
    n_reqs = sorted({r.fields["n_req"] for r in runs} | {as_column(r, "n_req") for r in kept})
    for n in n_reqs if sweep.curves else ():
        table = plots.curve_table([r for r in runs if r.fields["n_req"] == n], sweep.smooth)
        plots.plot_curves(table, OUT / sweep.curves.format(n=n),
                          sweep.curves_title.format(n=n, **text))  # fmt: skip
    for n in n_reqs if "{n}" in sweep.final else [None]:
        subset = [r for r in runs if n is None or r.fields["n_req"] == n]
        rows = [row for row in kept if n is None or as_column(row, "n_req") == n]
        scores: dict[str, dict] = defaultdict(lambda: defaultdict(list))
        for run in subset:
            scores[run.group][run.fields[sweep.final_x]].append(final_score(run, last))
        for row in rows:
            x = as_column(row, sweep.final_x)
            scores[label(sweep.group, row)][x].append(float(row["final_G"]))
        shared = {g: (max([r.g_max for r in subset if r.group == g], default=g_max), g)
                  for g in scores}  # fmt: skip
        table = scores_table(sweep.final_x, scores, shared) if rows else plots.final_table(
            subset, sweep.final_x, last=last)  # fmt: skip
        plots.plot_final(table, OUT / sweep.final.format(n=n), sweep.final_x,
                         sweep.final_title.format(n=n, **text))  # fmt: skip
    cells = defaultdict(list)
    for row in kept:
        cells[tuple(as_column(row, f) for f in sweep.cells)].append(float(row["final_G"]))
    for run in runs:
        cells[tuple(column(run, f) for f in sweep.cells)].append(final_score(run, last))
    found = [run_row(sweep, run, last) for run in runs]
    rows = sorted([*kept, *found], key=lambda row: row["run"]) if kept else found
    lines = [f"\n### {sweep.name}\n", f"| {' | '.join(sweep.cells)} | final G (mean +- 95% CI)"
             " | seeds |", "|" + "---|" * (len(sweep.cells) + 2)]  # fmt: skip
    for cell in sorted(cells):
        mean, ci, n = plots.mean_ci(np.array(cells[cell]))
        lines.append(f"| {' | '.join(map(str, cell))} | {float(mean):.2f} +- {float(ci):.2f}"
                     f" | {n} |")  # fmt: skip
    return rows, lines


ABLATED = ("method", "critic_lr", "critic_optimizer", "replay_pairs", "critic_hidden")
"""The fields the ablation changes, one at a time, from the paper's max critic."""


def ablation_table(runs: list[Run], last: int) -> None:
    """results/ablation.{md,csv}: per variant (what differs from the paper's max critic)
    and n_req, the final G (mean +- 95% CI over seeds), the critic's loss (mean squared
    error over the last ``last`` generations, mean over seeds) and the seeds and
    generations (``+`` when they differ)."""
    from physrover.config import LearnConfig
    from physrover.learn.configs import CriticConfig

    paper = {**LearnConfig(method="max-critic").to_dict(), **CriticConfig().to_dict()}
    cells = defaultdict(lambda: {"final": [], "loss": [], "gens": []})
    for run in runs:
        changed = [f"{f}={run.fields[f]}" for f in ABLATED if run.fields[f] != paper[f]]
        rows = read_metrics(run.path / "metrics.csv")
        loss = np.array([r["critic_loss"] for r in rows[-last:]], dtype=float)
        cell = cells[(", ".join(changed) or "the paper's max critic", run.fields["n_req"])]
        cell["final"].append(final_score(run, last))
        cell["loss"].append(float(np.nanmean(loss)) if np.isfinite(loss).any() else np.nan)
        cell["gens"].append(len(rows))
    n_reqs = sorted({n for _, n in cells})
    variants = sorted({v for v, _ in cells}, key=lambda v: (v != "the paper's max critic", v))
    head = " | ".join(f"n_req {n}: final G | loss | seeds, gens" for n in n_reqs)
    lines, csv_rows = [f"| variant | {head} |", "|---|" + "---|---|---|" * len(n_reqs)], []
    for v in variants:
        parts = []
        for n, c in ((n, cells.get((v, n))) for n in n_reqs):
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
    write_csv(csv_rows, list(csv_rows[0]), OUT / "ablation.csv")


def max_critic_at(n_req: int, episodes: int) -> str:
    """The max critic's mean eval G after ``episodes`` training episodes (50 a generation):
    fig4-7-long's curves (10 seeds, 100-generation moving mean), else fig4-7's (5, 20)."""
    for name in (f"fig4-6_long_curves_nreq{n_req}.csv", f"fig4-6_curves_nreq{n_req}.csv"):
        if (OUT / name).exists():
            with open(OUT / name, newline="") as f:
                rows = [r for r in csv.DictReader(f) if r["group"] == "max-critic"]
            first = int(rows[0]["generation"]) if rows else 1  # 0 in files of 0.1.0
            at = [r for r in rows if int(r["generation"]) - first + 1 == episodes // 50]
            if at:
                return f"{float(at[0]['mean']):.2f} +- {float(at[0]['ci95_half_width']):.2f}"
            return "n/a"
    return "n/a"


def budget(run: Run) -> int:
    """A gradient-based run's budget of training episodes (its config's)."""
    return int(run.fields[f"{run.fields['method']}.total_episodes"])


def trainer_label(run: Run) -> str:
    """A gradient-based run's group: its method and budget unless 25,000 episodes; MADDPG's
    with its warm-up, or marked as 0.1's (no ``action_penalty`` in its [maddpg] table: no
    penalty nor clipping, never pooled with the runs that had them)."""
    method, episodes = run.fields["method"], budget(run)
    if method == "maddpg" and "action_penalty" not in (run.path / "config.toml").read_text():
        method = "maddpg (0.1: no penalty, no clipping)"
    elif method == "maddpg":
        method = f"maddpg ({run.fields['maddpg.warmup_actions']} warm-up)"
    return method + ("" if episodes == 25000 else f", {episodes:,} episodes")


def marl_table(runs: list[Run], last: int, ccea: list[Run]) -> None:
    """results/marl.{md,csv} and marl_curves_nreq*.png (finished runs of the gradient-based
    sweeps): per method (:func:`trainer_label`) and n_req the final eval G (last ``last``
    iterations, 95% CI over seeds), the share of seeds that learn and the max critic after
    as many episodes; curves on training episodes, one figure per n_req and budget
    (``_250000`` appended unless 25,000), with the ``ccea`` runs of the n_req cut there."""
    cells = defaultdict(lambda: {"final": [], "episodes": []})
    for run in runs:
        run.group = trainer_label(run)
        cell = cells[(run.group, run.fields["n_req"])]
        cell["final"].append(final_score(run, last))
        cell["episodes"].append(int(run.episodes[-1]))
    for n_req, episodes in sorted({(r.fields["n_req"], budget(r)) for r in runs}):
        subset = [r for r in runs if r.fields["n_req"] == n_req and budget(r) == episodes]
        played = max(int(r.episodes[-1]) for r in subset)
        for run in (r for r in ccea if r.fields["n_req"] == n_req):
            keep = run.episodes <= played
            cut = dict(eval_G=run.eval_G[keep], episodes=run.episodes[keep],
                       generation=run.generation[keep])  # fmt: skip
            subset.append(dataclasses.replace(run, **cut))
            subset[-1].group = f"{run.fields['method']} (CCEA)"
        usual = episodes == 25000
        plots.plot_curves(plots.curve_table(subset, smooth=20 if usual else 100),
                          OUT / f"marl_curves_nreq{n_req}{'' if usual else f'_{episodes}'}.png",
                          f"15 rovers, 4 POIs, n_req = {n_req}", x="episodes")  # fmt: skip
    lines = ["| n_req | method | episodes | final G (mean +- 95% CI) | seeds that learn | "
             "max critic after as many episodes |", "|---|---|---|---|---|---|"]  # fmt: skip
    csv_rows = []
    for (method, n_req), c in sorted(cells.items(), key=lambda kv: (kv[0][1], kv[0][0])):
        mean, ci, k = plots.mean_ci(np.array(c["final"]))
        episodes, learned = min(c["episodes"]), float(np.mean(np.array(c["final"]) > 0.5))
        reference = max_critic_at(n_req, episodes)
        lines.append(f"| {n_req} | {method} | {episodes} | {float(mean):.2f} +- {float(ci):.2f}"
                     f" | {learned:.0%} of {k} | {reference} |")  # fmt: skip
        csv_rows.append({"method": method, "n_req": n_req, "episodes": episodes,
                         "final_G": float(mean), "ci95": float(ci), "seeds": k,
                         "learned": learned, "max_critic_same_episodes": reference})  # fmt: skip
    (OUT / "marl.md").write_text("\n".join(lines) + "\n")
    write_csv(csv_rows, list(csv_rows[0]), OUT / "marl.csv")


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--root", default="runs/sweeps")
    parser.add_argument("--last", type=int, default=50)
    args = parser.parse_args()
    root, last = Path(args.root), args.last
    OUT.mkdir(parents=True, exist_ok=True)
    previous = []
    if (OUT / "runs.csv").exists():
        with open(OUT / "runs.csv", newline="") as f:
            previous = list(csv.DictReader(f))
        for row in previous:  # written before runs.csv had these columns
            for name, default in (("feedback", "D"), ("variant", ""), ("code", ""), ("cpu", "")):
                row.setdefault(name, default)
    rows: dict[str, list[dict]] = {}  # sweep -> its rows of runs.csv
    sections: dict[str, list[str]] = {}  # sweep -> its lines of cells.md
    skipped = False
    for sweep in SWEEPS:
        if sweep.pooled and last != POOLED_LAST and (root / sweep.name).exists():
            print(f"{sweep.name}: --last {last} is not the committed rows' {POOLED_LAST}: "
                  "its rows, table and figures are left as they are")  # fmt: skip
            skipped = True
            continue
        runs = load(root, sweep.name, sweep.started)
        if runs and sweep.twins:
            runs += twins(runs, [load(root, name) for name in sweep.twins])
        if runs:
            kept = kept_rows(previous, sweep.name, runs) if sweep.pooled else []
            rows[sweep.name], sections[sweep.name] = make(sweep, runs, kept, last)
    if (root / "ablation").exists():
        ablation_table(load(root, "ablation"), last)
    marl = [r for n in ("marl", "maddpg-check", "maddpg-grid", "mappo-long") for r in load(root, n)]
    if marl:
        marl_table(marl, last, load(root, "fig4-7-long"))
    if not rows:
        if (root / "ablation").exists() or marl or skipped:
            return
        raise SystemExit(f"no sweeps found under {root}")
    # Sweeps not present under --root keep their rows and tables from the previous run.
    if (OUT / "cells.md").exists():
        for section in (OUT / "cells.md").read_text().split("\n### ")[1:]:
            name, body = section.split("\n", 1)
            sections.setdefault(name.strip(), [f"\n### {name.strip()}\n", body.strip("\n")])
    order = [sweep.name for sweep in SWEEPS]
    kept = [row for row in previous if row["sweep"] not in rows]
    found = [row for sweep in order for row in rows.get(sweep, [])]
    header = list(found[0])
    write_csv(sorted(kept + found, key=lambda r: order.index(r["sweep"])), header, OUT / "runs.csv")
    lines = [line for name in order for line in sections.get(name, [])]
    (OUT / "cells.md").write_text("\n".join(lines) + "\n")
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()
