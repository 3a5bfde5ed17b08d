"""A sweep's results rebuilt from its run directories: ``physrover results SWEEP_DIR...``.

For each sweep directory (``ROOT/NAME``, as ``physrover sweep`` makes it) this writes into
``out``:

- ``runs.csv``: one row per finished run: ``sweep``, ``run``, ``method``, the sweep's other
  grid fields (the config fields its runs differ in, seed aside), ``seed``, ``generations``,
  ``final_G`` (mean eval G of the last ``last`` generations, to 4 decimals), ``max_eval_G``,
  ``wall_seconds``, and the ``code`` and ``cpu`` that trained it (:func:`provenance_columns`);
- ``cells.md`` and ``cells.csv``: per sweep and cell of its grid, the final G's mean and
  Student-t 95% CI over seeds and their number;
- ``NAME_significance.md`` and ``.csv``: the planned comparisons of the sweep's file
  (``[[comparisons]]``, read from the copy ``physrover sweep`` keeps in the sweep's folder;
  :mod:`physrover.analysis.comparisons`), Holm over all of them;
- ``NAME_curves.png`` (learning curves, a group per cell; ``smooth``-generation moving
  mean) and, for each numeric grid field F that some cell of the other fields has two
  values of, ``NAME_final_vs_F.png`` (final score against F, a group per cell of the
  other fields), each with the plotted numbers as CSV beside it.

**Pooling across machines**: a sweep too long for one machine runs in chunks of seeds
(``physrover sweep FILE --seeds 0:5`` here, ``--seeds 5:10`` elsewhere) whose run
directories never meet. Rows of ``out/runs.csv`` (the file an earlier machine wrote, e.g.
committed) of finished runs of the same sweep that are not found on disk are kept: counted
in the cells and the final-score figures, and written again. Learning curves need the runs
themselves. A row counts as finished when it has the most generations of any run of its
sweep. Unfinished runs on disk are left out, and said so.
"""

from __future__ import annotations

import csv
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from physrover.analysis import plots
from physrover.analysis.curve_data import (
    Run,
    differing_fields,
    final_score,
    format_value,
    load_runs,
    run_fields,
    scores_table,
)
from physrover.core.stats import mean_ci
from physrover.experiment.provenance import read_provenance
from physrover.experiment.store import RunError, find_runs, read_metrics
from physrover.experiment.sweep import RunSpec, run_status

LEAD = ["sweep", "run", "method"]
TAIL = ["seed", "generations", "final_G", "max_eval_G", "wall_seconds", "code", "cpu"]
CELL_COLUMNS = ["sweep", "cell", "mean", "ci95_half_width", "n"]


def provenance_columns(run_dir: Path) -> dict[str, str]:
    """runs.csv's ``code`` and ``cpu`` of a run from its provenance.json: the first 12 hex
    digits of each distinct source fingerprint its segments were trained with, and each
    distinct CPU numba compiled for, in order, joined by ``+``; ``?+`` in front when the
    generations before the first segment are of unknown code (a run begun before runs
    recorded provenance); both empty for a run with no provenance.json."""
    segments = read_provenance(run_dir)
    if not segments:
        return {"code": "", "cpu": ""}
    unknown = "?+" if segments[0]["from_generation"] > 0 else ""
    codes = dict.fromkeys((s["code"] or "?")[:12] for s in segments)
    cpus = dict.fromkeys(s.get("llvm_cpu") or "?" for s in segments)
    return {"code": unknown + "+".join(codes), "cpu": unknown + "+".join(cpus)}


def is_finished(run_dir: Path) -> bool:
    """Whether a run (CCEA or trainer) has checkpointed the length its config asks for."""
    spec = RunSpec(run_dir.name, (Path(run_dir) / "config.toml").read_text(), str(run_dir))
    return run_status(spec) == "done"


def kept_rows(previous: list[dict], sweep: str, found: list[Run]) -> list[dict]:
    """The rows of ``previous`` (an earlier runs.csv) of ``sweep``'s finished runs that are
    not among the ``found`` finished run directories, one per run: a row is finished when
    it has the most generations of any run of the sweep, found or kept."""
    names = {run.path.name for run in found}
    mine = {r["run"]: r for r in previous if r["sweep"] == sweep and r["run"] not in names}
    full = max([len(run.eval_G) for run in found] + [int(r["generations"]) for r in mine.values()])
    return [row for row in mine.values() if int(row["generations"]) == full]


def run_row(sweep: str, run: Run, grid: list[str], last: int) -> dict:
    """A run's row of runs.csv (config values as group labels write them)."""
    rows = read_metrics(run.path / "metrics.csv")
    return {
        "sweep": sweep,
        "run": run.path.name,
        "method": run.fields["method"],
        **{name: format_value(run.fields.get(name, "")) for name in grid},
        "seed": run.fields["seed"],
        "generations": len(rows),
        "final_G": round(final_score(run, last), 4),
        "max_eval_G": float(np.nanmax(run.eval_G)),
        "wall_seconds": round(rows[-1]["wall_seconds"], 1),
        **provenance_columns(run.path),
    }


@dataclass
class SweepResults:
    """What :func:`sweep_results` made of one sweep."""

    name: str
    grid: list[str]
    """The fields (besides ``method``) whose values make the sweep's cells."""
    rows: list[dict]
    """runs.csv rows: the finished runs found, and the kept rows of earlier machines."""
    runs: list[Run]
    kept: int = 0
    messages: list[str] = field(default_factory=list)

    def cells(self) -> dict[tuple[str, ...], list[float]]:
        """{(method, grid values...): final scores}, cells in natural order."""
        found: dict[tuple[str, ...], list[float]] = defaultdict(list)
        for row in self.rows:
            found[tuple(str(row[f]) for f in ("method", *self.grid))].append(float(row["final_G"]))
        return dict(sorted(found.items()))


def sweep_results(sweep_dir: Path, previous: list[dict], last: int) -> SweepResults:
    """The finished runs of ``sweep_dir`` (named by its folder) and the kept rows of
    ``previous`` (:func:`kept_rows`); raises RunError when neither has a run."""
    sweep_dir = Path(sweep_dir)
    name = sweep_dir.name
    run_dirs = find_runs([sweep_dir])
    finished = [path for path in run_dirs if is_finished(path)]
    runs = [r for r in load_runs(finished) if len(r.eval_G)]
    messages = []
    if len(finished) < len(run_dirs):
        messages.append(f"{name}: {len(run_dirs) - len(finished)} of {len(run_dirs)} runs are "
                        "not finished and are left out")  # fmt: skip
    grid = [f for f in differing_fields([r.fields for r in runs]) if f != "seed"]
    earlier = [row for row in previous if row.get("sweep") == name]
    missing = sorted({f for f in ("method", *grid) for row in earlier if f not in row})
    if missing:
        messages.append(f"{name}: the earlier rows lack {', '.join(missing)}; not pooled")
        earlier = []
    kept = kept_rows(earlier, name, runs) if earlier else []
    if not runs and not kept:
        raise RunError(f"{sweep_dir}: no finished run (nor earlier rows of sweep {name})")
    if kept:  # the earlier rows' grid, then any field only the runs found here vary in (a
        # chunk whose finished runs are all of one cell varies in none)
        theirs = [c for c in kept[0] if c not in LEAD + TAIL]
        grid = theirs + [f for f in grid if f not in theirs]
    rows = sorted([*kept, *(run_row(name, run, grid, last) for run in runs)],
                  key=lambda row: row["run"])  # fmt: skip
    return SweepResults(name, grid, rows, runs, len(kept), messages)


def cells_markdown(result: SweepResults) -> tuple[str, list[dict]]:
    """cells.md's section of a sweep, and its cells.csv rows."""
    columns = ["method", *result.grid]
    lines = [f"\n### {result.name}\n", f"| {' | '.join(columns)} | final G (mean +- 95% CI) "
             "| seeds |", "|" + "---|" * (len(columns) + 2)]  # fmt: skip
    rows = []
    for cell, scores in result.cells().items():
        mean, ci, n = mean_ci(np.array(scores))
        lines.append(f"| {' | '.join(cell)} | {float(mean):.2f} +- {float(ci):.2f} | {n} |")
        rows.append({"sweep": result.name, "cell": " ".join(cell), "mean": float(mean),
                     "ci95_half_width": float(ci), "n": n})  # fmt: skip
    return "\n".join(lines) + "\n", rows


def _numeric(values) -> bool:
    try:
        [float(v) for v in values]
    except ValueError:
        return False
    return not {str(v).lower() for v in values} & {"true", "false"}


def figures(result: SweepResults, out: Path, last: int, smooth: int) -> list[Path]:
    """``NAME_curves.png`` of the runs found and ``NAME_final_vs_F.png`` for each numeric
    grid field F (runs and kept rows) that takes two values or more with the other fields
    fixed (not a field only one variant sets, such as a critic's size)."""
    made = []
    if result.runs:
        table = plots.curve_table(result.runs, smooth=smooth)
        unit = plots.row_unit(run.fields["method"] for run in result.runs)
        title = f"{result.name}: {smooth}-{unit} moving mean" if smooth > 1 else result.name
        made.append(plots.plot_curves(table, out / f"{result.name}_curves.png", title))
    g_max = max((run.g_max for run in result.runs), default=float("nan"))
    for x in result.grid:
        if not _numeric(row[x] for row in result.rows):
            continue
        scores: dict[str, dict[float, list[float]]] = defaultdict(lambda: defaultdict(list))
        for row in result.rows:
            group = " ".join([row["method"], *(f"{f}={row[f]}" for f in result.grid if f != x)])
            scores[group][float(row[x])].append(float(row["final_G"]))
        if all(len(by_x) < 2 for by_x in scores.values()):
            continue  # F changes only with the variant (a method's own field): no trend to draw
        shared = {group: (g_max, group.split()[0]) for group in scores}
        png = out / f"{result.name}_final_vs_{x}.png"
        title = f"{result.name}: final score (last {last} generations)"
        plots.plot_final(scores_table(x, scores, shared), png, x, title, last=last)
        made.append(png)
    return made


def _planned(sweep_dir: Path, result: SweepResults, out: Path) -> list[str]:
    """The sweep's planned comparisons (``[[comparisons]]`` of the copy of its file in its
    folder) over its finished runs: :func:`write_planned`."""
    from physrover.experiment.sweep import SWEEP_COPY, Sweep

    copy = sweep_dir / SWEEP_COPY
    if not copy.is_file():
        return []
    try:
        sweep = Sweep.load(copy)
    except Exception as exc:  # e.g. its imports, relative to where the file was
        return [f"{result.name}: planned comparisons not made: {copy}: {exc}"]
    found = {run.path.name: run for run in result.runs}
    runs = []  # each finished run's fields: its own config, or an earlier machine's row
    for row in result.rows:
        run = found.get(row["run"])
        fields = {k: format_value(v) for k, v in run.fields.items()} if run else dict(row)
        runs.append({**fields, "final_G": row["final_G"]})
    return write_planned(runs, sweep, result.name, ["method", *result.grid], out)


def write_planned(runs: list[dict], sweep, name: str, grid: list[str], out: Path) -> list[str]:
    """``NAME_significance.csv`` and ``.md`` in ``out``: ``sweep``'s planned comparisons
    (:mod:`physrover.analysis.comparisons`, Holm over all) over ``runs`` (each run's
    fields and ``final_G``) in the cells of ``grid``; the messages to show."""
    from physrover.analysis.comparisons import COLUMNS, planned_comparisons
    from physrover.analysis.tables import comparisons_markdown, write_csv

    if not sweep.comparisons:
        return []
    defaults = {k: format_value(v) for k, v in run_fields(sweep.base).items()}
    rows, skipped = planned_comparisons(runs, sweep.comparisons, defaults, grid)
    if not rows:
        return [*skipped, f"{name}: no planned comparison has 2 runs a side yet"]
    path = write_csv(rows, COLUMNS, out / f"{name}_significance.csv")
    path.with_suffix(".md").write_text(comparisons_markdown(rows))
    return [*skipped, f"{name}: {len(rows)} planned comparisons (Holm over all) in "
            f"{path.with_suffix('.md')}"]  # fmt: skip


def sweep_comparisons(rows: list[dict], sweep_file: str | Path, out: Path) -> list[str]:
    """A sweep file's planned comparisons over the rows of a runs.csv (``physrover
    compare``; no run directory needed): the rows of its sweep, in the cells of their grid
    columns (:func:`write_planned`)."""
    from physrover.experiment.sweep import Sweep

    sweep = Sweep.load(sweep_file)
    mine = [row for row in rows if row.get("sweep") == sweep.name]
    if not mine:
        raise RunError(f"the runs.csv has no row of sweep {sweep.name}")
    if not sweep.comparisons:
        raise RunError(f"{sweep_file}: the sweep file plans no [[comparisons]]")
    grid = [c for c in mine[0] if c not in LEAD + TAIL]
    out.mkdir(parents=True, exist_ok=True)  # (write_planned writes nothing without a row)
    return write_planned(mine, sweep, sweep.name, ["method", *grid], out)


def read_rows(path: Path) -> list[dict]:
    """The rows of a runs.csv ([] if there is none)."""
    if not Path(path).is_file():
        return []
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def write_results(sweep_dirs: list[Path], out: Path, last: int = 50,
                  smooth: int = 20) -> tuple[list[SweepResults], list[str]]:  # fmt: skip
    """Everything of the module docstring for ``sweep_dirs`` into ``out``; returns the
    sweeps' results and the messages to show. Rows of ``out/runs.csv`` of other sweeps stay
    (first, as they were); cells.md and cells.csv are those of ``sweep_dirs``."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    previous = read_rows(out / "runs.csv")
    results = [sweep_results(path, previous, last) for path in sweep_dirs]
    names = {r.name for r in results}
    rows = [row for row in previous if row.get("sweep") not in names]
    rows += [row for result in results for row in result.rows]
    columns = [*LEAD]
    for row in rows:
        columns += [c for c in row if c not in columns and c not in TAIL]
    columns += TAIL
    with open(out / "runs.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=columns, restval="")
        writer.writeheader()
        writer.writerows(rows)
    sections, cell_rows = [], []
    messages = [m for r in results for m in r.messages]
    for result in results:
        markdown, cells = cells_markdown(result)
        sections.append(markdown)
        cell_rows += cells
        figures(result, out, last, smooth)
        if result.kept:
            messages.append(f"{result.name}: {result.kept} finished runs of earlier machines "
                            f"pooled from {out / 'runs.csv'}")  # fmt: skip
    for path, result in zip(sweep_dirs, results, strict=True):
        messages += _planned(Path(path), result, out)
    (out / "cells.md").write_text("".join(sections))
    with open(out / "cells.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=CELL_COLUMNS)
        writer.writeheader()
        writer.writerows({k: repr(v) if isinstance(v, float) else v for k, v in row.items()}
                         for row in cell_rows)  # fmt: skip
    return results, messages
