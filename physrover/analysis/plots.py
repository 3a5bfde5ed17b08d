"""Learning curves and final scores with 95% confidence intervals over seeds, as figures.

The numbers come from :mod:`physrover.analysis.curve_data` (how runs are grouped, one
sample per seed, the Student-t 95% interval of the mean); its names are importable from
here too. The band is drawn clipped to the possible range of G, ``[0, sum of poi_values]``,
while the CSV keeps the raw interval. Every plot writes the plotted numbers as CSV beside
the PNG. matplotlib runs with the Agg backend.

For the command line, :func:`make_curves` and :func:`make_final` do everything (load, group,
tabulate, plot, CSV) and return a :class:`Plot` with the paths and the messages to show.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from physrover.analysis.curve_data import (
    CURVE_COLUMNS,
    NOT_GROUPED,
    Run,
    Table,
    curve_table,
    differing_fields,
    final_table,
    format_value,
    group_label,
    load_runs,
    training_episodes,
    write_csv,
)
from physrover.config import ConfigError
from physrover.core.stats import mean_ci, t975
from physrover.experiment.store import RunError

# ----------------------------------------------------------------------------------------------
# Figures
# ----------------------------------------------------------------------------------------------

# One colour per method in every figure (matplotlib's default cycle, in the order of the
# paper's Figs 4-7 first); groups that are not a bare method name take the cycle in order.
METHOD_COLOURS = {
    "D": "C0",
    "average": "C1",
    "max-critic": "C2",
    "mean-critic": "C3",
    "G": "C4",
    "leniency": "C5",
    "hall-of-fame": "C6",
    "max-critic-regular": "C7",
    "mean-critic-inexact": "C8",
    "gru-critic": "C9",
    "gru-sum-critic": "navy",
    "recurrent-max-critic": "black",
    "attention-critic": "darkgoldenrod",
}


def group_colours(groups, methods: dict[str, str | None] | None = None) -> dict[str, str | None]:
    """A colour per group: its method's own when every group has a known method and no two
    groups share one, else ``None`` for all (the axes' cycle), so a method keeps its colour
    across figures. ``methods``: {group: method}; by default a group's method is the group
    label itself if that is a bare method name."""
    groups = list(groups)
    methods = methods or {}
    of = {g: methods.get(g, g if g in METHOD_COLOURS else None) for g in groups}
    known = [m for m in of.values() if m in METHOD_COLOURS]
    if len(known) == len(groups) and len(set(known)) == len(known):
        return {g: METHOD_COLOURS[of[g]] for g in groups}
    if len(groups) > 10:  # beyond the axes' cycle of 10, which would repeat: 20 distinct
        from matplotlib import colormaps

        palette = colormaps["tab20"].colors
        return {g: palette[i % len(palette)] for i, g in enumerate(groups)}
    return dict.fromkeys(groups)


def band(
    mean: np.ndarray, ci: np.ndarray, g_max: float = math.inf
) -> tuple[np.ndarray, np.ndarray]:
    """The interval drawn: (low, high), each shaped like ``mean``, ``mean -+ ci`` clipped to
    the possible range of G, ``[0, g_max]`` (NaN where ``ci`` is NaN)."""
    mean, ci = np.asarray(mean, dtype=float), np.asarray(ci, dtype=float)
    return np.clip(mean - ci, 0.0, g_max), np.clip(mean + ci, 0.0, g_max)


def _axes(title: str):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.2), dpi=120)
    ax.set_title(title, fontsize=10)
    ax.set_ylabel("Mean performance score (G)")
    ax.grid(alpha=0.3)
    return fig, ax, plt


def _max_g_lines(ax, table: dict) -> None:
    """A dashed horizontal line at each distinct largest possible G, labelled ``max G``."""
    values = sorted({cols["g_max"] for cols in table.values() if "g_max" in cols})
    for v in values:
        label = "max G" if len(values) == 1 else f"max G = {v:g}"
        ax.axhline(v, color="0.4", linestyle="--", linewidth=1, label=label)


LEGEND_INSIDE_CHARS = 56
"""The longest legend entry kept inside the axes (8 points on the 6.4-inch figure): the
demo's ``max-critic (n=1, 20-generation moving mean)``, 44, fits, with room for a method's
feedback or a varied field."""


def _finish(fig, ax, plt, out: Path) -> None:
    """Legend, layout, save to ``out`` (creating its directory), close. More than five
    entries, or one longer than :data:`LEGEND_INSIDE_CHARS` (which inside the axes would
    run past the figure's edge), go beside the axes, the figure widened by the longest entry (about
    0.05 inch a character at 7 points), so the legend neither covers a curve nor squeezes
    the axes."""
    labels = ax.get_legend_handles_labels()[1]
    if len(labels) > 5 or max(map(len, labels), default=0) > LEGEND_INSIDE_CHARS:
        fig.set_size_inches(6.4 + max(2.6, 0.05 * max(map(len, labels))), 4.2)
        ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0)
    else:
        ax.legend(fontsize=8)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out)
    plt.close(fig)


def row_unit(methods) -> str:
    """What the metrics rows of runs of ``methods`` count: "iteration" when every one is a
    gradient-based trainer's, else "generation" (a CCEA's, or a mix)."""
    from physrover.core.registry import TRAINERS

    methods = set(methods)
    return "iteration" if methods and methods <= set(TRAINERS) else "generation"


def curve_legend(group: str, cols: dict) -> str:
    """A curve's legend entry: ``group (n=runs)``, plus the smoothing when there is some,
    e.g. ``max-critic (n=1, 20-generation moving mean)`` (``20-iteration`` for a
    gradient-based trainer, whose rows are iterations)."""
    smooth = int(cols.get("smooth", 1))
    unit = row_unit([cols.get("method")])
    note = f", {smooth}-{unit} moving mean" if smooth > 1 else ""
    return f"{group} (n={cols['n']}{note})"


def plot_curves(table: dict, out: Path, title: str = "", x: str = "generation") -> Path:
    """Mean performance score per generation (``x="episodes"``: per training episode, the
    axis on which learners of different sample costs compare) with 95% CI bands (like the
    paper's Figs 4-6), the band clipped to [0, max G], and a dashed line at max G; CSV
    beside ``out``."""
    if x not in ("generation", "episodes"):
        raise ConfigError("--x", f"must be generation or episodes, got {x!r}")
    out = Path(out)
    fig, ax, plt = _axes(title)
    colours = group_colours(table, {g: c.get("method") for g, c in table.items()})
    for group, cols in table.items():
        (line,) = ax.plot(
            cols[x], cols["mean"], label=curve_legend(group, cols), color=colours[group]
        )
        if cols["n"] > 1:
            low, high = band(cols["mean"], cols["ci"], cols.get("g_max", math.inf))
            ax.fill_between(cols[x], low, high, color=line.get_color(), alpha=0.2)
    _max_g_lines(ax, table)
    from matplotlib.ticker import MaxNLocator

    ax.xaxis.set_major_locator(MaxNLocator(integer=True))  # generations, episodes: whole
    unit = row_unit(c.get("method") for c in table.values())  # a trainer's rows: iterations
    ax.set_xlabel(unit.capitalize() if x == "generation" else "Training episodes")
    _finish(fig, ax, plt, out)
    write_csv(table, out.with_suffix(".csv"), "generation")
    return out


def plot_final(table: dict, out: Path, x: str, title: str = "", last: int | None = None) -> Path:
    """Final mean performance score against a config field (like the paper's Figs 7-9),
    error bars clipped to [0, max G], a dashed line at max G; CSV (raw CI) beside ``out``.
    ``last``: the generations each run's final score averages, named in the y label."""
    out = Path(out)
    fig, ax, plt = _axes(title)
    colours = group_colours(table, {g: c.get("method") for g, c in table.items()})
    for group, cols in table.items():
        low, high = band(cols["mean"], cols["ci"], cols.get("g_max", math.inf))
        yerr = np.nan_to_num(np.stack([cols["mean"] - low, high - cols["mean"]]))
        ax.errorbar(
            cols["x"],
            cols["mean"],
            yerr=yerr,
            marker="o",
            capsize=3,
            label=group,
            color=colours[group],
        )
    _max_g_lines(ax, table)
    values = np.concatenate([np.asarray(cols["x"], dtype=float) for cols in table.values()] or [[]])
    if len(values) and np.all(values == np.round(values)):  # n_req, n_rovers: whole ticks
        from matplotlib.ticker import MaxNLocator

        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_xlabel({"n_req": "Coupling (n_req)", "n_rovers": "Number of rovers"}.get(x, x))
    if last is not None:
        what = "last generation" if last <= 1 else f"mean of the last {last} generations"
        ax.set_ylabel(f"Final score: G, {what}")
    _finish(fig, ax, plt, out)
    write_csv(table, out.with_suffix(".csv"), x)
    return out


# ----------------------------------------------------------------------------------------------
# One call per command
# ----------------------------------------------------------------------------------------------


def default_title(runs: list[Run]) -> str:
    """What all ``runs`` share among n_rovers, n_req, motion and generations, e.g.
    ``15 rovers, n_req 3, ideal motion, 2000 generations`` ("" when nothing is shared)."""
    formats = {
        "n_rovers": "{} rovers",
        "n_req": "n_req {}",
        "motion": "{} motion",
        "generations": "{} generations",
    }
    parts = []
    for name, fmt in formats.items():
        values = {format_value(run.fields[name]) for run in runs}
        if len(values) == 1:
            parts.append(fmt.format(values.pop()))
    return ", ".join(parts)


def default_out(run_dirs: list[str | Path], final_field: str | None = None) -> Path:
    """Where a plot of ``run_dirs`` goes by default: ``curves.png`` (``final_FIELD.png`` with
    ``final_field``) inside the run directory for one run, else in the deepest directory
    holding all of them (their shared parent, e.g. ``runs/curves.png`` for ``runs/a`` and
    ``runs/b``; the current directory if they share none)."""
    name = f"final_{final_field}.png" if final_field else "curves.png"
    paths = [os.path.normpath(p) for p in run_dirs]
    if not paths:
        return Path(name)
    if len(set(paths)) == 1:
        return Path(paths[0]) / name
    try:
        common = os.path.commonpath(paths)
    except ValueError:  # absolute and relative paths mixed
        common = os.path.commonpath([str(Path(p).resolve()) for p in paths])
    return Path(common or ".") / name


@dataclass
class Plot:
    """What :func:`make_curves` / :func:`make_final` wrote, and what to tell the user."""

    png: Path
    csv: Path
    table: Table
    messages: list[str] = field(default_factory=list)


def _with_rows(runs: list[Run]) -> list[Run]:
    """``runs``, or a ConfigError naming them when none has a metrics row yet (an empty
    figure would say nothing)."""
    if not any(len(run.eval_G) for run in runs):
        names = ", ".join(str(run.path) for run in runs[:3]) + (" ..." if len(runs) > 3 else "")
        raise RunError(f"no generation in {names} yet: nothing to draw")
    return runs


def make_curves(
    run_dirs: list[str | Path],
    out: str | Path | None = None,
    *,
    by: tuple[str, ...] = (),
    smooth: int = 1,
    title: str | None = None,
    x: str = "generation",
) -> Plot:
    """Learning curves of ``run_dirs`` (``physrover curves``): group, tabulate, draw to
    ``out`` (default :func:`default_out`) with the CSV beside it, against generations or
    training episodes (``x``). ``title`` None: the :func:`default_title` of the runs."""
    runs = _with_rows(load_runs(run_dirs, by=by))
    table = curve_table(runs, smooth=smooth)
    png = Path(out) if out else default_out(run_dirs)
    plot_curves(table, png, default_title(runs) if title is None else title, x=x)
    return Plot(png, png.with_suffix(".csv"), table, list(table.messages))


def make_final(
    run_dirs: list[str | Path],
    x: str,
    out: str | Path | None = None,
    *,
    by: tuple[str, ...] = (),
    last: int = 1,
    title: str | None = None,
) -> Plot:
    """Final score against config field ``x`` (``physrover curves --final X``), like
    :func:`make_curves`; default output ``final_X.png`` (:func:`default_out`)."""
    runs = _with_rows(load_runs(run_dirs, by=by, x=x))
    table = final_table(runs, x, last=last)
    png = Path(out) if out else default_out(run_dirs, x)
    plot_final(table, png, x, default_title(runs) if title is None else title, last=last)
    return Plot(png, png.with_suffix(".csv"), table, list(table.messages))


__all__ = [  # with what physrover.analysis.curve_data computes, as this module had it before
    "CURVE_COLUMNS",
    "METHOD_COLOURS",
    "NOT_GROUPED",
    "Plot",
    "Run",
    "Table",
    "band",
    "curve_legend",
    "curve_table",
    "default_out",
    "default_title",
    "differing_fields",
    "final_table",
    "format_value",
    "group_colours",
    "group_label",
    "load_runs",
    "make_curves",
    "make_final",
    "mean_ci",
    "plot_curves",
    "plot_final",
    "t975",
    "training_episodes",
    "write_csv",
]
