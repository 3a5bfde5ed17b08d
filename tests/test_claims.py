"""Claims on run directories (issue 45): one process trains a run at a time, with real
processes and real files: a held run refuses a second trainer in one line naming the
holder; a holder killed with SIGKILL releases it at once; several sweep drivers on one root
train each run once and agree bit for bit with one driver."""

import json
import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from conftest import assert_same_run, comparable_rows

from physrover.cli.main import main
from physrover.config import RunConfig
from physrover.experiment.claims import CLAIM, RunHeld, check_free, claim, holder
from physrover.experiment.execute import run_sweep
from physrover.experiment.store import read_metrics
from physrover.experiment.sweep import Sweep
from physrover.experiment.training import train

ROOT = Path(__file__).parent.parent
TINY = {"n_rovers": 3, "n_req": 1, "population": 6, "steps": 20, "eval_episodes": 2,
        "method": "D", "checkpoint_every": 5}  # fmt: skip

HOLD = """
import sys, time
from pathlib import Path
from physrover.experiment.claims import claim
with claim(Path(sys.argv[1])):
    print("held", flush=True)
    time.sleep(600)
"""


def _holding(run_dir: Path) -> subprocess.Popen:
    """A process that claims ``run_dir`` and sleeps, once it says so."""
    process = subprocess.Popen([sys.executable, "-c", HOLD, str(run_dir)], stdout=subprocess.PIPE,
                               text=True, env={**os.environ, "PYTHONPATH": str(ROOT)})  # fmt: skip
    assert process.stdout.readline().strip() == "held"
    return process


def test_a_held_run_refuses_a_second_trainer_naming_the_holder(tmp_path, capsys):
    out = train(RunConfig().with_overrides(TINY), tmp_path / "run", generations=5,
                progress=False)  # fmt: skip
    process = _holding(out)
    try:
        who = holder(out)
        assert who["pid"] == process.pid and who["host"]
        with pytest.raises(RunHeld, match=rf"held by pid {process.pid} on "):
            train(None, out, resume=True, generations=10, progress=False)
        assert main(["train", "--resume", str(out), "--generations", "10", "--quiet"]) != 0
        err = capsys.readouterr().err.strip()
        assert err.startswith(f"physrover: error: {out} is held by pid {process.pid}")
        assert "\n" not in err and "resuming" not in err
        assert RunConfig.load(out / "config.toml").length == 5  # nothing written
    finally:
        process.kill()
        process.wait()
    # SIGKILL released it at once: the resume goes on, as one uninterrupted run
    assert holder(out) is None
    train(None, out, resume=True, generations=10, progress=False)
    whole = train(RunConfig().with_overrides(TINY), tmp_path / "whole", generations=10,
                  progress=False)  # fmt: skip
    assert_same_run(whole, out)


def test_a_claim_is_reentrant_in_its_process_and_its_file_stays(tmp_path):
    run = tmp_path / "run"
    assert holder(run) is None
    with claim(run):
        with claim(run):  # a sweep's worker, then train, claim the same run
            assert holder(run)["pid"] == os.getpid()
            check_free(run)  # its own claim is not another's
        assert holder(run)["pid"] == os.getpid()
    assert holder(run) is None
    assert (run / CLAIM).exists() and (run / CLAIM).read_text() == ""


SWEEP = """
[sweep]
name = "shared"
seeds = 3

[base.domain]
n_rovers = 3
steps = 20

[base.learn]
population = 6
eval_episodes = 2
generations = 40
checkpoint_every = 5

[grid]
method = ["D", "max-critic"]
n_req = [1, 2]
"""


CLI = "import sys; from physrover.cli.main import main; sys.exit(main(sys.argv[1:]))"


def _driver(path: Path, root: Path) -> subprocess.Popen:
    """A sweep driver in a process group of its own, with its pool worker: killing the group
    is a driver's machine dying (killing the driver alone would orphan its worker)."""
    command = [sys.executable, "-c", CLI, "sweep", str(path), "--root", str(root), "--workers", "1"]
    return subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "PYTHONPATH": str(ROOT)},
                            start_new_session=True)  # fmt: skip


def _kill_group(driver: subprocess.Popen) -> None:
    """SIGKILL ``driver``'s whole process group (its pool worker too), if it still runs."""
    try:
        os.killpg(driver.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass


def _segments(run: Path) -> int:
    return len(json.loads((run / "provenance.json").read_text())["segments"])


@pytest.mark.parametrize("kills", [0, 2])
def test_drivers_share_a_sweep_each_run_trained_once(tmp_path, kills):
    path = tmp_path / "shared.toml"
    path.write_text(SWEEP)
    reference = Sweep.load(path).runs(tmp_path / "one")
    run_sweep(reference, workers=1, progress=False)

    rng = random.Random(kills)
    root = tmp_path / "many"
    drivers = []
    for _ in range(3):  # three drivers at random offsets
        drivers.append(_driver(path, root))
        time.sleep(rng.uniform(0.2, 1.5))
    try:
        for _ in range(kills):  # a driver killed mid-sweep, and one started in its place
            time.sleep(rng.uniform(1.0, 3.0))
            victim = drivers.pop(rng.randrange(len(drivers)))
            _kill_group(victim)
            victim.wait()
            drivers.append(_driver(path, root))
        for driver in drivers:
            assert driver.wait(timeout=600) == 0, driver.stderr.read()
    finally:  # nothing outlives the test (a killed driver's orphaned worker did: issue 45)
        for driver in drivers:
            _kill_group(driver)
    runs = Sweep.load(path).runs(root)
    for spec, ref in zip(runs, reference, strict=True):
        assert comparable_rows(read_metrics(Path(spec.out) / "metrics.csv")) == comparable_rows(
            read_metrics(Path(ref.out) / "metrics.csv")), spec.name  # fmt: skip
        if not kills:  # nobody died: one process trained each run, start to end
            assert _segments(Path(spec.out)) == 1, spec.name


def test_a_locked_claim_not_yet_named_is_held_not_free(tmp_path):
    import fcntl

    run = tmp_path / "run"
    run.mkdir()
    fd = os.open(run / CLAIM, os.O_RDWR | os.O_CREAT)  # locked, its holder not written yet
    fcntl.flock(fd, fcntl.LOCK_EX)
    try:
        assert holder(run) == {"host": "?", "pid": "?", "since": None}
        with pytest.raises(RunHeld, match="held by another process"):
            with claim(run):
                pass
    finally:
        os.close(fd)
    assert holder(run) is None


def test_a_new_run_on_a_file_or_a_full_folder_is_one_line_and_claims_nothing(tmp_path, capsys):
    (tmp_path / "file").write_text("not a run")
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "notes.txt").write_text("mine")
    for out in ("file", "full"):
        assert main(["train", "--set", "n_rovers=3", "--out", str(tmp_path / out)]) != 0
        err = capsys.readouterr().err.strip()
        assert err == f"physrover: error: {tmp_path / out} exists and is not empty; use " \
            f"--resume {tmp_path / out} to continue it"  # fmt: skip
    assert not (tmp_path / "full" / CLAIM).exists()
