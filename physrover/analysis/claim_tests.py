"""Claims tested over a pooled runs.csv: ``physrover compare RUNS_CSV CLAIMS.toml``.

A claims file states, before the numbers are seen, which cells of which sweeps a study sets
against each other; the shipped ``paper-claims`` is the paper's Section 5 as RESULTS.md
tests it. Its parts:

- ``[claims]``: each claim's number and words.
- ``[defaults]``: the value of a runs.csv column a side leaves out (``motion = "ideal"``).
- ``grid``: the columns whose values make the cells (``["n_req", "n_rovers"]``).
- ``[labels]``: a column's short name in the tables (``n_rovers = "rovers"``).
- ``[[comparisons]]``: ``claim``, then ``a``, ``b`` and ``where`` as in a sweep file
  (:mod:`physrover.analysis.comparisons`), over runs.csv's columns (``sweep`` among them,
  so a side may name another sweep). Every column of ``[defaults]`` a side leaves out is
  pinned to its default on that side. Holm's method adjusts each claim's comparisons in one
  sweep (or pair of sweeps) together.
- ``[[trends]]``: ``claim``, ``sweep``, ``method``, ``n_req`` (lists, made in this order),
  ``x`` and its ``values``: whether a method's final scores rise with
  ``x`` (Spearman's rho and its permutation p: exact up to 8 scores, else 100,000 orderings
  seeded 0), Holm over each sweep's trends.

It writes ``NAME_significance.{md,csv}`` and ``NAME_trend.{md,csv}`` (NAME: the file's
stem). A run's final score is runs.csv's ``final_G``; a cell with fewer than 2 runs a side
is left out.
"""

from __future__ import annotations

import csv
import itertools
from importlib import resources
from pathlib import Path

import numpy as np
import tomllib

from physrover.analysis.comparisons import MIN_RUNS, compare_cells
from physrover.analysis.tables import (
    format_number,
    holm_families,
    markdown_header,
    significance_cells,
)
from physrover.config import ConfigError
from physrover.core.stats import spearman_trend

SHIPPED = "paper-claims"
"""The claims file that ships with the package (``physrover compare RUNS paper-claims``)."""


def load_claims(name_or_path: str | Path) -> tuple[str, dict]:
    """A claims file by path, or the shipped one by name: its name (the stem) and content."""
    path = Path(name_or_path)
    if str(name_or_path) == SHIPPED:
        text = resources.files("physrover.analysis").joinpath(f"{SHIPPED}.toml").read_text()
    elif path.is_file():
        text = path.read_text()
    else:
        raise ConfigError("claims", f"{name_or_path}: no such file (nor the shipped {SHIPPED})")
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError("claims", f"{name_or_path}: {exc}") from None
    unknown = set(doc) - {"claims", "defaults", "labels", "grid", "comparisons", "trends"}
    if unknown:
        raise ConfigError(f"claims.{sorted(unknown)[0]}", "unknown table")
    for k, table in enumerate(doc.get("comparisons", [])):
        if set(table) - {"claim", "a", "b", "where"} or not {"claim", "a", "b"} <= set(table):
            raise ConfigError(f"comparisons[{k}]", "needs claim, a and b (and may have where)")
    return Path(str(name_or_path)).stem, doc


def _name(side: dict[str, str]) -> str:
    """A side's cells as the claims table names them: ``max-critic (physics) on D++
    [variant]`` (the method; its motion, feedback and variant where not the defaults)."""
    name = side["method"]
    if side.get("motion", "ideal") != "ideal":
        name += f" ({side['motion']})"
    if side.get("feedback", "D") not in ("", "D"):
        name += f" on {side['feedback']}"
    return name + (f" [{side['variant']}]" if side.get("variant") else "")


def claim_comparisons(rows: list[dict], doc: dict) -> list[dict]:
    """The rows of the claims table: a comparison per cell, Holm within each claim and
    sweep (or pair of sweeps)."""
    defaults = {k: str(v) for k, v in doc.get("defaults", {}).items()}
    grid, labels = list(doc.get("grid", [])), doc.get("labels", {})
    specs = [{**c, "a": {**defaults, **c["a"]}, "b": {**defaults, **c["b"]}}
             for c in doc.get("comparisons", [])]  # fmt: skip
    found, _ = compare_cells(rows, specs, defaults, grid)
    out = []
    for row in found:
        a, b = row["sides"]["a"], row["sides"]["b"]
        sweep = a["sweep"] if a["sweep"] == b["sweep"] else f"{a['sweep']} vs {b['sweep']}"
        cell = " ".join(f"{labels.get(f, f)}={v}" for f, v in row["values"].items())
        out.append({"claim": specs[row["comparison"]]["claim"], "sweep": sweep,
                    "A": f"{_name(a)} {cell}", "B": f"{_name(b)} {cell}",
                    "n": f"{row['n_A']}/{row['n_B']}",
                    **{k: row[k] for k in ("mean_A", "mean_B", "diff", "p_permutation")},
                    "p_holm": np.nan, "family_size": 0,
                    **{k: row[k] for k in ("welch_t", "welch_df", "hedges_g", "learn_A",
                                           "learn_B")}})  # fmt: skip
    holm_families(out, lambda row: (row["claim"], row["sweep"]))
    return out


def claim_trends(rows: list[dict], doc: dict) -> list[dict]:
    """The rows of the trends table: one per (sweep, method, n_req) of each ``[[trends]]``
    whose every value of ``x`` has 2 runs or more; Holm within each sweep."""
    defaults = {k: str(v) for k, v in doc.get("defaults", {}).items()}
    out = []
    for spec in doc.get("trends", []):
        x, values = spec["x"], [str(v) for v in spec["values"]]
        for sweep, method, n_req in itertools.product(spec["sweep"], spec["method"],
                                                      spec["n_req"]):  # fmt: skip
            want = {**defaults, "sweep": sweep, "method": method, "n_req": str(n_req)}
            samples = [
                [
                    float(r["final_G"])
                    for r in rows
                    if r.get(x) == v and all(r.get(f, d) == d for f, d in want.items())
                ]
                for v in values
            ]
            if min(len(s) for s in samples) < MIN_RUNS:
                continue
            sizes = np.concatenate(
                [[float(v)] * len(s) for v, s in zip(values, samples, strict=True)]
            )
            rho, p = spearman_trend(sizes, np.concatenate(samples))
            means = {f"mean_{v}": float(np.mean(s)) for v, s in zip(values, samples, strict=True)}
            out.append({"claim": spec["claim"], "sweep": sweep, "method": method,
                        "n_req": n_req, "n": "/".join(str(len(s)) for s in samples), **means,
                        "rho": rho, "p_permutation": p, "p_holm": np.nan, "family_size": 0,
                        "_label": doc.get("labels", {}).get(x, x)})  # fmt: skip
    holm_families(out, lambda row: row["sweep"])
    return out


def _write_csv(rows: list[dict], path: Path) -> None:
    """``rows`` as CSV, their numbers as the tables print them (:func:`format_number`)."""
    columns = [k for k in rows[0] if not k.startswith("_")]
    with open(path, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=columns, extrasaction="ignore")
        writer.writeheader()
        writer.writerows({k: format_number(v) for k, v in r.items()} for r in rows)


def write_claims(rows: list[dict], doc: dict, name: str, out: Path) -> list[str]:
    """``NAME_significance`` and ``NAME_trend`` (.md and .csv) of ``rows`` (a pooled
    runs.csv) in ``out``; the lines to print."""
    said = []
    found, trends = claim_comparisons(rows, doc), claim_trends(rows, doc)
    if not found and not trends:
        raise ConfigError("claims", f"{name}: no comparison or trend has {MIN_RUNS} runs a side")
    out.mkdir(parents=True, exist_ok=True)
    if found:
        path = out / f"{name}_significance.md"
        _write_csv(found, path.with_suffix(".csv"))
        lines = [markdown_header("claim", "sweep", "A", "B", "n")]
        lines += [f"| {r['claim']} | {r['sweep']} | {r['A']} | {r['B']} | {r['n']} | "
                  f"{significance_cells(r)} |" for r in found]  # fmt: skip
        path.write_text("\n".join(lines) + "\n")
        said.append(f"{len(found)} comparisons -> {path}")
    if trends:
        path = out / f"{name}_trend.md"
        _write_csv(trends, path.with_suffix(".csv"))
        values = [k[len("mean_") :] for k in trends[0] if k.startswith("mean_")]
        label = trends[0]["_label"]
        means = " | ".join(f"mean, {v} {label}" for v in values)
        lines = [f"| sweep | method | n_req | seeds | {means} | Spearman rho | p (perm.) | "
                 "p (Holm, m) |", "|" + "---|" * (7 + len(values))]  # fmt: skip
        for r in trends:
            cells = " | ".join(f"{r[f'mean_{v}']:.2f}" for v in values)
            f = format_number
            lines.append(f"| {r['sweep']} | {r['method']} | {r['n_req']} | {r['n']} | {cells} "
                         f"| {f(r['rho'])} | {f(r['p_permutation'])} | {f(r['p_holm'])} "
                         f"({r['family_size']}) |")  # fmt: skip
        path.write_text("\n".join(lines) + "\n")
        said.append(f"{len(trends)} trends over {trends[0]['_label']} -> {path}")
    return said


__all__ = ["SHIPPED", "claim_comparisons", "claim_trends", "load_claims", "write_claims"]
