"""The commands that read run directories (or their runs.csv) and report on them:
``physrover curves``, ``table``, ``results`` and ``compare`` (one thin function each over
:mod:`physrover.analysis`)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from physrover.cli.commands import UsageError
from physrover.experiment.store import CONFIG, find_runs


def cmd_curves(args: argparse.Namespace) -> int:
    from physrover.analysis import plots

    if args.run_dirs and all(str(p).endswith(".csv") for p in args.run_dirs):
        from physrover.analysis.redraw import redraw  # a committed figure, from its numbers

        if args.out and len(args.run_dirs) > 1:
            raise UsageError("--out names one figure: redraw one CSV at a time")
        for path in args.run_dirs:
            if not Path(path).is_file():
                raise UsageError(f"{path}: no such file")
            result = redraw(path, args.out, args.title or "")
            print(f"plot: {result.png}\nnumbers: {result.csv}")
        return 0
    run_dirs = find_runs(args.run_dirs)
    if not run_dirs:
        raise UsageError("no run directories (with config.toml) found")
    by, title = tuple(args.by or ()), args.title or None
    if args.final:
        result = plots.make_final(run_dirs, args.final, args.out, by=by, last=args.last,
                                  title=title)  # fmt: skip
    else:
        result = plots.make_curves(run_dirs, args.out, by=by, smooth=args.smooth, title=title,
                                   x=args.x)  # fmt: skip
    for message in result.messages:
        print(message, file=sys.stderr)
    print(f"plot: {result.png}\nnumbers: {result.csv}")
    return 0


def cmd_table(args: argparse.Namespace) -> int:
    from physrover.analysis import tables
    from physrover.analysis.curve_data import load_runs

    run_dirs = find_runs(args.run_dirs)
    if not run_dirs:
        raise UsageError("no run directories (with config.toml) found")
    if args.last < 1:
        raise UsageError(f"--last must be >= 1, got {args.last}")
    runs = load_runs(run_dirs, by=tuple(args.by or ()))
    if not any(len(run.eval_G) for run in runs):
        raise UsageError(f"no generation in {len(runs)} run(s) yet: no final score to tabulate")
    for message in tables.scored(runs, args.last)[1] + tables.length_messages(runs):
        print(message, file=sys.stderr)
    rows = tables.cells(runs, args.last, args.learned)
    outputs = [("cells", rows, tables.CELL_COLUMNS, tables.cells_markdown(rows, args.last))]
    if args.compare:
        field, a, b = tables.parse_compare(args.compare)
        pairs, skipped = tables.comparisons(runs, field, a, b, args.last, args.learned)
        for message in skipped:
            print(message, file=sys.stderr)
        markdown = tables.comparisons_markdown(pairs)
        outputs.append(("compare", pairs, tables.COMPARE_COLUMNS, markdown))
    print("\n".join(markdown for *_, markdown in outputs), end="")
    if args.out:
        for name, table_rows, columns, markdown in outputs:
            path = Path(f"{args.out}_{name}.csv")
            path.parent.mkdir(parents=True, exist_ok=True)
            tables.write_csv(table_rows, columns, path)
            path.with_suffix(".md").write_text(markdown)
            print(f"{name}: {path} {path.with_suffix('.md')}", file=sys.stderr)
    return 0


def cmd_results(args: argparse.Namespace) -> int:
    from physrover.analysis.results import write_results

    sweeps = [Path(d) for d in args.sweep_dirs]
    for path in sweeps:
        if not path.is_dir():
            raise UsageError(f"{path} is not a directory")
        if (path / CONFIG).is_file():
            raise UsageError(f"{path} is a run directory; results reads sweeps "
                             f"(directories of runs, e.g. {path.parent}); for runs: "
                             "physrover table")  # fmt: skip
    if args.last < 1 or args.smooth < 1:
        raise UsageError("--last and --smooth must be >= 1")
    out = Path(args.out) if args.out else sweeps[0].parent / "results"
    results, messages = write_results(sweeps, out, args.last, args.smooth)
    for message in messages:
        print(message, file=sys.stderr)
    rows = sum(len(r.rows) for r in results)
    print(f"results of {len(results)} sweep(s), {rows} runs: {out}")
    return 0


def _is_claims(path: Path) -> bool:
    """Whether ``path`` is a claims file (a TOML file without a [sweep] table)."""
    import tomllib

    try:
        return path.is_file() and "sweep" not in tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise UsageError(f"{path}: {exc}") from None


def cmd_compare(args: argparse.Namespace) -> int:
    from physrover.analysis.claim_tests import SHIPPED, load_claims, write_claims
    from physrover.analysis.results import read_rows, sweep_comparisons

    runs = Path(args.runs_csv)
    if not runs.is_file():
        raise UsageError(f"{runs}: no such file (a runs.csv of physrover results)")
    rows = read_rows(runs)
    out = Path(args.out) if args.out else runs.parent
    if args.file == SHIPPED or _is_claims(Path(args.file)):
        name, doc = load_claims(args.file)
        said = write_claims(rows, doc, name, out)
    else:  # a sweep file (or a shipped sweep's name): its [[comparisons]]
        said = sweep_comparisons(rows, args.file, out)
    print("\n".join(said))
    return 0


def add_compare(sub) -> None:
    """The ``compare`` command's parser, under ``sub``."""
    p = sub.add_parser(
        "compare",
        help="planned comparisons (Holm) over a runs.csv, from a sweep or claims file",
        description="Tests the comparisons FILE plans over the runs RUNS_CSV lists (a "
        "runs.csv of physrover results, or one pooled over sweeps): a sweep file's (or a "
        "shipped sweep's) [[comparisons]] over its own rows, into NAME_significance.md/.csv; "
        "or a claims file's (paper-claims: the paper's Section 5) comparisons and trends "
        "over every sweep's rows, into NAME_significance and NAME_trend. Needs no run "
        "directory: the committed tables regenerate from the committed runs.csv.",
    )
    p.add_argument("runs_csv", help="runs.csv (physrover results, or experiments' pooled one)")
    p.add_argument("file", help="a sweep file or name, a claims file, or paper-claims")
    p.add_argument("--out", help="where to write (default: beside RUNS_CSV)")
    p.set_defaults(func=cmd_compare)
