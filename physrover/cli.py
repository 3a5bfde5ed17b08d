"""The ``physrover`` command: parses arguments and calls library functions.

Errors in user input (bad config values, unknown fields, missing files) are printed as one
line ``physrover: error: ...`` with exit status 2, never as a traceback.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence
from pathlib import Path

from physrover.config import ConfigError, RunConfig, parse_override
from physrover.registry import FITNESS_METHODS
from physrover.render import VideoError
from physrover.runs import RunError, find_runs, last_checkpoint, load_run_config
from physrover.threads import pin_threads


class UsageError(Exception):
    """A user-facing error: printed as one line, exit status 2."""


class Interrupted(Exception):
    """Ctrl-C, with what was saved and how to continue: printed as one line, status 130."""


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
    p.add_argument(
        "--config", metavar="FILE.toml", help="config file ([domain] and [learn] tables)"
    )
    p.add_argument(
        "--set",
        action="append",
        metavar="FIELD=VALUE",
        help="override a config field by name (repeatable), e.g. --set n_rovers=6",
    )


def _add_motion_args(p: argparse.ArgumentParser, default: str) -> None:
    p.add_argument(
        "--motion", choices=["ideal", "physics"], help=f"motion model (default: {default})"
    )
    p.add_argument(
        "--collisions",
        action=argparse.BooleanOptionalAction,
        default=None,
        help=f"rover-rover collisions under physics (default: {default})",
    )


def cmd_info(args: argparse.Namespace) -> int:
    print(_run_config(args).to_toml(), end="")
    return 0


def cmd_methods(args: argparse.Namespace) -> int:
    width = max(len(name) for name in FITNESS_METHODS)
    sections = max(len(spec.section) for _, spec in FITNESS_METHODS.items())
    print(f"{'method':{width}}  {'paper':{sections}}  fitness of a policy")
    for name, spec in FITNESS_METHODS.items():
        print(f"{name:{width}}  {spec.section:{sections}}  {spec.summary}")
    from physrover.registry import TRAINERS

    print("\ngradient-based trainers (their table: [NAME]; length: total_episodes):")
    for name, spec in TRAINERS.items():
        print(f"{name:{width}}  {spec.reference:{sections}}  {spec.summary}")
    print('\nchoose with: physrover train --method NAME  (or [learn] method = "NAME")')
    return 0


def _interrupted(out: Path) -> str:
    """What a Ctrl-C left in run directory ``out`` and how to continue."""
    saved = last_checkpoint(out)
    what = (
        f"saved: the checkpoint after generation {saved}"
        if saved is not None
        else "nothing saved yet (the first checkpoint comes after checkpoint_every generations)"
    )
    return f"interrupted; {what}. Continue with: physrover train --resume {out}"


def cmd_train(args: argparse.Namespace) -> int:
    from physrover.runs import train

    pin_threads(args.threads)
    if args.resume:
        given = [args.config, args.set, args.method, args.n_req, args.motion, args.seed, args.out]
        if any(v is not None for v in given):
            raise UsageError(
                "--resume continues a run with its own config; only --generations applies"
            )
        out = Path(args.resume)
        run_config = load_run_config(out)
        target = run_config.length
        if args.generations and run_config.trainer is None:
            target = args.generations
        done = last_checkpoint(out)
        if done is not None and done >= target:
            if run_config.trainer is not None:
                print(f"{out} is finished: {done} iterations, its total_episodes")
                return 0
            print(
                f"{out} is already at {done} generations; to extend it: "
                f"physrover train --resume {out} --generations {done + 1000}"
            )
            return 0
    else:
        config = _run_config(args)
        cfg = config.learn
        out = Path(
            args.out
            or f"runs/{cfg.method}_{config.domain.motion}_nreq{config.domain.n_req}_seed{cfg.seed}"
        )
    try:
        if args.resume:
            train(None, out, resume=True, generations=args.generations,
                  progress=not args.quiet, tensorboard=args.tensorboard)  # fmt: skip
        else:
            train(config, out, progress=not args.quiet, tensorboard=args.tensorboard)
    except KeyboardInterrupt:
        raise Interrupted(_interrupted(out)) from None
    print(f"run directory: {out}")
    return 0


def cmd_bench(args: argparse.Namespace) -> int:
    from physrover import bench

    pin_threads(args.threads)
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
        methods = args.methods.split(",") if args.methods else list(FITNESS_METHODS)
        for line in bench.bench_train(config, methods, generations=args.repeats):
            print(line)
        return 0
    if args.what == "paper":
        return _bench_paper(args, bench)
    raise UsageError(f"unknown benchmark {args.what!r}")


PAPER_SWEEPS = ("experiments/fig4-7-long.toml", "experiments/fig8-9-paper.toml")


def _bench_paper(args: argparse.Namespace, bench) -> int:
    """Time a few generations of every cell of the sweep files and print what each sweep
    (and all of them) will take on this machine with ``--workers`` processes."""
    from physrover.sweep import Sweep

    files = args.sweeps or list(PAPER_SWEEPS)
    grand = 0.0
    for path in files:
        sweep = Sweep.load(path)
        specs = sweep.runs("runs/sweeps", seeds=args.seeds)
        estimates = bench.estimate_sweep(
            specs, timer=lambda c: bench.time_generation(c, generations=args.repeats)
        )
        wall = bench.sweep_wall_time(estimates, args.workers)
        grand += wall
        print(f"{sweep.name}: {len(specs)} runs, {len(estimates)} cells")
        for e in sorted(estimates, key=lambda e: -e.total_seconds):
            per_gen = 1000 * e.seconds_per_generation
            print(f"  {e.label:40s} {per_gen:7.1f} ms/gen x {e.generations} gen x {e.runs} "
                  f"runs = {e.total_seconds / 60:6.1f} min")  # fmt: skip
        print(f"  estimated wall time on {args.workers} workers: {wall / 3600:.2f} h")
    if len(files) > 1:
        print(f"all {len(files)} sweeps: {grand / 3600:.2f} h on {args.workers} workers")
    return 0


def cmd_render(args: argparse.Namespace) -> int:
    from physrover.playback import record_run
    from physrover.render import RenderConfig

    render = RenderConfig(width=args.size, height=args.size, fps=args.fps)
    run_dir = Path(args.run_dir)
    out = args.out or str(run_dir / ("side_by_side.mp4" if args.side_by_side else "episodes.mp4"))
    path, scores = record_run(
        run_dir,
        out,
        checkpoint=args.checkpoint,
        episodes=args.episodes,
        seed=args.seed,
        side_by_side=args.side_by_side,
        render=render,
    )
    print(f"video: {path}  (G per episode: {', '.join(f'{g:g}' for g in scores)})")
    return 0


def cmd_evaluate(args: argparse.Namespace) -> int:
    from physrover.evaluate import EVAL_SEED, evaluate_run

    pin_threads(1)
    result = evaluate_run(
        args.run_dir,
        episodes=args.episodes,
        seed=EVAL_SEED if args.seed is None else args.seed,
        checkpoint=args.checkpoint,
        motion=args.motion,
        collisions=args.collisions,
    )
    print(result.line())
    if args.out:
        print(f"per-episode G: {result.write_csv(args.out)}")
    return 0


def cmd_curves(args: argparse.Namespace) -> int:
    from physrover import plots

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


def cmd_demo(args: argparse.Namespace) -> int:
    from physrover import plots
    from physrover.playback import record_run
    from physrover.runs import train

    pin_threads(1)
    base = Path(args.out)
    out, n = base, 1
    while out.exists() and any(out.iterdir()):
        n += 1
        out = base.with_name(f"{base.name}-{n}")
    config = RunConfig().with_overrides(
        {"method": "max-critic", "generations": args.generations, "checkpoint_every": 500}
    )
    print(f"demo: max-critic on the paper's domain, {args.generations} generations -> {out}")
    try:
        train(config, out, progress=True)
    except KeyboardInterrupt:
        raise Interrupted(_interrupted(out)) from None
    curve = plots.make_curves([out], out / "learning_curve.png", smooth=20).png
    video, scores = record_run(out, out / "side_by_side.mp4", episodes=2, side_by_side=True)
    print(f"learning curve: {curve}")
    print(f"video: {video}  (the trained team, same start states under both models)")
    print(_episode_table(scores, config.domain.poi_values))
    return 0


def _episode_table(scores: list[float], poi_values) -> str:
    """The side-by-side video's G per episode: ``scores`` alternate ideal, physics."""
    lines = [f"episode  G ideal  G physics   (max G {sum(poi_values):g})"]
    for episode, (ideal, physics) in enumerate(zip(scores[::2], scores[1::2], strict=True)):
        lines.append(f"{episode + 1:7d}  {ideal:7g}  {physics:9g}")
    return "\n".join(lines)


def cmd_sweep(args: argparse.Namespace) -> int:
    from physrover.sweep import Sweep, run_sweep

    sweep = Sweep.load(args.sweep_file)
    specs = sweep.runs(args.root, seeds=args.seeds, drop_state=args.drop_state)
    if args.dry_run:
        for spec in specs:
            print(spec.out)
        return 0
    print(f"sweep {sweep.name}: {len(specs)} runs under {Path(args.root) / sweep.name}")
    try:
        report = run_sweep(specs, workers=args.workers, ray_address=args.ray)
    except KeyboardInterrupt:
        again = " ".join(["physrover", *sys.argv[1:]]) if sys.argv[1:] else "the same command"
        raise Interrupted(
            "sweep interrupted; finished runs are kept and the others resume from their last "
            f"checkpoint when you run it again: {again}"
        ) from None
    print(
        f"sweep {sweep.name}: {len(report.finished)} run, {report.skipped} already done, "
        f"{len(report.failed)} failed, {report.seconds:.0f} s"
    )
    for name, error in report.failed.items():
        print(f"  failed: {name}: {error}", file=sys.stderr)
    return 1 if report.failed else 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="physrover",
        description="Multi-rover testbed: the tightly coupled rover domain and fitness critics.",
        epilog="Start with `physrover demo`; `physrover COMMAND --help` describes a command.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", title="commands")

    p = sub.add_parser("info", help="print the resolved run config ([domain], [learn]) as TOML")
    _add_config_args(p)
    p.set_defaults(func=cmd_info)

    p = sub.add_parser("train", help="train a team with the CCEA and a fitness method")
    _add_config_args(p)
    p.add_argument(
        "--method", help="fitness method, e.g. max-critic, D, average (list: physrover methods)"
    )
    p.add_argument("--n-req", dest="n_req", type=int, help="coupling n_req")
    p.add_argument("--motion", choices=["ideal", "physics"], help="motion model")
    p.add_argument("--generations", type=int, help="generations (with --resume: run up to)")
    p.add_argument("--seed", type=int, help="seed of every random draw")
    p.add_argument("--out", help="run directory (must not exist or be empty)")
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
    p.add_argument("--out", metavar="FILE.csv", help="also write each episode's G as CSV")
    p.set_defaults(func=cmd_evaluate)

    p = sub.add_parser("curves", help="learning curves (or final scores) with 95%% CI")
    p.add_argument("run_dirs", nargs="+", help="run directories, or directories holding them")
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

    p = sub.add_parser("demo", help="short max-critic training, then a curve and a video")
    p.add_argument("--generations", type=int, default=2000, help="generations (default 2000)")
    p.add_argument("--out", default="runs/demo", help="run directory (default runs/demo)")
    p.set_defaults(func=cmd_demo)

    p = sub.add_parser("sweep", help="run a grid of training runs (process pool or Ray)")
    p.add_argument("sweep_file", help="sweep TOML ([sweep], [base.*], [grid])")
    p.add_argument("--seeds", type=int, help="seeds per cell (default: the file's)")
    p.add_argument("--workers", type=int, help="parallel runs (default: CPU count)")
    p.add_argument("--ray", metavar="ADDRESS", help="run on Ray ('local' starts one here)")
    p.add_argument("--root", default="runs/sweeps", help="where sweeps go (default runs/sweeps)")
    p.add_argument("--dry-run", action="store_true", help="list the run directories only")
    p.add_argument(
        "--drop-state",
        action="store_true",
        help="delete each run's state.npz (~18 MB) when it finishes; it can then not be extended",
    )
    p.set_defaults(func=cmd_sweep)

    p = sub.add_parser("bench", help="time the world or the learner (benchmarks, not tests)")
    p.add_argument(
        "what",
        choices=["world", "train", "paper"],
        help="what to time ('paper': estimate the wall time of sweep files)",
    )
    p.add_argument(
        "sweeps", nargs="*", help="paper: sweep files (default: the paper's long sweeps)"
    )
    p.add_argument("--seeds", type=int, help="paper: seeds per cell (default: the file's)")
    p.add_argument("--workers", type=int, default=2, help="paper: parallel runs (default 2)")
    p.add_argument("--methods", help="comma-separated methods for 'train' (default: all)")
    _add_motion_args(p, "the config's")
    p.add_argument("--teams", type=int, default=50, help="teams stepped together (default 50)")
    p.add_argument("--repeats", type=int, default=20, help="timed runs/generations (default 20)")
    p.add_argument("--threads", type=int, default=1, help="torch/BLAS threads (default 1)")
    _add_config_args(p)
    p.set_defaults(func=cmd_bench)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:  # bare `physrover`: show the commands, not just "required"
        parser.print_help(sys.stderr)
        return 2
    if "PHYSROVER_ENGINE" in os.environ:  # physrover 0.1 had a numpy engine beside numba
        print("physrover: note: PHYSROVER_ENGINE is no longer read; the compiled kernels are "
              "the one implementation (NUMBA_DISABLE_JIT=1 runs them as Python)",
              file=sys.stderr)  # fmt: skip
    try:
        return args.func(args)
    except (ConfigError, UsageError, RunError, VideoError) as exc:
        print(f"physrover: error: {exc}", file=sys.stderr)
        return 2
    except Interrupted as exc:
        print(f"physrover: {exc}", file=sys.stderr)
        return 130
    except KeyboardInterrupt:
        print("physrover: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
