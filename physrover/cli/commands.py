"""What each ``physrover`` command does: one ``cmd_NAME(args)`` per command, calling library
functions with the parsed arguments and printing the results.

:mod:`physrover.cli` builds the parser and runs these. A command raises :class:`UsageError`
for a user error and :class:`Interrupted` for Ctrl-C with something to say; the command line
prints either as one line, never as a traceback.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from physrover.config import RunConfig, parse_override
from physrover.core.registry import FITNESS_METHODS
from physrover.core.threads import pin_threads
from physrover.experiment.store import find_runs, last_checkpoint, load_run_config


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


def cmd_info(args: argparse.Namespace) -> int:
    print(_run_config(args).to_toml(), end="")
    return 0


def cmd_methods(args: argparse.Namespace) -> int:
    width = max(len(name) for name in FITNESS_METHODS)
    sections = max(len(spec.section) for _, spec in FITNESS_METHODS.items())
    print(f"{'method':{width}}  {'paper':{sections}}  fitness of a policy")
    for name, spec in FITNESS_METHODS.items():
        print(f"{name:{width}}  {spec.section:{sections}}  {spec.summary}")
    from physrover.core.registry import TRAINERS

    print("\ngradient-based trainers (their table: [NAME]; length: total_episodes):")
    for name, spec in TRAINERS.items():
        print(f"{name:{width}}  {spec.reference:{sections}}  {spec.summary}")
    print('\nchoose with: physrover train --method NAME  (or [learn] method = "NAME")')
    from physrover.core.registry import CREDITS, DYNAMICS, SCENARIOS, SENSORS

    print("\nthe other seams (physrover.core.registry; docs/extending.md):")
    for label, registry, how in (
        ("credit signals", CREDITS, "--set feedback=NAME"),
        ("scenarios", SCENARIOS, "--set scenario=NAME"),
        ("sensors", SENSORS, "--set sensor=NAME"),
        ("motion models", DYNAMICS, "--set motion=NAME"),
    ):
        print(f"  {label + ':':16} {', '.join(registry.names()):38} {how}")
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
    from physrover.experiment.training import train

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
        n_req = "-".join(map(str, config.domain.n_req_per_poi))
        if len(set(config.domain.n_req_per_poi)) == 1:
            n_req = str(config.domain.n_req_per_poi[0])
        out = Path(
            args.out or f"runs/{cfg.method}_{config.domain.motion}_nreq{n_req}_seed{cfg.seed}"
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
    from physrover.experiment import bench

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
    from physrover.experiment.sweep import Sweep

    files = args.sweeps or list(PAPER_SWEEPS)
    grand = 0.0
    for path in files:
        sweep = Sweep.load(path)
        specs = sweep.runs("runs/sweeps", seeds=_seeds(args.seeds))
        estimates = bench.estimate_sweep(specs, timer=lambda c: bench.time_step(c, args.repeats))
        wall = bench.sweep_wall_time(estimates, args.workers)
        grand += wall
        print(f"{sweep.name}: {len(specs)} runs, {len(estimates)} cells")
        for e in sorted(estimates, key=lambda e: -e.total_seconds):
            per_gen = 1000 * e.seconds_per_generation
            print(f"  {e.label:40s} {per_gen:7.1f} ms/{e.unit} x {e.generations} {e.unit} x "
                  f"{e.runs} runs = {e.total_seconds / 60:6.1f} min")  # fmt: skip
        print(f"  estimated wall time on {args.workers} workers: {wall / 3600:.2f} h")
    if len(files) > 1:
        print(f"all {len(files)} sweeps: {grand / 3600:.2f} h on {args.workers} workers")
    return 0


def cmd_render(args: argparse.Namespace) -> int:
    from physrover.experiment.playback import record_run
    from physrover.viz.render import RenderConfig

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
    from physrover.experiment.evaluate import EVAL_SEED, evaluate_run

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
    from physrover.analysis import plots

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
    if args.last < 1 or args.smooth < 1:
        raise UsageError("--last and --smooth must be >= 1")
    out = Path(args.out) if args.out else sweeps[0].parent / "results"
    results, messages = write_results(sweeps, out, args.last, args.smooth)
    for message in messages:
        print(message, file=sys.stderr)
    rows = sum(len(r.rows) for r in results)
    print(f"results of {len(results)} sweep(s), {rows} runs: {out}")
    return 0


def cmd_demo(args: argparse.Namespace) -> int:
    from physrover.analysis import plots
    from physrover.experiment.playback import record_run
    from physrover.experiment.training import train

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


def _seeds(text: str | None) -> int | range | None:
    """``--seeds`` of sweep and bench paper (:func:`physrover.experiment.sweep.parse_seeds`)."""
    from physrover.experiment.sweep import parse_seeds

    return None if text is None else parse_seeds(text)


def cmd_sweep(args: argparse.Namespace) -> int:
    from physrover.experiment.execute import run_sweep
    from physrover.experiment.sweep import Sweep

    sweep = Sweep.load(args.sweep_file)
    specs = sweep.runs(args.root, seeds=_seeds(args.seeds), drop_state=args.drop_state)
    listed = set()
    if args.skip_listed:
        from physrover.experiment.sweep import listed_finished

        listed = listed_finished(specs, args.skip_listed, sweep.name)
        specs = [spec for spec in specs if spec.name not in listed]
        print(f"sweep {sweep.name}: {len(listed)} runs left out, finished in {args.skip_listed}",
              file=sys.stderr)  # fmt: skip
    if args.status:
        from physrover.experiment.sweep import status_report

        print("\n".join(status_report(sweep.name, specs, listed=len(listed))))
        return 0
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
