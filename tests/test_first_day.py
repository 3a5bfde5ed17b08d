"""The rough edges a new user hit on their first day (issue 30), each fixed and kept fixed:
every test here failed before its fix."""

import signal
import sys

import pytest

import physrover
from physrover.cli import main
from physrover.config import RunConfig
from physrover.experiment.store import prepare_run_dir, read_metrics
from physrover.marl.common import Trainer

SMALL = ["--set", "n_rovers=3", "--set", "n_req=1", "--set", "steps=10", "--quiet"]
TRAINER = [*SMALL, "--set", "num_envs=4", "--set", "eval_episodes=2"]


def _err(capsys) -> list[str]:
    return capsys.readouterr().err.strip().splitlines()


def test_a_trainer_is_measured_in_iterations_and_says_so(tmp_path, capsys, monkeypatch):
    out = tmp_path / "mappo"
    # --generations was silently ignored: 250,000 episodes were trained instead
    assert main(["train", "--method", "mappo", "--generations", "10", *TRAINER,
                 "--out", str(out)]) == 2  # fmt: skip
    assert _err(capsys) == ["physrover: error: --generations: mappo trains in iterations (4 "
                            "episodes each), not generations: use --iterations N"]  # fmt: skip
    assert not out.exists()
    assert main(["train", "--method", "mappo", "--iterations", "2", *TRAINER,
                 "--out", str(out)]) == 0  # fmt: skip
    assert [r["episodes"] for r in read_metrics(out / "metrics.csv")] == [4, 8]
    assert main(["train", "--resume", str(out), "--generations", "3"]) == 2
    assert main(["train", "--resume", str(out), "--iterations", "3", "--quiet"]) == 0
    assert len(read_metrics(out / "metrics.csv")) == 3
    assert RunConfig.load(out / "config.toml").trainer.total_episodes == 12
    assert main(["train", "--generations", "2", *SMALL, "--iterations", "2",
                 "--out", str(tmp_path / "ccea")]) == 2  # fmt: skip
    assert "the CCEA) trains in generations, not iterations" in _err(capsys)[-1]
    # a stop says where it stopped in the trainer's own unit
    real = Trainer.iteration

    def stop_at_4(self):
        if self.iterations == 3:
            signal.raise_signal(signal.SIGINT)
        return real(self)

    monkeypatch.setattr(Trainer, "iteration", stop_at_4)
    assert main(["train", "--resume", str(out), "--iterations", "5", "--quiet"]) == 130
    assert "saved: the checkpoint after iteration 4" in _err(capsys)[-1]


def test_the_default_run_folder_follows_the_config_or_takes_the_next_free_name(
    tmp_path, capsys, monkeypatch
):
    monkeypatch.chdir(tmp_path)
    args = ["train", "--generations", "2", "--quiet"]
    assert main([*args, "--set", "n_rovers=4"]) == 0
    assert main([*args, "--set", "n_rovers=4"]) == 0  # not "exists ... use --resume"
    assert main([*args, "--set", "n_rovers=5"]) == 0
    runs = sorted(p.name for p in (tmp_path / "runs").iterdir())
    assert runs == [
        "max-critic_ideal_nreq3_seed0_n_rovers=4",
        "max-critic_ideal_nreq3_seed0_n_rovers=4-2",
        "max-critic_ideal_nreq3_seed0_n_rovers=5",
    ]
    assert RunConfig.load(tmp_path / "runs" / runs[2] / "config.toml").domain.n_rovers == 5
    said = capsys.readouterr()  # --quiet: named once, when the run is written
    assert "run directory: runs/max-critic_ideal_nreq3_seed0_n_rovers=4-2" in said.out
    assert "run directory:" not in said.err


def test_zero_generations_and_runs_without_generations_are_errors(tmp_path, capsys):
    assert main(["train", "--generations", "0", *SMALL, "--out", str(tmp_path / "r")]) == 2
    assert _err(capsys) == ["physrover: error: generations: must be >= 1, got 0"]
    assert not (tmp_path / "r").exists()  # before: a run without provenance
    prepare_run_dir(tmp_path / "empty", RunConfig())  # started, no generation yet
    assert main(["curves", str(tmp_path / "empty")]) == 2  # before: an empty plot, status 0
    assert "nothing to draw" in _err(capsys)[-1]
    assert main(["table", str(tmp_path / "empty")]) == 2  # before: an empty table
    assert not (tmp_path / "empty" / "curves.png").exists()


def test_tensorboard_without_the_package_leaves_nothing_behind(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "torch.utils.tensorboard", None)  # import fails
    out = tmp_path / "run"
    assert main(["train", "--generations", "2", *SMALL, "--tensorboard", "--out", str(out)]) == 2
    assert "pip install 'physrover[tensorboard]'" in _err(capsys)[-1]
    assert not out.exists()  # before: a half-made directory the next run refused


def test_render_checks_before_it_writes_and_labels_the_two_models(tmp_path, capsys):
    run = tmp_path / "run"
    assert main(["train", "--generations", "2", *SMALL, "--out", str(run)]) == 0
    video = run / "episodes.mp4"
    assert main(["render", str(run), "--episodes", "1"]) == 0
    good = video.read_bytes()
    assert main(["render", str(run), "--episodes", "0"]) == 2  # before: a 0-byte file
    assert video.read_bytes() == good
    capsys.readouterr()
    assert main(["render", str(run), "--episodes", "2", "--side-by-side"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[1].startswith("episode  G ideal  G physics") and len(out) == 4
    assert not list(run.glob(".*.partial"))


def test_version_usage_and_help(capsys):
    with pytest.raises(SystemExit) as exited:
        main(["--version"])
    assert exited.value.code == 0 and capsys.readouterr().out == (
        f"physrover {physrover.__version__}\n"
    )
    with pytest.raises(SystemExit):
        main(["train", "--generatoins", "3"])
    err = capsys.readouterr().err
    assert err.startswith("usage: physrover train")  # the command's usage, not the top's
    assert "unrecognized arguments: --generatoins 3" in err
    with pytest.raises(SystemExit):
        main(["table", "--help"])
    text = capsys.readouterr().out
    assert "95%" in text and "95%%" not in text


def test_sweep_set_shortens_a_sweep_under_a_name_of_its_own(tmp_path, capsys):
    sweep = tmp_path / "s.toml"
    sweep.write_text('[sweep]\nname = "s"\n[base.domain]\nn_rovers = 3\nn_req = 1\nsteps = 10\n'
                     '[base.learn]\ngenerations = 500\n[grid]\nmethod = ["D", "G"]\n')  # fmt: skip
    root = tmp_path / "root"
    assert main(["sweep", str(sweep), "--set", "generations=3", "--root", str(root),
                 "--workers", "1"]) == 0  # fmt: skip
    runs = sorted(p for p in (root / "s+generations=3").iterdir() if p.is_dir())
    assert (root / "s+generations=3" / "sweep.toml").is_file()  # the file, for results
    assert [len(read_metrics(r / "metrics.csv")) for r in runs] == [3, 3]
    assert not (root / "s").exists()  # the file's own runs are not these
    assert "2 runs trained" in capsys.readouterr().out  # was "2 run"
    assert main(["sweep", str(sweep), "--set", "method=D", "--dry-run"]) == 2
    assert "method: is varied by sweep s's grid" in _err(capsys)[-1]
    sweep.write_text(sweep.read_text().replace('["D", "G"]', '["D", "max-critc"]'))
    assert main(["sweep", str(sweep), "--dry-run"]) == 2  # the second value is checked too
    assert _err(capsys)[-1].startswith(f"physrover: error: {sweep}: method")


def test_one_episode_is_one_episode(tmp_path, capsys):
    run = tmp_path / "run"
    assert main(["train", "--generations", "2", *SMALL, "--out", str(run)]) == 0
    assert main(["evaluate", str(run), "--episodes", "1"]) == 0
    assert "over 1 episode\n" in capsys.readouterr().out + "\n"


def test_sweep_files_ship_with_the_package_and_run_by_name(tmp_path, capsys, monkeypatch):
    """A wheel installed anywhere reproduces the paper: the sweep files are package data,
    found by name from any directory (a path still works)."""
    import shutil
    import subprocess
    import zipfile
    from pathlib import Path

    from physrover.experiment.sweep import shipped_sweeps

    shipped = shipped_sweeps()
    assert {"fig4-7-long", "fig8-9-paper", "smoke"} <= set(shipped)
    monkeypatch.chdir(tmp_path)  # no experiments/ here
    assert main(["sweep", "fig4-7-long", "--dry-run"]) == 0
    assert len(capsys.readouterr().out.splitlines()) == 160  # 4 methods x 4 n_req x 10 seeds
    assert main(["sweep", str(shipped["smoke"]), "--dry-run"]) == 0  # a path, as before
    assert main(["sweep", "fig4-7-lng", "--dry-run"]) == 2
    assert "shipped: ablation" in _err(capsys)[-1]
    if shutil.which("pip") is None:
        pytest.skip("needs pip to build the wheel")
    root = Path(__file__).parent.parent
    built = subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "-w",
                            str(tmp_path), str(root)],
                           capture_output=True, text=True, timeout=300)  # fmt: skip
    assert built.returncode == 0, built.stderr[-2000:]
    (wheel,) = tmp_path.glob("physrover-*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    assert {f"physrover/sweeps/{name}.toml" for name in shipped} <= names


def test_a_sweep_resumes_a_trainer_run_in_iterations(tmp_path):
    """A sweep's partial run is resumed up to the sweep's length in the learner's own unit:
    with --generations for every run, a MAPPO run of a sweep could not be resumed."""
    from physrover.experiment.execute import run_one
    from physrover.experiment.sweep import RunSpec
    from physrover.experiment.training import train

    config = RunConfig().with_overrides({"method": "mappo", "n_rovers": 3, "n_req": 1,
                                         "steps": 10, "num_envs": 4, "total_episodes": 12,
                                         "eval_episodes": 2})  # fmt: skip
    out = tmp_path / "run"
    train(config, out, iterations=1, progress=False)  # killed after its first iteration
    name, _, error = run_one(RunSpec("run", config.to_toml(), str(out)))
    assert error is None, error
    assert [r["episodes"] for r in read_metrics(out / "metrics.csv")] == [4, 8, 12]
