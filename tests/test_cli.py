"""The command line a new user meets: help, errors, messages, and the run files it writes."""

import argparse
import io
import os
import stat
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from physrover.cli import commands
from physrover.cli.main import build_parser, main
from physrover.config import ConfigError, RunConfig
from physrover.core.progress import Progress
from physrover.core.registry import FITNESS_METHODS, did_you_mean
from physrover.experiment.store import read_metrics
from physrover.experiment.training import train
from physrover.learn.fitness import SingleEpisode, register_method

TINY = ["--set", "n_rovers=3", "--set", "n_req=1", "--set", "population=4",
        "--set", "steps=5", "--set", "eval_episodes=2", "--method", "D"]  # fmt: skip


def _subcommands(parser):
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return action.choices


def test_help_of_every_parser_lists_its_options(capsys):
    parser = build_parser()
    commands = _subcommands(parser)
    assert {"info", "train", "methods", "render", "curves", "demo", "sweep", "bench"} <= set(
        commands
    )
    with pytest.raises(SystemExit) as exit_:
        main(["--help"])
    assert exit_.value.code == 0
    top = capsys.readouterr().out
    assert all(name in top for name in commands)
    for name, sub in commands.items():
        with pytest.raises(SystemExit) as exit_:
            main([name, "--help"])
        assert exit_.value.code == 0
        text = capsys.readouterr().out
        options = [o for a in sub._actions for o in a.option_strings if o.startswith("--")]
        assert options and all(o in text for o in options), name


def test_bare_command_lists_the_commands(capsys):
    assert main([]) == 2
    err = capsys.readouterr().err
    assert "commands:" in err and "train" in err and "methods" in err


def test_methods_lists_every_registered_method(capsys):
    name = "test-only-G"
    register_method(name, lambda cfg, n, steps, rng: SingleEpisode(True), "G again", "none")
    try:
        assert main(["methods"]) == 0
        out = capsys.readouterr().out
        for method, spec in FITNESS_METHODS.items():
            line = next(line for line in out.splitlines() if line.split()[:1] == [method])
            assert spec.summary in line and spec.section in line
            assert (f"[{spec.config.section}]" if spec.config else " - ") in line  # its table
        assert RunConfig().with_overrides({"method": name}).learn.method == name
        assert "scenarios:       ring, ring-random, uniform, explicit" in out
        sensors = next(line for line in out.splitlines() if "sensors:" in line)
        assert "density" in sensors and "quadrants" not in sensors  # an alias: not listed
    finally:
        del FITNESS_METHODS._entries[name]


def test_unknown_names_suggest_the_nearest(capsys):
    assert main(["info", "--set", "nreq=5"]) == 2
    assert "did you mean 'n_req'?" in capsys.readouterr().err
    assert main(["train", "--method", "max_critic"]) == 2
    assert "did you mean 'max-critic'" in capsys.readouterr().err
    assert did_you_mean("zzz", ["n_req", "d_cap"]) == ""
    with pytest.raises(ConfigError, match="did you mean 'physics'"):
        RunConfig().with_overrides({"motion": "phys"})


def test_config_errors_name_the_file_and_line(tmp_path, capsys):
    broken = tmp_path / "broken.toml"
    broken.write_text("[domain]\nn_req = 3\nn_rovers = \n")
    assert main(["info", "--config", str(broken)]) == 2
    err = capsys.readouterr().err
    assert str(broken) in err and "line 3" in err
    invalid = tmp_path / "invalid.toml"
    invalid.write_text("[domain]\nn_req = 0\n")
    assert main(["info", "--config", str(invalid)]) == 2
    assert f"{invalid}: n_req: must be in" in capsys.readouterr().err
    sweep = tmp_path / "sweep.toml"
    sweep.write_text("[sweep]\nname = 'x'\n[grid]\nnreq = [1, 2]\n")
    assert main(["sweep", str(sweep), "--dry-run"]) == 2
    assert str(sweep) in capsys.readouterr().err


def test_sweep_runs_a_chunk_of_seeds(tmp_path, capsys):
    sweep = tmp_path / "sweep.toml"
    sweep.write_text("[sweep]\nname = 'x'\nseeds = 10\n[grid]\nn_req = [1, 2]\n")
    assert main(["sweep", str(sweep), "--dry-run", "--root", str(tmp_path), "--seeds", "8:10"]) == 0
    listed = capsys.readouterr().out.split()
    assert [Path(p).name for p in listed] == [
        "n_req=1_seed=8", "n_req=2_seed=8", "n_req=1_seed=9", "n_req=2_seed=9"
    ]  # fmt: skip
    assert main(["sweep", str(sweep), "--dry-run", "--seeds", "10:8"]) == 2
    assert "seeds: must be" in capsys.readouterr().err


def test_sweep_skips_the_runs_a_results_table_lists_as_finished(tmp_path, capsys):
    """A later machine runs what no earlier one finished: listed with the config's
    generations (or more) is finished; fewer, another sweep's or unlisted runs are not."""
    sweep = tmp_path / "sweep.toml"
    sweep.write_text("[sweep]\nname = 'x'\nseeds = 2\n[base.learn]\ngenerations = 40\n"
                     "[grid]\nn_req = [1, 2]\n")  # fmt: skip
    table = tmp_path / "runs.csv"
    table.write_text("sweep,run,generations,final_G\n"
                     "x,n_req=1_seed=0,40,1.0\n"  # finished
                     "x,n_req=1_seed=1,39,1.0\n"  # cut short
                     "y,n_req=2_seed=0,40,1.0\n")  # another sweep's  # fmt: skip
    args = ["sweep", str(sweep), "--dry-run", "--root", str(tmp_path), "--skip-listed", str(table)]
    assert main(args) == 0
    out, err = capsys.readouterr()
    assert [Path(p).name for p in out.split()] == [
        "n_req=2_seed=0",
        "n_req=1_seed=1",
        "n_req=2_seed=1",
    ]
    assert "1 runs left out" in err
    table.write_text("sweep,run\nx,n_req=1_seed=0\n")
    assert main(args) == 2
    assert "no column 'generations'" in capsys.readouterr().err
    assert main([*args[:-1], str(tmp_path / "none.csv")]) == 2
    assert "is not a file" in capsys.readouterr().err


def test_sweep_status_counts_what_is_left(tmp_path, capsys):
    """--status runs nothing: each run not done with its checkpointed generations, then
    the counts and the share of their generations reached; --skip-listed's runs apart."""
    sweep = tmp_path / "sweep.toml"
    sweep.write_text("[sweep]\nname = 'x'\nseeds = 2\n[base.learn]\ngenerations = 40\n"
                     "[grid]\nn_req = [1, 2]\n")  # fmt: skip
    runs = tmp_path / "x"
    for name, generation in (("n_req=1_seed=0", 40), ("n_req=2_seed=0", 10)):
        (runs / name).mkdir(parents=True)
        (runs / name / "state.json").write_text(f'{{"generation": {generation}}}')
    (runs / "n_req=1_seed=1").mkdir()  # started, no checkpoint yet
    args = ["sweep", str(sweep), "--status", "--root", str(tmp_path)]
    assert main(args) == 0
    lines = capsys.readouterr().out.splitlines()
    assert [line.split()[:2] for line in lines[:-1]] == [
        ["partial", "10/40"], ["partial", "0/40"], ["new", "0/40"]
    ]  # fmt: skip
    assert [Path(line.split()[-1]).name for line in lines[:-1]] == [
        "n_req=2_seed=0", "n_req=1_seed=1", "n_req=2_seed=1"
    ]  # fmt: skip
    # (40 + 10) of 4 x 40 generations
    assert lines[-1] == "sweep x: 1 done, 2 partial, 1 new; 31.2% of their generations checkpointed"
    assert not (runs / "n_req=2_seed=1").exists()  # nothing ran
    table = tmp_path / "runs.csv"
    table.write_text("sweep,run,generations\nx,n_req=2_seed=1,40\n")
    assert main([*args, "--skip-listed", str(table)]) == 0
    last = capsys.readouterr().out.splitlines()[-1]
    assert last == (
        "sweep x: 1 done, 2 partial, 0 new; 41.7% of their generations checkpointed; "
        "1 more listed as finished by --skip-listed"
    )


def test_generation_numbers_agree_across_files(tmp_path):
    out = tmp_path / "run"
    stream = io.StringIO()
    config = RunConfig().with_overrides(
        {"n_rovers": 3, "n_req": 1, "population": 4, "steps": 5, "checkpoint_every": 2}
    )
    real = Progress.__init__

    def to_stream(self, *args, **kwargs):
        real(self, *args, **{**kwargs, "stream": stream})

    Progress.__init__ = to_stream
    try:
        train(config, out, generations=5, progress=True)
    finally:
        Progress.__init__ = real
    rows = read_metrics(out / "metrics.csv")
    assert [r["generation"] for r in rows] == [1, 2, 3, 4, 5]
    raw = (out / "metrics.csv").read_text().splitlines()
    assert raw[1].startswith("1,") and raw[-1].startswith("5,")
    champions = sorted(p.name for p in (out / "champions").iterdir())
    assert champions == ["gen_000002.npy", "gen_000004.npy", "gen_000005.npy"]
    assert "5/5" in stream.getvalue().splitlines()[-1]


def test_old_zero_based_metrics_are_read_from_one(tmp_path):
    path = tmp_path / "metrics.csv"
    path.write_text(
        "generation,eval_G,train_G_mean,fitness_mean,critic_loss,wall_seconds\n"
        "0,1,0,0,nan,0.1\n1,2,0,0,nan,0.2\n"
    )
    assert [r["generation"] for r in read_metrics(path)] == [1, 2]


@pytest.mark.parametrize("umask", [0o022, 0o002])
def test_run_files_follow_the_umask(tmp_path, umask):
    old = os.umask(umask)
    try:
        config = RunConfig().with_overrides({"n_rovers": 3, "n_req": 1, "population": 4})
        out = train(config, tmp_path / "run", generations=1, progress=False)
    finally:
        os.umask(old)
    files = [p for p in out.rglob("*") if p.is_file()]
    names = {p.name for p in files}
    assert {"config.toml", "metrics.csv", "state.npz", "state.json", "gen_000001.npy"} <= names
    for path in files:
        assert stat.S_IMODE(path.stat().st_mode) == 0o666 & ~umask, path.name


def test_unreachable_ray_address_fails_with_one_line(tmp_path, capsys):
    sweep = tmp_path / "sweep.toml"
    sweep.write_text(
        "[sweep]\nname = 'x'\n[base.domain]\nn_rovers = 3\nn_req = 1\n"
        "[base.learn]\ngenerations = 1\npopulation = 4\n[grid]\nmethod = ['D']\n"
    )
    argv = ["sweep", str(sweep), "--root", str(tmp_path), "--ray", "127.0.0.1:1"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert "no Ray cluster answers at 127.0.0.1:1" in err and "ray start --head" in err
    assert main([*argv[:-1], "127.0.0.1:port"]) == 2
    assert "bad address" in capsys.readouterr().err


def test_resume_of_a_finished_run_says_how_to_extend(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["train", *TINY, "--generations", "2", "--out", str(out), "--quiet"]) == 0
    capsys.readouterr()
    assert main(["train", "--resume", str(out), "--quiet"]) == 0
    said = capsys.readouterr().out
    assert f"{out} is already at 2 generations" in said
    assert f"physrover train --resume {out} --generations" in said


def test_ctrl_c_says_what_was_saved_and_how_to_resume(tmp_path, capsys, monkeypatch):
    from physrover.learn.ccea import CCEA

    real = CCEA.run_generation

    def interrupt_after_3(self):
        if self.generation == 3:
            raise KeyboardInterrupt
        return real(self)

    monkeypatch.setattr(CCEA, "run_generation", interrupt_after_3)
    out = tmp_path / "run"
    argv = ["train", *TINY, "--set", "checkpoint_every=2", "--out", str(out), "--quiet"]
    assert main(argv) == 130
    err = capsys.readouterr().err
    assert "the checkpoint after generation 2" in err
    assert f"physrover train --resume {out}" in err
    fresh = tmp_path / "fresh"
    argv = ["train", *TINY, "--set", "checkpoint_every=5", "--out", str(fresh), "--quiet"]
    assert main(argv) == 130
    assert "nothing saved yet" in capsys.readouterr().err


def test_tensorboard_events_hold_the_metrics(tmp_path):
    pytest.importorskip("tensorboard")
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    out = tmp_path / "run"
    assert main(["train", *TINY, "--generations", "3", "--out", str(out), "--quiet",
                 "--tensorboard"]) == 0  # fmt: skip
    events = EventAccumulator(str(out / "tensorboard"))
    events.Reload()
    rows = read_metrics(out / "metrics.csv")
    for column in ("eval_G", "train_G_mean", "fitness_mean", "wall_seconds"):
        scalars = events.Scalars(column)
        assert [s.step for s in scalars] == [1, 2, 3]
        np.testing.assert_allclose([s.value for s in scalars], [r[column] for r in rows], rtol=1e-6)


def test_demo_prints_a_table_of_both_models():
    table = commands._episode_table([7.0, 9.0, 6.0, 9.0], (1.0, 2.0, 3.0, 4.0))
    lines = table.splitlines()
    assert lines[0].split()[:5] == ["episode", "G", "ideal", "G", "physics"]
    assert lines[1].split() == ["1", "7", "9"] and lines[2].split() == ["2", "6", "9"]


def test_output_into_a_closed_pipe_ends_quietly(tmp_path):
    """`physrover ... | head`: the reader has gone before the output is written; the command
    exits with 141 (128 + SIGPIPE) and no traceback, instead of a BrokenPipeError."""
    read, write = os.pipe()
    os.close(read)  # every write into the pipe now fails with EPIPE
    try:
        done = subprocess.run(
            [sys.executable, "-c", "import sys; from physrover.cli import main; "
             "sys.exit(main(['methods']))"],
            stdout=write, stderr=subprocess.PIPE, text=True, timeout=120,
        )  # fmt: skip
    finally:
        os.close(write)
    assert done.returncode == 141, done.stderr
    assert "Traceback" not in done.stderr and "BrokenPipe" not in done.stderr


def test_bench_train_reports_median_spread_and_phases():
    """The line a method gets: its median between the fastest and slowest generation, and
    the mean time of each phase (a format check; no timing is asserted)."""
    import re

    from physrover.config import RunConfig
    from physrover.experiment.bench import bench_train

    config = RunConfig().with_overrides(dict(n_rovers=3, n_req=1, population=10, steps=10))
    (line,) = bench_train(config, ["max-critic"], generations=3)
    found = re.fullmatch(
        r"max-critic +median +([\d.]+) ms/generation \(min ([\d.]+), max ([\d.]+); "
        r"mean per phase: (.*)\)",
        line,
    )
    assert found, line
    median, low, high = map(float, found.groups()[:3])
    assert low <= median <= high
    assert {part.split()[0] for part in found.group(4).split(", ")} >= {"rollout", "critic"}


def test_bench_train_against_interleaves_two_configs_and_states_their_ratios(capsys, tmp_path):
    """``--against``: both configs' medians and their ratios per phase (format and
    arithmetic; no timing asserted), and a one-line error for a benchmark it does not
    time."""
    import re

    # 7 steps against the paper's 50, the --set fields in both: the same kernels' types,
    # nothing new to compile (a --set steps would make the two configs one)
    longer = tmp_path / "longer.toml"
    longer.write_text("[domain]\nsteps = 7\n")
    args = ["bench", "train", "--methods", "D", "--repeats", "3", "--config", str(longer),
            "--against", "paper", "--set", "n_rovers=3", "--set", "n_req=1",
            "--set", "population=6"]  # fmt: skip
    assert main(args) == 0
    out = capsys.readouterr().out
    (line,) = [row for row in out.splitlines() if row.startswith("D ")]
    parts = re.findall(r"(\w+) ([\d.]+) / ([\d.]+)(?: = ([\d.]+)x)?", line)
    assert {name for name, *_ in parts} == {"generation", "rollout", "feedback", "evolution",
                                            "critic"}  # fmt: skip
    for name, ours, theirs, ratio in parts:  # the ratio of the medians before rounding
        if ratio:
            ours, theirs = float(ours), float(theirs)
            low, high = (ours - 0.05) / (theirs + 0.05), (ours + 0.05) / (theirs - 0.05)
            assert low - 0.005 <= float(ratio) <= high + 0.005, name
    assert main(["bench", "world", "--against", "paper"]) == 2
    assert capsys.readouterr().err.strip() == (
        "physrover: error: --against times 'bench train', not 'bench world'"
    )


def test_bench_envs_drives_every_torchrl_env_with_the_actions_drawn_beforehand():
    """The throughput table times the envs, not the drawing of actions: the policy writes
    its bank of pre-drawn actions in turn, episode after episode."""
    import torch

    pytest.importorskip("torchrl")
    from physrover.envs.torchrl_env import RoverTorchEnv
    from physrover.experiment.bench_envs import _replay_policy

    env = RoverTorchEnv(2, n_rovers=3, steps=4)
    policy = _replay_policy(env, 4)
    rollout = env.rollout(8, policy, break_when_any_done=False)
    actions = rollout["rover", "action"]  # (2 teams, 8 steps, 3, 2)
    assert torch.equal(actions[:, :4], actions[:, 4:])
    assert not torch.equal(actions[:, 0], actions[:, 1])


def test_bench_world_scaling_spreads_large_teams_and_rejects_bad_sizes(capsys):
    from physrover.config import DomainConfig
    from physrover.experiment.bench import scaling_config

    config = scaling_config(DomainConfig(n_req=3), 1000)
    assert config.n_rovers == 1000 and config.scenario.spawn_radius == pytest.approx(40.0)
    assert scaling_config(DomainConfig(n_req=3), 15) == DomainConfig(n_rovers=15, n_req=3)
    assert scaling_config(DomainConfig(n_req=3), 2).n_req == 2
    with pytest.raises(SystemExit):
        main(["bench", "world", "--rovers", "15,0"])
    assert "positive integers" in capsys.readouterr().err


def test_bench_train_checks_set_fields_against_the_methods_it_times(capsys):
    """A trajectory critic's fields are accepted when it is the method timed (they were
    once checked against the default max critic and refused)."""
    from physrover.cli import main

    args = ["bench", "train", "--methods", "recurrent-max-critic", "--repeats", "1",
            "--set", "n_rovers=3", "--set", "n_req=1", "--set", "population=6",
            "--set", "steps=5", "--set", "trajectory_hidden=4"]  # fmt: skip
    assert main(args) == 0
    assert "recurrent-max-critic" in capsys.readouterr().out
    refused = ["bench", "train", "--methods", "max-critic", "--set", "trajectory_hidden=4"]
    assert main(refused) == 2
    assert "trajectory_hidden" in capsys.readouterr().err


def test_a_resume_says_where_it_starts(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["train", *TINY, "--generations", "2", "--out", str(out), "--quiet"]) == 0
    capsys.readouterr()
    assert main(["train", "--resume", str(out), "--generations", "3", "--quiet"]) == 0
    assert f"resuming {out} from generation 2 to 3" in capsys.readouterr().err


def test_quiet_names_the_run_directory_once(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["train", *TINY, "--generations", "1", "--quiet"]) == 0
    said = capsys.readouterr()
    assert (said.out + said.err).count("run directory:") == 1


def test_no_run_directory_is_named_for_a_run_that_cannot_start(tmp_path, capsys, monkeypatch):
    from physrover.experiment.loop import TensorBoardLog

    def missing():
        raise ConfigError("tensorboard", "needs the tensorboard package")

    monkeypatch.setattr(TensorBoardLog, "check_installed", staticmethod(missing))
    monkeypatch.chdir(tmp_path)
    assert main(["train", *TINY, "--generations", "1", "--tensorboard"]) != 0
    said = capsys.readouterr()
    assert "run directory:" not in said.out + said.err
    assert "needs the tensorboard package" in said.err
    assert not (tmp_path / "runs").exists()


def test_agents_and_pois_tables_are_not_set_by_name(capsys):
    assert main(["train", *TINY, "--set", "agents.count=3"]) != 0
    err = capsys.readouterr().err.strip()
    assert err.endswith("agents.count: [[agents]] tables cannot be changed with --set or a "
                        "sweep's grid: edit the TOML")  # fmt: skip
    assert "\n" not in err


def test_reports_pass_over_files_a_glob_matches_and_name_what_is_missing(tmp_path, capsys):
    sweep = tmp_path / "sweep"
    train(RunConfig().with_overrides({"n_rovers": 3, "n_req": 1, "population": 4, "steps": 5,
                                      "eval_episodes": 2, "method": "D"}),
          sweep / "a", generations=2, progress=False)  # fmt: skip
    (sweep / "curves.csv").write_text("left by an earlier call\n")
    globbed = [str(p) for p in sorted(sweep.iterdir())]  # what runs/sweeps/x/* expands to
    assert main(["curves", *globbed, "--out", str(tmp_path / "c.png")]) == 0
    assert (tmp_path / "c.png").is_file()
    capsys.readouterr()
    assert main(["curves", str(tmp_path / "nowhere")]) != 0
    assert capsys.readouterr().err.strip() == f"physrover: error: {tmp_path / 'nowhere'} does " \
        "not exist"  # fmt: skip
    assert main(["results", str(sweep / "a")]) != 0
    assert "is a run directory; results reads sweeps" in capsys.readouterr().err


def test_nothing_to_draw_is_said_without_a_field_prefix(tmp_path, capsys):
    run = tmp_path / "run"
    train(RunConfig().with_overrides({"n_rovers": 3, "n_req": 1, "population": 4, "steps": 5,
                                      "eval_episodes": 2, "method": "D"}),
          run, generations=1, progress=False)  # fmt: skip
    (run / "metrics.csv").write_text((run / "metrics.csv").read_text().splitlines()[0] + "\n")
    assert main(["curves", str(run), "--out", str(tmp_path / "c.png")]) != 0
    err = capsys.readouterr().err.strip()
    assert err.startswith("physrover: error: no generation in ")


def test_a_warning_is_named_by_the_package_that_raised_it(tmp_path, capsys):
    """physrover's own warnings read "physrover: warning:"; another package's (TorchRL's
    deprecations under `physrover benchmarl`) are named by that package, in one line."""
    from physrover.cli.main import _show_warning, warning_origin

    theirs = tmp_path / "lib" / "python3.11" / "site-packages" / "torchrl" / "envs" / "libs.py"
    assert warning_origin(str(theirs)) == "torchrl"
    assert warning_origin(str(tmp_path / "my_parts.py")) == "physrover"  # a researcher's file
    import physrover.learn.ccea as ours

    assert warning_origin(ours.__file__) == "physrover"
    _show_warning(DeprecationWarning("old API\nsecond line"), DeprecationWarning, str(theirs), 3)
    _show_warning(UserWarning("resuming from the previous checkpoint"), UserWarning,
                  ours.__file__, 9)  # fmt: skip
    assert capsys.readouterr().err.splitlines() == [
        "torchrl: warning: old API",
        "physrover: warning: resuming from the previous checkpoint",
    ]


def test_benchmarl_runs_stop_in_one_line_and_say_when_the_default_experiment_is_long():
    from physrover.cli.benchmarl_cmd import run_experiment, runs_default_experiment
    from physrover.cli.commands import Interrupted

    class Experiment:
        folder_name = "runs/benchmarl/mappo_rover_domain_mlp__x"

        def run(self):
            raise KeyboardInterrupt

    with pytest.raises(Interrupted, match="interrupted; what BenchMARL wrote so far is in "
                                          "runs/benchmarl/mappo_rover_domain_mlp__x"):  # fmt: skip
        run_experiment(Experiment())
    assert runs_default_experiment(["algorithm=masac", "task.n_req=1"])
    assert not runs_default_experiment(["experiment=physrover_quick"])
    assert not runs_default_experiment(["experiment.max_n_iters=5"])
    assert runs_default_experiment(["experiments_note=1"])  # not the experiment group


def test_the_venv_the_docs_make_inside_the_clone_is_ignored_by_git():
    import shutil
    import subprocess
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    if shutil.which("git") is None or not (root / ".git").exists():
        pytest.skip("needs a git checkout")
    assert "python3 -m venv .venv-benchmarl" in (root / "docs/user-guide/torchrl-benchmarl.md"
                                                 ).read_text()  # fmt: skip
    done = subprocess.run(["git", "check-ignore", "-q", ".venv-benchmarl/bin/python"], cwd=root)
    assert done.returncode == 0
