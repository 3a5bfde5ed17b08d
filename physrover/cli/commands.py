"""What each ``physrover`` command does: one ``cmd_NAME(args)`` per command, calling library
functions with the parsed arguments and printing the results.

:mod:`physrover.cli` builds the parser and runs these. A command raises :class:`UsageError`
for a user error and :class:`Interrupted` for Ctrl-C with something to say; the command line
prints either as one line, never as a traceback.
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

from physrover.config import RunConfig, parse_override
from physrover.core.registry import FITNESS_METHODS
from physrover.core.threads import pin_threads
from physrover.experiment.claims import check_free
from physrover.experiment.loop import TensorBoardLog
from physrover.experiment.store import last_checkpoint, load_run_config


class UsageError(Exception):
    """A user-facing error: printed as one line, exit status 2."""


class Interrupted(Exception):
    """Ctrl-C, with what was saved and how to continue: printed as one line, status 130."""


def _run_config(args: argparse.Namespace, path: str | None = None) -> RunConfig:
    """RunConfig from ``--config FILE`` ([domain] and [learn]) or ``path`` (``"paper"``:
    the defaults), ``--set`` and shortcut flags."""
    path = getattr(args, "config", None) if path is None else path
    config = RunConfig.load(path) if path and path != "paper" else RunConfig()
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
    ):
        if getattr(args, flag, None) is not None:
            overrides[field] = getattr(args, flag)
    config = config.with_overrides(overrides)
    for unit in ("generation", "iteration"):  # the length, in the learner's own unit
        n = getattr(args, f"{unit}s", None)
        if n is not None:
            config = config.with_length(n, unit)
    return config


def _default_out(config: RunConfig, args: argparse.Namespace) -> Path:
    """``runs/METHOD_MOTION_nreqN_seedS``, then each ``--set FIELD=VALUE`` given (so a run
    of another config never lands in a run of this one's folder), or the next free name
    (``-2``, ``-3``, ...) where that folder holds a run already."""
    cfg = config.learn
    n_req = "-".join(map(str, config.domain.n_req_per_poi))
    if len(set(config.domain.n_req_per_poi)) == 1:
        n_req = str(config.domain.n_req_per_poi[0])
    name = f"{cfg.method}_{config.domain.motion}_nreq{n_req}_seed{cfg.seed}"
    for text in sorted(getattr(args, "set", None) or []):
        field, value = (part.strip() for part in text.split("=", 1))
        name += "_" + re.sub(r"[^\w.,+=-]", "", f"{field}={value}")
    return next_free(Path("runs") / name)


def next_free(base: Path) -> Path:
    """``base``, or ``base-2``, ``base-3``, ... : the first that holds no run (missing or
    an empty directory)."""
    out, n = base, 1
    while out.exists() and (not out.is_dir() or any(out.iterdir())):
        n += 1
        out = base.with_name(f"{base.name}-{n}")
    return out


def cmd_info(args: argparse.Namespace) -> int:
    print(_run_config(args).to_toml(), end="")
    return 0


def cmd_methods(args: argparse.Namespace) -> int:
    width = max(len(name) for name in FITNESS_METHODS)
    sections = max(len(spec.section) for _, spec in FITNESS_METHODS.items())
    tables = {name: f"[{spec.config.section}]" if spec.config else "-"
              for name, spec in FITNESS_METHODS.items()}  # fmt: skip
    own = max(len("settings"), *map(len, tables.values()))
    print(f"{'method':{width}}  {'paper':{sections}}  {'settings':{own}}  fitness of a policy")
    for name, spec in FITNESS_METHODS.items():
        print(f"{name:{width}}  {spec.section:{sections}}  {tables[name]:{own}}  {spec.summary}")
    from physrover.core.registry import TRAINERS

    print("\ngradient-based trainers (their table: [NAME]; length: total_episodes):")
    for name, spec in TRAINERS.items():
        print(f"{name:{width}}  {spec.reference:{sections}}  {spec.summary}")
    print(
        '\nchoose with: physrover train --method NAME  (or [learn] method = "NAME"); its '
        "settings: physrover info --set method=NAME"
    )
    print("a trainer beside a fitness method, its actor migrating into the populations (MERL): "
          "--set hybrid=mappo  ([hybrid]; physrover info --set hybrid=mappo)")  # fmt: skip
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


def _interrupted(out: Path, unit: str = "generation") -> str:
    """What a Ctrl-C left in run directory ``out`` and how to continue (``unit``: what the
    run counts, generations or a trainer's iterations)."""
    saved = last_checkpoint(out)
    what = (
        f"saved: the checkpoint after {unit} {saved}"
        if saved is not None
        else f"nothing saved yet (the first checkpoint comes after checkpoint_every {unit}s)"
    )
    return f"interrupted; {what}. Continue with: physrover train --resume {out}"


def cmd_train(args: argparse.Namespace) -> int:
    from physrover.experiment.training import train

    pin_threads(args.threads)
    if args.resume:
        given = [args.config, args.set, args.method, args.n_req, args.motion, args.seed, args.out]
        if any(v is not None for v in given):
            raise UsageError("--resume continues a run with its own config; only --generations "
                             "(or a trainer's --iterations) applies")  # fmt: skip
        out = Path(args.resume)
        config = load_run_config(out)
        length = args.generations if args.generations is not None else args.iterations
        if length is not None:
            unit = "generation" if args.generations is not None else "iteration"
            config = config.with_length(length, unit)
        done = last_checkpoint(out)
        if done is not None and done >= config.length:
            flag = f"--{config.unit}s"
            print(f"{out} is already at {done} {config.unit}s; to extend it: "
                  f"physrover train --resume {out} {flag} {done + 1000}")  # fmt: skip
            return 0
    else:
        config = _run_config(args)
        out = Path(args.out) if args.out else _default_out(config, args)
    if args.tensorboard:  # before naming a run directory that nothing will be written to
        TensorBoardLog.check_installed()
    if args.resume:
        check_free(out)  # another process training it: say so before anything else
    elif not args.out and not args.quiet:  # a name of its own: say it first
        print(f"run directory: {out}", file=sys.stderr)
    try:
        if args.resume:

            def said(generation: int) -> None:  # once the checkpoint has loaded
                print(f"resuming {out} from {config.unit} {generation} to {config.length}",
                      file=sys.stderr)  # fmt: skip

            train(None, out, resume=True, generations=args.generations,
                  iterations=args.iterations, progress=not args.quiet,
                  tensorboard=args.tensorboard, on_resumed=said)  # fmt: skip
        else:
            train(config, out, progress=not args.quiet, tensorboard=args.tensorboard)
    except KeyboardInterrupt:
        raise Interrupted(_interrupted(out, config.unit)) from None
    print(f"run directory: {out}")
    return 0


def cmd_bench(args: argparse.Namespace) -> int:
    from physrover.experiment import bench

    pin_threads(args.threads)
    if args.against and args.what != "train":
        raise UsageError(f"--against times 'bench train', not 'bench {args.what}'")
    if args.what == "train" and args.methods:  # --set is checked against the first method
        args.method = args.methods.split(",")[0]  # (a trajectory critic's fields, say)
    config = _run_config(args)
    if args.what == "world" and args.rovers:
        d = config.domain
        print(f"world: M rover-steps per second, reset + {d.steps} steps, random actions, "
              f"motion={d.motion}, about 1500 rovers in all, median of {args.repeats}, "
              f"{args.threads} thread(s)")  # fmt: skip
        print("| rovers per team | teams | M rover-steps/s |\n|---|---|---|")
        for n_rovers, teams, rate in bench.bench_scaling(d, args.rovers, repeats=args.repeats):
            print(f"| {n_rovers} | {teams} | {rate:.2f} |")
        return 0
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
        if args.against:
            against = _run_config(args, args.against)
            print(f"against {args.against}: its generations interleaved with these, in one "
                  "process (the same --motion, --collisions and --set)")  # fmt: skip
            lines = bench.bench_train_against(config, against, methods, args.repeats)
        else:
            lines = bench.bench_train(config, methods, generations=args.repeats)
        for line in lines:
            print(line)
        return 0
    if args.what == "paper":
        return _bench_paper(args, bench)
    if args.what == "envs":
        from physrover.experiment.bench_envs import bench_envs

        d = config.domain
        print(f"envs: {d.n_rovers} rovers, {d.n_pois} POIs, n_req {max(d.n_req_per_poi)}, "
              f"{d.steps} steps, motion={d.motion}; team steps per second, median of "
              f"{args.repeats} episodes, {args.threads} thread(s)")  # fmt: skip
        print("| env | teams | team steps/s | note |\n|---|---|---|---|")
        for row in bench_envs(d, teams=args.teams, repeats=args.repeats):
            print(row.line())
        return 0
    raise UsageError(f"unknown benchmark {args.what!r}")


PAPER_SWEEPS = ("fig4-7-long", "fig8-9-paper")  # shipped (physrover/sweeps)


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

    render = RenderConfig(width=args.size, height=args.size, fps=args.fps, ids=args.ids)
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
    if args.side_by_side:  # the scores alternate ideal, physics: a table, as demo prints
        config = load_run_config(run_dir)
        print(f"video: {path}\n{_episode_table(scores, config.domain.poi_values)}")
    else:
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
        n_req=args.n_req,
    )
    print(result.line())
    if args.out:
        print(f"per-episode G: {result.write_csv(args.out)}")
    return 0


def cmd_demo(args: argparse.Namespace) -> int:
    from physrover.analysis import plots
    from physrover.experiment.playback import record_run
    from physrover.experiment.training import train

    pin_threads(1)
    out = next_free(Path(args.out))
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
    from physrover.experiment.sweep import Sweep, resolve_sweep_file

    sweep = Sweep.load(args.sweep_file).with_overrides(
        dict(parse_override(text) for text in args.set or [])
    )
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
    sweep.write_copy(args.root, resolve_sweep_file(args.sweep_file).read_text())
    try:
        report = run_sweep(specs, workers=args.workers, ray_address=args.ray)
    except KeyboardInterrupt:
        again = " ".join(["physrover", *sys.argv[1:]]) if sys.argv[1:] else "the same command"
        raise Interrupted(
            "sweep interrupted; finished runs are kept and the others resume from their last "
            f"checkpoint when you run it again: {again}"
        ) from None
    ran = len(report.finished)
    print(
        f"sweep {sweep.name}: {ran} run{'s' * (ran != 1)} trained, {report.skipped} already "
        f"done, {len(report.failed)} failed, {report.seconds:.0f} s"
    )
    for name, error in report.failed.items():
        print(f"  failed: {name}: {error}", file=sys.stderr)
    return 1 if report.failed else 0
