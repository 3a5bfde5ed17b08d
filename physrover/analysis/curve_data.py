"""Learning-curve data: runs loaded, grouped by experiment and tabulated with 95% CIs, as CSV.

Runs are grouped so that only runs of one experiment are pooled: two runs share a group when
their configs are equal in every field except ``seed`` and the bookkeeping fields of
:data:`NOT_GROUPED`. A group is named by its method, then ``field=value`` for each field that
differs between the runs given (and each field named in ``by``), e.g.
``max-critic n_req=3 generations=2000``; a bare method name when only the method differs.
Within a group each run is one sample (one seed). The interval is the Student-t 95% interval
of the mean, ``mean +- t_{0.975, n-1} * sd / sqrt(n)``; the tables and the CSV keep it raw
(:mod:`physrover.analysis.plots` draws it clipped to the possible range of G).
"""

from __future__ import annotations

import csv
import math
import re
from collections import defaultdict
from dataclasses import dataclass
from functools import reduce
from pathlib import Path

import numpy as np

from physrover.config import ConfigError, DomainConfig, LearnConfig
from physrover.config.roles import role_fields
from physrover.core.registry import FITNESS_METHODS
from physrover.core.stats import mean_ci
from physrover.experiment.store import METRICS, load_run_config, read_metrics

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


def final_score(run: Run, last: int) -> float:
    """A run's final score: its mean eval G over its last ``last`` generations, of those
    evaluated (a gradient-based trainer with ``log_every > 1`` evaluates every k-th row
    only); NaN when none of them is. What ``curves --final``, ``table`` and
    experiments/make_results.py score a run by."""
    recent = run.eval_G[-last:]
    recent = recent[~np.isnan(recent)]
    return float(recent.mean()) if len(recent) else math.nan


def format_value(value) -> str:
    """A config value as written in a group label: ``true``, ``0.5``, ``1,2,3,4``."""
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, float):
        return f"{value:g}"
    if isinstance(value, (tuple, list)):
        return ",".join(format_value(v) for v in value)
    return str(value)


def _method_fields() -> tuple[str, ...]:
    """The fields of the fitness methods' own tables, in registration order."""
    names: dict[str, None] = {}
    for _name, spec in FITNESS_METHODS.items():
        names |= dict.fromkeys(spec.config.field_names() if spec.config else ())
    return tuple(names)


def field_order() -> tuple[str, ...]:
    """Every field by its bare name, in config order: the domain's, [learn]'s, the fitness
    methods' own tables' (``critic_lr``: a 0.5 run's [learn] held them); a scenario's or
    sensor's own fields of other kinds than the defaults come after, sorted."""
    return (*DomainConfig().flat_dict(), *LearnConfig.field_names(), *_method_fields())


def differing_fields(fields: list[dict], skip: tuple[str, ...] = ()) -> list[str]:
    """Names of the config fields (in config order) whose value is not the same in all of
    ``fields`` (one dict per run) that have them, leaving out ``method``, :data:`NOT_GROUPED`
    and ``skip`` (a field that only some runs have, e.g. a scenario kind's own, differs only
    if those runs disagree on it: the kind already tells the others apart)."""
    left_out = {"method", *NOT_GROUPED, *skip}
    order = field_order()
    # then a trainer's own fields (``mappo.lr``), which only some runs have
    extra = sorted({name for f in fields for name in f} - set(order))
    return [
        name
        for name in (*order, *extra)
        if name not in left_out
        and name.rsplit(".", 1)[-1] not in NOT_GROUPED  # a trainer's seed: ``maddpg.seed``
        and len({format_value(f[name]) for f in fields if name in f}) > 1
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
        fields = run_fields(config)
        if config.trainer is not None:
            del fields["generations"]  # [learn] generations: not what a trainer's run counts
        all_fields.append(fields)
    for name, option in [(n, "--by") for n in by] + ([(x, "--final")] if x else []):
        if name not in field_order() and not any(name in f for f in all_fields):
            raise ConfigError(name, f"not a config field of these runs ({option})")
    split = set(differing_fields(all_fields, skip=(x,) if x else ())) | set(by)
    order = list(field_order()) + sorted(split - set(field_order()))
    names = [n for n in order if n in split and n not in ("method", x)]
    runs = []
    for path, config, fields in zip(paths, configs, all_fields, strict=True):
        rows = read_metrics(path / METRICS)
        eval_g = np.array([r["eval_G"] for r in rows], dtype=float)
        generation = np.array([r["generation"] for r in rows], dtype=np.int64)
        if config.trainer is not None or (rows and "episodes" in rows[0]):
            # A gradient-based run logs its episodes (none yet if it has just started).
            episodes = np.array([r["episodes"] for r in rows], dtype=np.int64)
        else:
            episodes = generation * training_episodes(config)
        label = group_label(fields, names)
        runs.append(Run(path, label, fields, eval_g, generation, episodes))
    return runs


def run_fields(config) -> dict:
    """A run's config fields by the names labels and tables use: the domain's (with its
    [[agents]] and [[pois]] fields, ``uav.count``...), [learn]'s, and the method's own
    table's, by bare name for a fitness method's (``critic_lr``) and ``table.field`` for a
    gradient-based trainer's (``mappo.lr``); ``hybrid``, the hybrid's learner or "none",
    and with a ``[hybrid]`` table its fields as ``hybrid.field``."""
    fields = {**config.domain.flat_dict(), **role_fields(config.domain), **config.learn.to_dict()}
    if config.trainer is not None:
        section = config.trainer.section
        fields |= {f"{section}.{k}": v for k, v in config.trainer.to_dict().items()}
    elif config.settings is not None:
        fields |= config.settings.to_dict()
    fields["hybrid"] = "none" if config.hybrid is None else config.hybrid.learner
    if config.hybrid is not None:
        fields |= {f"hybrid.{k}": v for k, v in config.hybrid.to_dict().items()}
    return fields


def training_episodes(config) -> int:
    """Training episodes per CCEA generation: the fitness method's rounds x the population
    (k for D, G and the critics; n_samples x k for average and leniency; R x k for the hall
    of fame) x ``rollouts``. The champion's evaluation episodes are a measurement and do not
    count."""
    from physrover.learn.fitness import Problem, make_method

    problem = Problem(config.domain.n_rovers, 1, 1, 1)  # sizes do not change the rounds
    method = make_method(config, problem, np.random.default_rng(0))
    return method.rounds * config.learn.population * config.learn.rollouts


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
        value = run.fields[x]
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            hint = f"--by {x} groups the curves by it instead"
            raise ConfigError(x, f"--final draws the final score against a number, and {x} "
                              f"is {value!r}; {hint}")  # fmt: skip
        if len(run.eval_G):
            cells[run.group][run.fields[x]].append(run)
        else:
            table.messages.append(f"{run.path}: no generations yet, left out")
    scores: dict[str, dict[float, list[float]]] = {}
    shared = {}
    for group in sorted(cells, key=_natural):
        by_x = cells[group]
        for v in sorted(by_x):
            lengths = sorted(len(run.eval_G) for run in by_x[v])
            if lengths[0] != lengths[-1]:
                table.messages.append(
                    f"{group}, {x}={format_value(v)}: {len(lengths)} runs of {lengths[0]} to "
                    f"{lengths[-1]} generations, each scored on its own last {last}"
                )
        scores[group] = {v: [final_score(run, last) for run in by_x[v]] for v in by_x}
        shared[group] = _shared([run for v in by_x for run in by_x[v]])
    scored = scores_table(x, scores, shared)
    scored.messages[:0] = table.messages
    return scored


def scores_table(
    x: str, scores: dict[str, dict[float, list[float]]], shared: dict[str, tuple]
) -> Table:
    """The table of :func:`final_table` from final scores already computed: ``scores``
    {group: {value of ``x``: [a final score per run]}}, ``shared`` {group: (G max, method
    or None)}. Also what draws a final-score figure from rows of a results CSV."""
    table = Table(x)
    for group in sorted(scores, key=_natural):
        xs = sorted(scores[group])
        stats = [mean_ci(np.array(scores[group][v], dtype=float)) for v in xs]
        g_max, method = shared[group]
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
