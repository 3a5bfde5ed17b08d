"""A Ctrl-C or SIGTERM ends the generation, checkpoints it and stops: a resume loses nothing,
for one run and for a sweep's runs, and a second signal interrupts at once."""

import json
import os
import signal
import subprocess
import sys
import time

import pytest
from conftest import assert_same_run

from physrover.config import RunConfig
from physrover.runs import read_metrics, train

EASY = dict(n_rovers=3, n_req=1, population=10, steps=20, method="max-critic",
            checkpoint_every=100, eval_episodes=2)  # fmt: skip


def _signal_at(generation, *signals):
    def on_generation(stats):
        if stats.generation == generation:
            for sig in signals:
                signal.raise_signal(sig)

    return on_generation


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_checkpoints_the_generation_and_a_resume_goes_on(sig, tmp_path):
    config = RunConfig().with_overrides(EASY)
    full = train(config, tmp_path / "full", generations=7, progress=False)
    stopped = tmp_path / "stopped"
    with pytest.raises(KeyboardInterrupt, match=f"stopped by {sig.name} after generation 4"):
        train(config, stopped, generations=7, progress=False, on_generation=_signal_at(3, sig))
    # The signal came after generation 3's row; generation 4 ran to its end and was saved,
    # though checkpoint_every (100) would not have saved it.
    assert json.loads((stopped / "state.json").read_text())["generation"] == 4
    assert len(read_metrics(stopped / "metrics.csv")) == 4
    assert signal.getsignal(sig) in (signal.default_int_handler, signal.SIG_DFL)  # restored
    train(None, stopped, resume=True, progress=False)
    assert_same_run(full, stopped)


def test_a_second_signal_interrupts_at_once(tmp_path):
    config = RunConfig().with_overrides(EASY)
    out = tmp_path / "run"
    twice = _signal_at(3, signal.SIGINT, signal.SIGINT)
    with pytest.raises(KeyboardInterrupt) as caught:
        train(config, out, generations=7, progress=False, on_generation=twice)
    assert "stopped by" not in str(caught.value)  # not at a generation's end
    assert not (out / "state.json").exists()  # nothing checkpointed yet (every 100)


def test_sigterm_to_a_sweep_stops_its_runs_at_a_checkpoint_and_starts_no_other(tmp_path):
    sweep = tmp_path / "long.toml"
    sweep.write_text(
        '[sweep]\nname = "long"\nseeds = 3\n\n[base.domain]\nn_rovers = 3\nn_req = 1\n'
        'steps = 10\n\n[base.learn]\nmethod = "D"\ngenerations = 1000000\npopulation = 4\n'
        "eval_episodes = 1\ncheckpoint_every = 1000000\n"
    )
    root = tmp_path / "root"
    code = "import sys; from physrover.cli import main; sys.exit(main(sys.argv[1:]))"
    argv = [sys.executable, "-c", code, "sweep", str(sweep), "--workers", "2", "--root", str(root)]
    sweep_process = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                     text=True, start_new_session=True)  # fmt: skip
    try:
        runs = [root / "long" / f"seed={seed}" for seed in range(3)]
        deadline = time.monotonic() + 120
        while not all(_rows(run) >= 2 for run in runs[:2]):  # both workers are training
            assert time.monotonic() < deadline and sweep_process.poll() is None, "no training"
            time.sleep(0.2)
        os.kill(sweep_process.pid, signal.SIGTERM)  # the parent only, as `kill PID` does
        _out, err = sweep_process.communicate(timeout=60)
    finally:  # never leave a sweep of a million generations behind
        if sweep_process.poll() is None:
            os.killpg(sweep_process.pid, signal.SIGKILL)
    assert sweep_process.returncode == 130, err
    assert "sweep interrupted" in err
    for run in runs[:2]:  # each checkpointed where it stopped, far from checkpoint_every
        saved = json.loads((run / "state.json").read_text())["generation"]
        assert saved == _rows(run) >= 2
    assert not (runs[2] / "metrics.csv").exists()  # the third never started


def _rows(run) -> int:
    try:
        return len((run / "metrics.csv").read_text().splitlines()) - 1
    except FileNotFoundError:
        return 0
