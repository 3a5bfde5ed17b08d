"""Learning curves and final scores with 95% confidence intervals over seeds.

Runs are grouped by method (and any config fields named in ``by``); within a group each run
is one sample (one seed). The band is the Student-t 95% interval of the mean,
``mean +- t_{0.975, n-1} * sd / sqrt(n)``. Every plot writes the plotted numbers as CSV
beside the PNG. matplotlib runs with the Agg backend (no display).
"""

from __future__ import annotations

import csv
import math
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from physrover.config import ConfigError
from physrover.runs import METRICS, load_run_config, read_metrics

# t_{0.975, df} for df = 1..30; beyond, the Cornish-Fisher expansion below (error < 1e-4).
_T975 = [
    12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228,
    2.201, 2.179, 2.160, 2.145, 2.131, 2.120, 2.110, 2.101, 2.093, 2.086,
    2.080, 2.074, 2.069, 2.064, 2.060, 2.056, 2.052, 2.048, 2.045, 2.042,
]  # fmt: skip


def t975(df: int) -> float:
    """The 97.5% quantile of Student's t with ``df`` degrees of freedom."""
    if df < 1:
        return math.nan
    if df <= 30:
        return _T975[df - 1]
    z = 1.959964
    return z + (z**3 + z) / (4 * df) + (5 * z**5 + 16 * z**3 + 3 * z) / (96 * df**2)


def mean_ci(samples: np.ndarray, axis: int = 0) -> tuple[np.ndarray, np.ndarray, int]:
    """Mean and 95% CI half-width over ``axis`` (half-width NaN for a single sample)."""
    n = samples.shape[axis]
    mean = samples.mean(axis=axis)
    if n < 2:
        return mean, np.full_like(mean, np.nan, dtype=np.float64), n
    sd = samples.std(axis=axis, ddof=1)
    return mean, t975(n - 1) * sd / math.sqrt(n), n


@dataclass
class Run:
    path: Path
    group: str
    fields: dict
    eval_G: np.ndarray  # per generation


def load_runs(run_dirs: list[str | Path], by: tuple[str, ...] = ()) -> list[Run]:
    """Runs with their group label: the method, then ``field=value`` for each of ``by``."""
    runs = []
    for path in map(Path, run_dirs):
        config = load_run_config(path)
        fields = {**config.domain.to_dict(), **config.learn.to_dict()}
        for name in by:
            if name not in fields:
                raise ConfigError(name, "not a config field (--by)")
        group = " ".join([config.learn.method] + [f"{name}={fields[name]}" for name in by])
        rows = read_metrics(path / METRICS)
        runs.append(Run(path, group, fields, np.array([r["eval_G"] for r in rows])))
    return runs


def _smooth(y: np.ndarray, window: int) -> np.ndarray:
    """Trailing moving average over ``window`` generations (the first ones average fewer)."""
    if window <= 1:
        return y
    c = np.cumsum(np.insert(y, 0, 0.0, axis=-1), axis=-1)
    idx = np.arange(1, y.shape[-1] + 1)
    lo = np.maximum(idx - window, 0)
    return (c[..., idx] - c[..., lo]) / (idx - lo)


def curve_table(runs: list[Run], smooth: int = 1) -> dict[str, dict[str, np.ndarray]]:
    """{group: {generation, mean, ci, n}} over the generations every run of the group has."""
    groups: dict[str, list[np.ndarray]] = defaultdict(list)
    for run in runs:
        groups[run.group].append(run.eval_G)
    table = {}
    for group, curves in sorted(groups.items()):
        length = min(len(c) for c in curves)
        if length == 0:
            continue
        data = _smooth(np.stack([c[:length] for c in curves]), smooth)
        mean, ci, n = mean_ci(data)
        table[group] = {"generation": np.arange(length), "mean": mean, "ci": ci, "n": n}
    return table


def final_table(runs: list[Run], x: str, last: int = 1) -> dict[str, dict[str, np.ndarray]]:
    """{group: {x, mean, ci, n}}: each run's mean eval G over its ``last`` generations."""
    cells: dict[str, dict[float, list[float]]] = defaultdict(lambda: defaultdict(list))
    for run in runs:
        if x not in run.fields:
            raise ConfigError(x, "not a config field (--final)")
        if len(run.eval_G):
            cells[run.group][run.fields[x]].append(float(run.eval_G[-last:].mean()))
    table = {}
    for group, by_x in sorted(cells.items()):
        xs = sorted(by_x)
        stats = [mean_ci(np.array(by_x[v])) for v in xs]
        table[group] = {
            "x": np.array(xs, dtype=float),
            "mean": np.array([s[0] for s in stats]),
            "ci": np.array([s[1] for s in stats]),
            "n": np.array([s[2] for s in stats]),
        }
    return table


def write_csv(table: dict, path: Path, x_name: str) -> None:
    key = "generation" if x_name == "generation" else "x"
    with open(path, "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["group", x_name, "mean", "ci95_half_width", "n"])
        for group, cols in table.items():
            n = np.broadcast_to(cols["n"], cols["mean"].shape)
            for xv, m, c, k in zip(cols[key], cols["mean"], cols["ci"], n, strict=True):
                writer.writerow([group, f"{xv:g}", repr(float(m)), repr(float(c)), int(k)])


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


def group_colours(groups) -> dict[str, str | None]:
    """A colour per group: the method's own for a bare method name, else ``None`` (the
    axes' cycle), so a method keeps its colour across figures."""
    if all(g in METHOD_COLOURS for g in groups):
        return {g: METHOD_COLOURS[g] for g in groups}
    return dict.fromkeys(groups)


def _axes(title: str):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.2), dpi=120)
    ax.set_title(title, fontsize=10)
    ax.grid(alpha=0.3)
    return fig, ax, plt


def plot_curves(table: dict, out: Path, title: str = "") -> Path:
    """Mean performance score per generation with 95% CI bands (like the paper's Figs 4-6)."""
    fig, ax, plt = _axes(title)
    colours = group_colours(table)
    for group, cols in table.items():
        (line,) = ax.plot(
            cols["generation"],
            cols["mean"],
            label=f"{group} (n={cols['n']})",
            color=colours[group],
        )
        if cols["n"] > 1:
            low, high = cols["mean"] - cols["ci"], cols["mean"] + cols["ci"]
            ax.fill_between(cols["generation"], low, high, color=line.get_color(), alpha=0.2)
    ax.set_xlabel("Generation")
    ax.set_ylabel("Mean performance score (G)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out)
    plt.close(fig)
    write_csv(table, out.with_suffix(".csv"), "generation")
    return out


def plot_final(table: dict, out: Path, x: str, title: str = "") -> Path:
    """Final mean performance score against a config field (like the paper's Figs 7-9)."""
    fig, ax, plt = _axes(title)
    colours = group_colours(table)
    for group, cols in table.items():
        ci = np.nan_to_num(cols["ci"])
        ax.errorbar(
            cols["x"],
            cols["mean"],
            yerr=ci,
            marker="o",
            capsize=3,
            label=group,
            color=colours[group],
        )
    ax.set_xlabel({"n_req": "Coupling (n_req)", "n_rovers": "Number of rovers"}.get(x, x))
    ax.set_ylabel("Mean performance score (G)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out)
    plt.close(fig)
    write_csv(table, out.with_suffix(".csv"), x)
    return out
