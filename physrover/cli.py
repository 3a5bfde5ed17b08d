"""The ``physrover`` command: parses arguments and calls library functions.

Errors in user input (bad config values, unknown fields, missing files) are printed as one
line ``physrover: error: ...`` with exit status 2, never as a traceback.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence

from physrover.config import (
    METHODS,
    ConfigError,
    RunConfig,
    parse_override,
)
from physrover.runs import RunError


class UsageError(Exception):
    """A user-facing error: printed as one line, exit status 2."""


def _run_config(args: argparse.Namespace) -> RunConfig:
    """RunConfig from ``--config FILE`` ([domain] and [learn]), ``--set`` and shortcut flags."""
    config = RunConfig.load(args.config) if getattr(args, "config", None) else RunConfig()
    overrides: dict = {}
    for text in getattr(args, "set", None) or []:
        name, value = parse_override(text)
        overrides[name] = value
    for flag, field in (
        ("motion", "motion"),
        ("n_req", "n_req"),
        ("collisions", "collisions"),
        ("method", "method"),
        ("seed", "seed"),
        ("generations", "generations"),
    ):
        if getattr(args, flag, None) is not None:
            overrides[field] = getattr(args, flag)
    return config.with_overrides(overrides)


def _add_config_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--config", metavar="FILE.toml", help="config file ([domain] table)")
    p.add_argument(
        "--set",
        action="append",
        metavar="FIELD=VALUE",
        help="override a config field by name (repeatable), e.g. --set n_rovers=6",
    )


def cmd_info(args: argparse.Namespace) -> int:
    print(_run_config(args).to_toml(), end="")
    return 0


def cmd_train(args: argparse.Namespace) -> int:
    from physrover.runs import train

    _pin_threads(args.threads)
    if args.resume:
        given = [args.config, args.set, args.method, args.n_req, args.motion, args.seed, args.out]
        if any(v is not None for v in given):
            raise UsageError(
                "--resume continues a run with its own config; only --generations applies"
            )
        out = train(
            None, args.resume, resume=True, generations=args.generations, progress=not args.quiet
        )
    else:
        config = _run_config(args)
        cfg = config.learn
        out = args.out or (
            f"runs/{cfg.method}_{config.domain.motion}_nreq{config.domain.n_req}_seed{cfg.seed}"
        )
        out = train(config, out, progress=not args.quiet)
    print(f"run directory: {out}")
    return 0


def _pin_threads(threads: int) -> None:
    os.environ["OMP_NUM_THREADS"] = str(threads)
    try:
        import torch

        torch.set_num_threads(threads)
    except ImportError:  # pragma: no cover - torch is a dependency
        pass


def cmd_bench(args: argparse.Namespace) -> int:
    from physrover import bench

    _pin_threads(args.threads)
    config = _run_config(args)
    if args.what == "world":
        timing = bench.bench_world(config.domain, n_teams=args.teams, repeats=args.repeats)
        print(timing.line())
        return 0
    if args.what == "train":
        d, cfg = config.domain, config.learn
        print(
            f"train: {d.n_rovers} rovers, {d.n_pois} POIs, k={cfg.population}, "
            f"{d.steps} steps, motion={d.motion}, median of {args.repeats} generations"
        )
        methods = args.methods.split(",") if args.methods else list(METHODS)
        for line in bench.bench_train(config, methods, generations=args.repeats):
            print(line)
        return 0
    raise UsageError(f"unknown benchmark {args.what!r}")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="physrover",
        description="Multi-rover testbed: the tightly coupled rover domain and fitness critics.",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = sub.add_parser("info", help="print the resolved run config ([domain], [learn]) as TOML")
    _add_config_args(p)
    p.set_defaults(func=cmd_info)

    p = sub.add_parser("train", help="train a team with the CCEA and a fitness method")
    _add_config_args(p)
    p.add_argument("--method", help="fitness method, e.g. max-critic, mean-critic, D, average")
    p.add_argument("--n-req", dest="n_req", type=int, help="coupling n_req")
    p.add_argument("--motion", choices=["ideal", "physics"], help="motion model")
    p.add_argument("--generations", type=int, help="generations (with --resume: run up to)")
    p.add_argument("--seed", type=int, help="seed of every random draw")
    p.add_argument("--out", help="run directory (must not exist or be empty)")
    p.add_argument("--resume", metavar="DIR", help="continue the run in DIR")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument("--threads", type=int, default=1, help="torch/BLAS threads (default 1)")
    p.set_defaults(func=cmd_train)

    p = sub.add_parser("bench", help="time the world or the learner (benchmarks, not tests)")
    p.add_argument("what", choices=["world", "train"], help="what to time")
    p.add_argument("--methods", help="comma-separated methods for 'train' (default: all)")
    p.add_argument("--motion", choices=["ideal", "physics"], help="motion model")
    p.add_argument(
        "--collisions",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="rover-rover collisions under physics (config default: on)",
    )
    p.add_argument("--teams", type=int, default=50, help="teams stepped together (default 50)")
    p.add_argument("--repeats", type=int, default=20, help="timed runs/generations (default 20)")
    p.add_argument("--threads", type=int, default=1, help="torch/BLAS threads (default 1)")
    _add_config_args(p)
    p.set_defaults(func=cmd_bench)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except (ConfigError, UsageError, RunError) as exc:
        print(f"physrover: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("physrover: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
