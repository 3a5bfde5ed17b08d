"""The ``physrover`` command: parses arguments and calls library functions.

Errors in user input (bad config values, unknown fields, missing files) are printed as one
line ``physrover: error: ...`` with exit status 2, never as a traceback.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence

from physrover.config import ConfigError, DomainConfig, load_toml_file, parse_override


class UsageError(Exception):
    """A user-facing error: printed as one line, exit status 2."""


def _domain_config(args: argparse.Namespace) -> DomainConfig:
    """DomainConfig from ``--config FILE`` (its [domain] table), then ``--set`` overrides."""
    values: dict = {}
    if getattr(args, "config", None):
        data = load_toml_file(args.config)
        values.update(data.get(DomainConfig.section, {}))
    for text in getattr(args, "set", None) or []:
        name, value = parse_override(text)
        values[name] = value
    for name in ("motion", "n_req", "collisions"):  # shortcut flags, where a subcommand has them
        if getattr(args, name, None) is not None:
            values[name] = getattr(args, name)
    return DomainConfig.from_dict(values)


def _add_config_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--config", metavar="FILE.toml", help="config file ([domain] table)")
    p.add_argument(
        "--set",
        action="append",
        metavar="FIELD=VALUE",
        help="override a config field by name (repeatable), e.g. --set n_rovers=6",
    )


def cmd_info(args: argparse.Namespace) -> int:
    print(_domain_config(args).to_toml(), end="")
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
    cfg = _domain_config(args)
    if args.what == "world":
        timing = bench.bench_world(cfg, n_teams=args.teams, repeats=args.repeats)
        print(timing.line())
        return 0
    raise UsageError(f"unknown benchmark {args.what!r}")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="physrover",
        description="Multi-rover testbed: the tightly coupled rover domain and fitness critics.",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = sub.add_parser("info", help="print the resolved config as TOML")
    _add_config_args(p)
    p.set_defaults(func=cmd_info)

    p = sub.add_parser("bench", help="time the world or the learner (benchmarks, not tests)")
    p.add_argument("what", choices=["world"], help="what to time")
    p.add_argument("--motion", choices=["ideal", "physics"], help="motion model")
    p.add_argument(
        "--collisions",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="rover-rover collisions under physics (config default: on)",
    )
    p.add_argument("--teams", type=int, default=50, help="teams stepped together (default 50)")
    p.add_argument("--repeats", type=int, default=20, help="timed runs (default 20)")
    p.add_argument("--threads", type=int, default=1, help="torch/BLAS threads (default 1)")
    _add_config_args(p)
    p.set_defaults(func=cmd_bench)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except (ConfigError, UsageError) as exc:
        print(f"physrover: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("physrover: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
