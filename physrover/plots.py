"""Learning curves and final scores with 95% confidence intervals over seeds.

Runs are grouped so that only runs of one experiment are pooled: two runs share a group when
their configs are equal in every field except ``seed`` and the bookkeeping fields of
:data:`NOT_GROUPED`. A group is named by its method, then ``field=value`` for each field that
differs between the runs given (and each field named in ``by``), e.g.
``max-critic n_req=3 generations=2000``; a bare method name when only the method differs.
Within a group each run is one sample (one seed). The band is the Student-t 95% interval of
the mean, ``mean +- t_{0.975, n-1} * sd / sqrt(n)``; it is drawn clipped to the possible
range of G, ``[0, sum of poi_values]``, while the CSV keeps the raw interval. Every plot
writes the plotted numbers as CSV beside the PNG. matplotlib runs with the Agg backend.

For the command line, :func:`make_curves` and :func:`make_final` do everything (load, group,
tabulate, plot, CSV) and return a :class:`Plot` with the paths and the messages to show.
"""

from __future__ import annotations

import csv
import math
import os
import re
from collections import defaultdict
from dataclasses import dataclass, field
from functools import reduce
from pathlib import Path

import numpy as np

from physrover.config import ConfigError, DomainConfig, LearnConfig
from physrover.runs import METRICS, load_run_config, read_metrics
from physrover.stats import mean_ci, t975  # noqa: F401  (t975: part of this module's API)

NOT_GROUPED = ("seed", "checkpoint_every")
"""Config fields in which runs of one group may differ: the seed (each run is one sample)
and bookkeeping that does not change the experiment. Every other field splits groups,
``generations`` included (a 300- and a 2000-generation run are different experiments)."""


# ----------------------------------------------------------------------------------------------
# Loading and grouping runs
# ----------------------------------------------------------------------------------------------


@dataclass
class Run:
    """One run directory: its group label, config fields and learning curve."""

    path: Path
    group: str
    fields: dict
    """Every config field by bare name ([domain] then [learn])."""
    eval_G: np.ndarray
    """(G,) float: the champion team's mean eval G, one per metrics row."""
    generation: np.ndarray
    """(G,) int: the metrics' ``generation`` column for the same rows (1 = first)."""
    episodes: np.ndarray
    """(G,) int: training episodes the learner had played by the end of each row (the
    metrics' ``episodes`` column if it has one, else generation x the fitness method's
    episodes per generation, :func:`training_episodes`)."""

    @property
    def g_max(self) -> float:
        """The largest G possible in this run's domain: the sum of its POI values."""
        return float(sum(self.fields["poi_values"]))


def format_value(value) -> str:
    """A config value as written in a group label: ``true``, ``0.5``, ``1,2,3,4``."""
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, float):
        return f"{value:g}"
    if isinstance(value, (tuple, list)):
        return ",".join(format_value(v) for v in value)
    return str(value)


_FIELD_ORDER = DomainConfig.field_names() + LearnConfig.field_names()


def differing_fields(fields: list[dict], skip: tuple[str, ...] = ()) -> list[str]:
    """Names of the config fields (in config order) whose value is not the same in all of
    ``fields`` (one dict per run), leaving out ``method``, :data:`NOT_GROUPED` and ``skip``."""
    left_out = {"method", *NOT_GROUPED, *skip}
    # then a trainer's own fields (``mappo.lr``), which only some runs have
    extra = sorted({name for f in fields for name in f} - set(_FIELD_ORDER))
    return [
        name
        for name in (*_FIELD_ORDER, *extra)
        if name not in left_out and len({format_value(f.get(name)) for f in fields}) > 1
    ]


def group_label(fields: dict, names: list[str]) -> str:
    """``method name=value ...`` for a run's ``fields`` and the label fields ``names`` (a
    field the run does not have is left out)."""
    return " ".join(
        [fields["method"]] + [f"{n}={format_value(fields[n])}" for n in names if n in fields]
    )


def load_runs(
    run_dirs: list[str | Path], by: tuple[str, ...] = (), x: str | None = None
) -> list[Run]:
    """The runs with their group label (see the module docstring).

    ``by``: fields also named in every label (``--by``). ``x``: the field plotted on the x
    axis (``--final``): runs that differ in it are not split into groups by it.
    """
    paths = list(map(Path, run_dirs))
    configs = [load_run_config(path) for path in paths]
    all_fields = []
    for config in configs:
        fields = {**config.domain.to_dict(), **config.learn.to_dict()}
        if config.trainer is not None:  # a gradient-based run: its own table, by table.field
            section = config.trainer.section
            fields |= {f"{section}.{k}": v for k, v in config.trainer.to_dict().items()}
        all_fields.append(fields)
    for name, option in [(n, "--by") for n in by] + ([(x, "--final")] if x else []):
        if name not in _FIELD_ORDER:
            raise ConfigError(name, f"not a config field ({option})")
    split = set(differing_fields(all_fields, skip=(x,) if x else ())) | set(by)
    order = list(_FIELD_ORDER) + sorted(split - set(_FIELD_ORDER))
    names = [n for n in order if n in split and n not in ("method", x)]
    runs = []
    for path, config, fields in zip(paths, configs, all_fields, strict=True):
        rows = read_metrics(path / METRICS)
        eval_g = np.array([r["eval_G"] for r in rows], dtype=float)
        generation = np.array([r["generation"] for r in rows], dtype=np.int64)
        if rows and "episodes" in rows[0]:
            episodes = np.array([r["episodes"] for r in rows], dtype=np.int64)
        else:
            episodes = generation * training_episodes(config)
        label = group_label(fields, names)
        runs.append(Run(path, label, fields, eval_g, generation, episodes))
    return runs


def training_episodes(config) -> int:
    """Training episodes per CCEA generation: the fitness method's rounds x the population
    (k for D, G and the critics; n_samples x k for average and leniency; R x k for the hall
    of fame). The champion's evaluation episodes are a measurement and do not count."""
    from physrover.learn.fitness import Problem, make_method

    problem = Problem(config.domain.n_rovers, 1, 1, 1)  # sizes do not change the rounds
    method = make_method(config.learn, problem, np.random.default_rng(0))
    return method.rounds * config.learn.population


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


# ----------------------------------------------------------------------------------------------
# Tables
# ----------------------------------------------------------------------------------------------


class Table(dict):
    """``{group: {column: values}}`` in plotting order, plus ``x`` (the name of the x
    column: ``generation`` or a config field) and ``messages`` (notes for the user, e.g.
    runs cut to the shortest; the command line prints them to stderr)."""

    def __init__(self, x: str):
        super().__init__()
        self.x = x
        self.messages: list[str] = []


def _natural(label: str) -> list:
    """Sort key that orders numbers in a label by value (``n_req=3`` before ``n_req=10``)."""
    return [float(p) if i % 2 else p for i, p in enumerate(re.split(r"(\d+(?:\.\d+)?)", label))]


def _shared(runs: list[Run]) -> tuple[float, str | None]:
    """(G max, method) of a group: the largest sum of POI values over its runs, and the
    method if all its runs have the same one (else None)."""
    methods = {run.fields["method"] for run in runs}
    return max(run.g_max for run in runs), (methods.pop() if len(methods) == 1 else None)


def _smooth(y: np.ndarray, window: int) -> np.ndarray:
    """Trailing moving average over ``window`` generations (the first ones average fewer)."""
    if window <= 1:
        return y
    c = np.cumsum(np.insert(y, 0, 0.0, axis=-1), axis=-1)
    idx = np.arange(1, y.shape[-1] + 1)
    lo = np.maximum(idx - window, 0)
    return (c[..., idx] - c[..., lo]) / (idx - lo)


def _align(group: str, runs: list[Run], messages: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """(generation (L,), eval_G (n, L)) over the generations every run of the group has;
    appends a message to ``messages`` when that cuts any run."""
    common = reduce(np.intersect1d, [run.generation for run in runs])
    data = np.stack([run.eval_G[np.isin(run.generation, common)] for run in runs])
    lengths = [len(run.generation) for run in runs]
    if len(common) and max(lengths) > len(common):
        how = "the shortest" if min(lengths) == len(common) else "the generations all have"
        messages.append(
            f"{group}: {len(runs)} runs cut to {how}, {len(common)} generations "
            f"(longest {max(lengths)})"
        )
    return common, data


def curve_table(runs: list[Run], smooth: int = 1) -> Table:
    """{group: columns} over the generations every run of the group has (see ``_align``).

    Columns, L = generations kept, n = runs in the group: ``generation`` (L,) int from the
    metrics; ``mean``, ``ci`` (L,): mean and 95% CI half-width over runs of the curves
    smoothed by a trailing ``smooth``-generation moving mean (equal to ``raw_mean``,
    ``raw_ci`` when ``smooth`` <= 1); ``raw_mean``, ``raw_ci`` (L,): the same unsmoothed;
    ``n``, ``smooth`` ints; ``g_max`` (largest G possible) and ``method`` (None if mixed).
    """
    groups: dict[str, list[Run]] = defaultdict(list)
    for run in runs:
        groups[run.group].append(run)
    table = Table("generation")
    window = max(int(smooth), 1)
    for group in sorted(groups, key=_natural):
        generation, data = _align(group, groups[group], table.messages)
        if len(generation) == 0:
            table.messages.append(f"{group}: no generation shared by all its runs, left out")
            continue
        raw_mean, raw_ci, n = mean_ci(data)
        mean, ci, _ = mean_ci(_smooth(data, window)) if window > 1 else (raw_mean, raw_ci, n)
        g_max, method = _shared(groups[group])
        first = groups[group][0]
        table[group] = {
            "generation": generation,
            "episodes": first.episodes[np.isin(first.generation, generation)],
            "mean": mean,
            "ci": ci,
            "n": n,
            "raw_mean": raw_mean,
            "raw_ci": raw_ci,
            "smooth": window,
            "g_max": g_max,
            "method": method,
        }
    return table


def final_table(runs: list[Run], x: str, last: int = 1) -> Table:
    """{group: columns}: each run's final score, its mean eval G over its ``last``
    generations, averaged over the runs of a group with the same value of field ``x``.

    Columns, K = distinct values of ``x`` in the group: ``x``, ``mean``, ``ci``, ``n`` (K,);
    ``g_max`` and ``method`` as in :func:`curve_table`. Runs without generations are left
    out; a message names cells whose runs differ in length (each scored on its own end).
    """
    cells: dict[str, dict[float, list[Run]]] = defaultdict(lambda: defaultdict(list))
    table = Table(x)
    for run in runs:
        if x not in run.fields:
            raise ConfigError(x, "not a config field (--final)")
        if len(run.eval_G):
            cells[run.group][run.fields[x]].append(run)
        else:
            table.messages.append(f"{run.path}: no generations yet, left out")
    for group in sorted(cells, key=_natural):
        by_x = cells[group]
        xs = sorted(by_x)
        stats = []
        for v in xs:
            lengths = sorted(len(run.eval_G) for run in by_x[v])
            if lengths[0] != lengths[-1]:
                table.messages.append(
                    f"{group}, {x}={format_value(v)}: {len(lengths)} runs of {lengths[0]} to "
                    f"{lengths[-1]} generations, each scored on its own last {last}"
                )
            stats.append(mean_ci(np.array([run.eval_G[-last:].mean() for run in by_x[v]])))
        g_max, method = _shared([run for v in xs for run in by_x[v]])
        table[group] = {
            "x": np.array(xs, dtype=float),
            "mean": np.array([s[0] for s in stats]),
            "ci": np.array([s[1] for s in stats]),
            "n": np.array([s[2] for s in stats]),
            "g_max": g_max,
            "method": method,
        }
    return table


CURVE_COLUMNS = [
    "group",
    "generation",
    "episodes",
    "mean",
    "ci95_half_width",
    "n",
    "raw_mean",
    "raw_ci95_half_width",
    "smooth_window",
]
"""Columns of a learning-curve CSV: ``mean`` and ``ci95_half_width`` are of the curves
smoothed by a trailing ``smooth_window``-generation moving mean (1: unsmoothed), ``raw_*``
of the unsmoothed curves; every interval is raw (not clipped to the range of G)."""


def write_csv(table: dict, path: Path, x_name: str | None = None) -> None:
    """The table's numbers as CSV: :data:`CURVE_COLUMNS` for a curve table, else
    ``group, X, mean, ci95_half_width, n`` (X = ``x_name``, default the table's ``x``)."""
    x_name = x_name or getattr(table, "x", "x")
    curves = x_name == "generation"
    key = "generation" if curves else "x"

    def num(v) -> str:
        return repr(float(v))

    with open(path, "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(
            CURVE_COLUMNS if curves else ["group", x_name, "mean", "ci95_half_width", "n"]
        )
        for group, cols in table.items():
            n = np.broadcast_to(cols["n"], cols["mean"].shape)
            for i, (xv, m, c, k) in enumerate(
                zip(cols[key], cols["mean"], cols["ci"], n, strict=True)
            ):
                row = [group, str(int(xv)) if curves else f"{xv:g}", num(m), num(c), int(k)]
                if curves:
                    row.insert(2, int(cols["episodes"][i]) if "episodes" in cols else "")
                    raw_mean = cols.get("raw_mean", cols["mean"])[i]
                    raw_ci = cols.get("raw_ci", cols["ci"])[i]
                    row += [num(raw_mean), num(raw_ci), int(cols.get("smooth", 1))]
                writer.writerow(row)


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


def _finish(fig, ax, plt, out: Path) -> None:
    """Legend, layout, save to ``out`` (creating its directory), close."""
    ax.legend(fontsize=8)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out)
    plt.close(fig)


def curve_legend(group: str, cols: dict) -> str:
    """A curve's legend entry: ``group (n=runs)``, plus the smoothing when there is some,
    e.g. ``max-critic (n=1, 20-generation moving mean)``."""
    smooth = int(cols.get("smooth", 1))
    note = f", {smooth}-generation moving mean" if smooth > 1 else ""
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
    ax.set_xlabel("Generation" if x == "generation" else "Training episodes")
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


@dataclass
class Plot:
    """What :func:`make_curves` / :func:`make_final` wrote, and what to tell the user."""

    png: Path
    csv: Path
    table: Table
    messages: list[str] = field(default_factory=list)


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
    runs = load_runs(run_dirs, by=by)
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
    runs = load_runs(run_dirs, by=by, x=x)
    table = final_table(runs, x, last=last)
    png = Path(out) if out else default_out(run_dirs, x)
    plot_final(table, png, x, default_title(runs) if title is None else title, last=last)
    return Plot(png, png.with_suffix(".csv"), table, list(table.messages))
