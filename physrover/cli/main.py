"""The ``physrover`` command: its argument parser, and ``main``, which runs a command.

The commands themselves are in :mod:`physrover.cli.commands`. Errors in user input (bad config
values, unknown fields, missing files) are printed as one line ``physrover: error: ...``
with exit status 2, never as a traceback.
"""

from __future__ import annotations

import argparse
import os
import sys
import warnings
from collections.abc import Sequence
from pathlib import Path

from physrover.cli.benchmarl_cmd import cmd_benchmarl
from physrover.cli.commands import (
    Interrupted,
    UsageError,
    cmd_bench,
    cmd_demo,
    cmd_evaluate,
    cmd_info,
    cmd_methods,
    cmd_render,
    cmd_sweep,
    cmd_train,
)
from physrover.cli.lab_cmd import add_import_lab
from physrover.cli.reports import add_compare, cmd_curves, cmd_results, cmd_table
from physrover.config import ConfigError
from physrover.core import plugins
from physrover.experiment.on_ray import ClusterLost
from physrover.experiment.store import RunError
from physrover.viz.video import VideoError


def _add_config_args(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--config",
        metavar="FILE.toml",
        help="config file ([domain], [physics], [scenario], [sensor], [learn] tables)",
    )
    p.add_argument(
        "--set",
        action="append",
        metavar="FIELD=VALUE",
        help="override a config field by name (repeatable), e.g. --set n_rovers=6",
    )


def _add_motion_args(p: argparse.ArgumentParser, default: str) -> None:
    p.add_argument(
        "--motion", help=f"motion model: ideal, physics or one registered (default: {default})"
    )
    p.add_argument(
        "--collisions",
        action=argparse.BooleanOptionalAction,
        default=None,
        help=f"rover-rover collisions under physics (default: {default})",
    )


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="physrover",
        description="Multi-rover testbed: the tightly coupled rover domain and fitness critics.",
        epilog="Start with `physrover demo`; `physrover COMMAND --help` describes a command.",
    )
    parser.add_argument(
        "--import",
        dest="imports",
        action="append",
        default=[],
        metavar="MODULE|FILE.py",
        help="import a module or file of your own parts (scenario, sensor, motion model, "
        "credit, fitness method, trainer) before the command; repeatable; sweep workers "
        "inherit it (also: PHYSROVER_IMPORT, a sweep file's [sweep] imports)",
    )
    from physrover import __version__

    parser.add_argument("--version", action="version", version=f"physrover {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", title="commands")

    p = sub.add_parser("info", help="print the resolved run config (every table) as TOML")
    _add_config_args(p)
    p.set_defaults(func=cmd_info)

    p = sub.add_parser("train", help="train a team with the CCEA and a fitness method")
    _add_config_args(p)
    p.add_argument(
        "--method", help="fitness method, e.g. max-critic, D, average (list: physrover methods)"
    )
    p.add_argument("--n-req", dest="n_req", type=int, help="coupling n_req")
    p.add_argument("--motion", help="motion model: ideal, physics or one registered")
    p.add_argument("--generations", type=int, help="the CCEA's length in generations "
                   "(with --resume: run up to)")  # fmt: skip
    p.add_argument("--iterations", type=int, help="a trainer's (mappo, maddpg) length in "
                   "iterations of num_envs episodes (with --resume: run up to)")  # fmt: skip
    p.add_argument("--seed", type=int, help="seed of every random draw")
    p.add_argument("--out", help="run directory (must not exist or be empty; default: "
                   "runs/ and a name from the config, or the next free one)")  # fmt: skip
    p.add_argument("--resume", metavar="DIR", help="continue the run in DIR")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument("--threads", type=int, default=1, help="torch/BLAS threads (default 1)")
    p.add_argument(
        "--tensorboard",
        action="store_true",
        help="also log metrics as TensorBoard events in DIR/tensorboard "
        "(pip install 'physrover[tensorboard]')",
    )
    p.set_defaults(func=cmd_train)

    p = sub.add_parser("methods", help="list the fitness methods (name, paper section, summary)")
    p.set_defaults(func=cmd_methods)

    p = sub.add_parser("render", help="record a run's champion team to MP4")
    p.add_argument("run_dir", help="a run directory")
    p.add_argument("--checkpoint", type=int, help="generation of the champion (default: last)")
    p.add_argument("--episodes", type=int, default=3, help="episodes to record (default 3)")
    p.add_argument("--seed", type=int, default=0, help="seed of the first episode")
    p.add_argument("--out", help="output .mp4 (default: inside the run directory)")
    p.add_argument("--side-by-side", action="store_true", help="ideal and physics side by side")
    p.add_argument("--ids", action="store_true", help="draw each rover's index beside it")
    p.add_argument("--size", type=int, default=640, help="frame width and height, pixels (even)")
    p.add_argument("--fps", type=int, default=10, help="frames per second")
    p.set_defaults(func=cmd_render)

    p = sub.add_parser(
        "evaluate", help="play a run's champion team on fresh episodes, under any motion model"
    )
    p.add_argument("run_dir", help="a run directory")
    _add_motion_args(p, "the run's")
    p.add_argument("--episodes", type=int, default=100, help="episodes (default 100)")
    p.add_argument("--checkpoint", type=int, help="generation of the champion (default: last)")
    p.add_argument("--seed", type=int, help="seed of the first episode (default 1000000)")
    p.add_argument("--n-req", type=int, metavar="N",
                   help="play at coupling N (the domain's n_req; default: the run's)")  # fmt: skip
    p.add_argument("--out", metavar="FILE.csv", help="also write each episode's G as CSV")
    p.set_defaults(func=cmd_evaluate)

    p = sub.add_parser("curves", help="learning curves (or final scores) with 95%% CI")
    p.add_argument(
        "run_dirs",
        nargs="+",
        help="run directories, or directories holding them "
        "(or a CSV it wrote: the figure drawn again from its numbers)",
    )
    p.add_argument(
        "--out",
        help="output PNG (default: curves.png / final_FIELD.png beside the runs); CSV beside it",
    )
    p.add_argument("--by", action="append", metavar="FIELD", help="also group by this field")
    p.add_argument("--final", metavar="FIELD", help="plot the final score against FIELD")
    p.add_argument("--last", type=int, default=1, help="--final: average the last N gens")
    p.add_argument("--smooth", type=int, default=1, help="moving average over N generations")
    p.add_argument(
        "--x",
        choices=["generation", "episodes"],
        default="generation",
        help="x axis: generations, or training episodes (compares learners of different cost)",
    )
    p.add_argument("--title", default=None, help="plot title (default: what all runs share)")
    p.set_defaults(func=cmd_curves)

    p = sub.add_parser(
        "table",
        help="final scores with 95%% CI and the fraction that learns; --compare: tests",
        description="Each group's final score (mean eval G over its last N generations) "
        "+- the Student-t 95% half-width, range and fraction of runs that learn, as a "
        "Markdown table; --compare FIELD=A,B also sets A against B in every cell of the other "
        "fields (permutation p, exact up to 10 vs 10 seeds; Holm-adjusted over the comparisons; "
        "Welch's t; Hedges' g).",
    )
    p.add_argument("run_dirs", nargs="+", help="run directories, or directories holding them")
    p.add_argument("--last", type=int, default=50, help="final score: mean of the last N "
                   "generations (default 50)")  # fmt: skip
    p.add_argument("--by", action="append", metavar="FIELD", help="also group by this field")
    p.add_argument(
        "--compare",
        metavar="FIELD=A,B",
        help="value A of FIELD against B, e.g. method=max-critic,D",
    )
    p.add_argument(
        "--learned", type=float, default=0.5, help="a run learns above this score (default 0.5)"
    )
    p.add_argument("--out", metavar="PREFIX", help="also write PREFIX_cells.csv/.md "
                   "(and PREFIX_compare.csv/.md)")  # fmt: skip
    p.set_defaults(func=cmd_table)

    p = sub.add_parser(
        "results",
        help="a sweep's runs.csv, cells table and figures, pooling earlier machines' rows",
        description="For each sweep directory: runs.csv (a row per finished run: its grid "
        "values, seed, final score, wall time, code and CPU), cells.md/.csv (final score "
        "+- 95% CI per cell of the grid), learning curves and final score against each "
        "numeric grid field. Rows of OUT/runs.csv of finished runs not found on disk (a "
        "sweep run in chunks of seeds on other machines) are pooled in.",
    )
    p.add_argument("sweep_dirs", nargs="+", help="sweep directories (ROOT/NAME of physrover "
                   "sweep)")  # fmt: skip
    p.add_argument("--out", help="where to write (default: results/ beside the first sweep)")
    p.add_argument("--last", type=int, default=50, help="final score: mean of the last N "
                   "generations (default 50)")  # fmt: skip
    p.add_argument("--smooth", type=int, default=20, help="moving mean of the learning "
                   "curves, in generations (default 20)")  # fmt: skip
    p.set_defaults(func=cmd_results)

    p = sub.add_parser("demo", help="short max-critic training, then a curve and a video")
    p.add_argument("--generations", type=int, default=2000, help="generations (default 2000)")
    p.add_argument("--out", default="runs/demo", help="run directory (default runs/demo)")
    p.set_defaults(func=cmd_demo)

    p = sub.add_parser("sweep", help="run a grid of training runs (process pool or Ray)")
    p.add_argument("sweep_file", help="sweep TOML ([sweep], [base.*], [grid])")
    p.add_argument("--seeds", metavar="N|A:B",
                   help="seeds per cell, N (seeds 0..N-1) or A:B (seeds A..B-1, a chunk of "
                        "the sweep); default: the file's")  # fmt: skip
    p.add_argument("--workers", type=int, help="parallel runs (default: CPU count)")
    p.add_argument("--ray", metavar="ADDRESS", help="run on Ray ('local' starts one here)")
    p.add_argument("--root", default="runs/sweeps", help="where sweeps go (default runs/sweeps)")
    p.add_argument("--dry-run", action="store_true", help="list the run directories only")
    p.add_argument("--status", action="store_true",
                   help="run nothing: list the runs not done yet with their checkpointed "
                        "generations (a trainer's: iterations), and count done, partial and "
                        "new runs")  # fmt: skip
    p.add_argument(
        "--skip-listed",
        metavar="CSV",
        help="leave out the runs this results table (columns sweep, run, generations; "
        "e.g. experiments/results/runs.csv) lists as finished",
    )
    p.add_argument(
        "--set",
        action="append",
        metavar="FIELD=VALUE",
        help="override a config field of every run (repeatable), e.g. --set generations=50; "
        "the runs go under NAME+FIELD=VALUE, apart from the file's",
    )
    p.add_argument(
        "--drop-state",
        action="store_true",
        help="delete each run's checkpoint (state*.npz, ~2 x 18 MB) when it finishes; it can "
        "then not be extended",
    )
    p.set_defaults(func=cmd_sweep)

    p = sub.add_parser(
        "benchmarl",
        help="train with BenchMARL (MAPPO, IPPO, MASAC, ...) on a physrover task "
        "(needs physrover[benchmarl])",
        description="A BenchMARL experiment from Hydra overrides, as BenchMARL's run.py takes "
        "them; defaults: algorithm=mappo task=physrover/rover_domain experiment.loggers=[csv].",
    )
    p.add_argument(
        "overrides",
        nargs="*",
        metavar="KEY=VALUE",
        help="Hydra overrides, e.g. task.n_req=1 experiment.max_n_iters=20 seed=1",
    )
    p.add_argument(
        "--out",
        default="runs/benchmarl",
        help="experiment folder (default runs/benchmarl, or the next free name)",
    )
    p.add_argument("--threads", type=int, default=1, help="torch threads (default 1)")
    p.set_defaults(func=cmd_benchmarl)

    add_compare(sub)
    add_import_lab(sub)

    p = sub.add_parser("bench", help="time the world or the learner (benchmarks, not tests)")
    p.add_argument(
        "what",
        choices=["world", "train", "paper", "envs"],
        help="what to time ('paper': estimate the wall time of sweep files; 'envs': team "
        "steps per second through each env interface, and VMAS discovery)",
    )
    p.add_argument(
        "sweeps", nargs="*", help="paper: sweep files (default: the paper's long sweeps)"
    )
    p.add_argument(
        "--seeds", metavar="N|A:B", help="paper: seeds per cell, N or A:B (default: the file's)"
    )
    p.add_argument("--workers", type=int, default=2, help="paper: parallel runs (default 2)")
    p.add_argument("--methods", help="comma-separated methods for 'train' (default: all)")
    _add_motion_args(p, "the config's")
    p.add_argument("--teams", type=int, default=50, help="teams stepped together (default 50)")
    p.add_argument("--rovers", type=_int_list, metavar="R,R,...",
                   help="world: the scaling table over these team sizes (about 1500 rovers "
                        "in all), e.g. 15,100,400,1000")  # fmt: skip
    p.add_argument("--repeats", type=int, default=20, help="timed runs/generations (default 20)")
    p.add_argument("--against", metavar="FILE.toml|paper",
                   help="train: interleave each generation with one of this config's "
                        "(paper: the defaults) in one process, and print the medians' "
                        "ratio")  # fmt: skip
    p.add_argument("--threads", type=int, default=1, help="torch/BLAS threads (default 1)")
    _add_config_args(p)
    p.set_defaults(func=cmd_bench)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args, extra = parser.parse_known_args(argv)
    if extra:  # a misspelt flag: the command's own usage, not the top level's
        command = _subparser(parser, args.command)
        (command or parser).error(f"unrecognized arguments: {' '.join(extra)}")
    if args.command is None:  # bare `physrover`: show the commands, not just "required"
        parser.print_help(sys.stderr)
        return 2
    if "PHYSROVER_ENGINE" in os.environ:  # physrover 0.1 had a numpy engine beside numba
        print("physrover: note: PHYSROVER_ENGINE is no longer read; the compiled kernels are "
              "the one implementation (NUMBA_DISABLE_JIT=1 runs them as Python)",
              file=sys.stderr)  # fmt: skip
    with warnings.catch_warnings():
        warnings.showwarning = _show_warning
        return _run(args)


def _int_list(text: str) -> list[int]:
    """``15,100,400`` -> [15, 100, 400]; positive integers only."""
    try:
        values = [int(part) for part in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected integers like 15,100,400, got {text!r}"
        ) from None
    if not values or min(values) < 1:
        raise argparse.ArgumentTypeError(f"expected positive integers, got {text!r}")
    return values


def _subparser(parser: argparse.ArgumentParser, name: str | None):
    """The parser of command ``name`` (None for none)."""
    for action in parser._subparsers._group_actions if parser._subparsers else ():
        if isinstance(action, argparse._SubParsersAction) and name in action.choices:
            return action.choices[name]
    return None


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """A warning (a resume from the previous checkpoint, other code than the run's) in one
    line, as errors are, not Python's file:line and source; one another package raised
    (TorchRL's deprecations, say) is named by that package, not by physrover."""
    first = str(message).strip().splitlines()[0] if str(message).strip() else category.__name__
    print(
        f"{warning_origin(filename)}: warning: {first}", file=sys.stderr if file is None else file
    )


def warning_origin(filename: str) -> str:
    """The top-level package of the module ``filename`` (a path), "physrover" for ours and
    for what is not in an installed package (a script, a researcher's own parts)."""
    path = Path(filename).resolve()
    if Path(__file__).resolve().parents[1] in path.parents:
        return "physrover"
    parts = path.parts
    for marker in ("site-packages", "dist-packages"):
        if marker in parts and parts.index(marker) + 1 < len(parts) - 1:
            return parts[parts.index(marker) + 1]
    return "physrover"


def _run(args: argparse.Namespace) -> int:
    try:
        plugins.load_from_environment()
        plugins.load(args.imports)
        code = args.func(args)
        sys.stdout.flush()  # inside the try: a closed pipe shows here, not at exit
        return code
    except BrokenPipeError:
        # The reader of the output has gone (e.g. `physrover sweep F --dry-run | head`):
        # stop quietly as Unix tools do, with 128 + SIGPIPE; stdout goes to /dev/null so
        # Python's final flush does not raise again.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141
    except (ConfigError, UsageError, RunError, VideoError, plugins.PluginError) as exc:
        print(f"physrover: error: {exc}", file=sys.stderr)
        return 2
    except ClusterLost as exc:
        print(f"\nphysrover: error: {exc}", file=sys.stderr)
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(1)  # not Ray's exit hooks: they wait a minute for the lost head, then abort
    except Interrupted as exc:
        print(f"physrover: {exc}", file=sys.stderr)
        return 130
    except KeyboardInterrupt:
        print("physrover: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
