"""A Ctrl-C or SIGTERM ends the generation, checkpoints it and stops: a resume loses nothing,
for one run and for a sweep's runs, and a second signal interrupts at once."""

import json
import os
import signal
import subprocess
import sys
import threading
import time

import pytest
from conftest import assert_same_run

from physrover.config import RunConfig
from physrover.experiment import stops
from physrover.experiment.execute import run_one
from physrover.experiment.stops import StopRequests
from physrover.experiment.store import read_metrics
from physrover.experiment.sweep import RunSpec
from physrover.experiment.training import train

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
    with pytest.raises(KeyboardInterrupt, match=f"stopped by {sig.name} after generation 3"):
        train(config, stopped, generations=7, progress=False, on_generation=_signal_at(3, sig))
    # The signal came while generation 3 was reported: it was saved, though checkpoint_every
    # (100) would not have saved it.
    assert json.loads((stopped / "state.json").read_text())["generation"] == 3
    assert len(read_metrics(stopped / "metrics.csv")) == 3
    assert signal.getsignal(sig) in (signal.default_int_handler, signal.SIG_DFL)  # restored
    train(None, stopped, resume=True, progress=False)
    assert_same_run(full, stopped)


def test_a_signal_in_the_last_generation_lets_the_run_finish(tmp_path):
    config = RunConfig().with_overrides(EASY)
    out = train(config, tmp_path / "run", generations=3, progress=False,
                on_generation=_signal_at(3, signal.SIGTERM))  # fmt: skip
    assert json.loads((out / "state.json").read_text())["generation"] == 3


def test_a_repeated_sigterm_is_one_request_a_second_sigint_interrupts(tmp_path):
    config = RunConfig().with_overrides(EASY)
    with pytest.raises(KeyboardInterrupt, match="stopped by SIGTERM after generation 2"):
        train(config, tmp_path / "a", generations=7, progress=False,
              on_generation=_signal_at(2, signal.SIGTERM, signal.SIGTERM))  # fmt: skip
    assert json.loads((tmp_path / "a" / "state.json").read_text())["generation"] == 2


def test_a_second_signal_interrupts_at_once(tmp_path):
    config = RunConfig().with_overrides(EASY)
    out = tmp_path / "run"
    twice = _signal_at(3, signal.SIGINT, signal.SIGINT)
    with pytest.raises(KeyboardInterrupt) as caught:
        train(config, out, generations=7, progress=False, on_generation=twice)
    assert "stopped by" not in str(caught.value)  # not at a generation's end
    assert not (out / "state.json").exists()  # nothing checkpointed yet (every 100)


SWEEP = (
    '[sweep]\nname = "long"\nseeds = SEEDS\n\n[base.domain]\nn_rovers = 3\nn_req = 1\n'
    'steps = 10\n\n[base.learn]\nmethod = "D"\ngenerations = 1000000\npopulation = 4\n'
    "eval_episodes = 1\ncheckpoint_every = 1000000\n"
)


def _sweep(tmp_path, text):
    """``physrover sweep`` of ``text`` in its own process group, 2 workers; (process, root)."""
    sweep = tmp_path / "long.toml"
    sweep.write_text(text)
    root = tmp_path / "root"
    code = "import sys; from physrover.cli import main; sys.exit(main(sys.argv[1:]))"
    argv = [sys.executable, "-c", code, "sweep", str(sweep), "--workers", "2", "--root", str(root)]
    process = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               start_new_session=True)  # fmt: skip
    return process, root / "long"


def _wait_for(process, condition):
    deadline = time.monotonic() + 120
    while not condition():
        assert time.monotonic() < deadline and process.poll() is None, "no training"
        time.sleep(0.2)


def _stopped(process, send):
    """Send the signal (``send(pid)``), then the sweep's stderr once it has exited."""
    try:
        send(process.pid)
        _out, err = process.communicate(timeout=60)
        return err
    finally:  # never leave a sweep of a million generations behind
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)


def _checkpointed_where_it_stopped(run):
    saved = json.loads((run / "state.json").read_text())["generation"]
    assert saved == _rows(run) >= 2  # far from checkpoint_every (10^6)


def test_sigterm_to_a_sweep_stops_its_runs_at_a_checkpoint_and_starts_no_other(tmp_path):
    process, root = _sweep(tmp_path, SWEEP.replace("SEEDS", "3"))
    runs = [root / f"seed={seed}" for seed in range(3)]
    _wait_for(process, lambda: all(_rows(run) >= 2 for run in runs[:2]))  # both training
    err = _stopped(process, lambda pid: os.kill(pid, signal.SIGTERM))  # as `kill PID` does
    assert process.returncode == 130 and "sweep interrupted" in err, err
    for run in runs[:2]:
        _checkpointed_where_it_stopped(run)
    assert not (runs[2] / "metrics.csv").exists()  # the third never started


@pytest.mark.parametrize("to", ["group", "parent"])
def test_ctrl_c_to_a_sweep_with_an_idle_worker(to, tmp_path):
    """A terminal's Ctrl-C reaches every process of the group, an idle worker's too (the
    pool must not break, which would kill the running run without a checkpoint); ``kill
    -INT PID`` or an IDE's stop button reaches the sweep's process only (its runs must stop
    all the same, not run on to their end)."""
    text = SWEEP.replace("SEEDS", "1") + "\n[grid]\ngenerations = [3, 1000000]\n"
    process, root = _sweep(tmp_path, text)
    short, long = root / "generations=3_seed=0", root / "generations=1000000_seed=0"
    _wait_for(process, lambda: _rows(long) >= 2 and (short / "state.json").exists())
    time.sleep(1.0)  # the short run's worker is idle now
    send = os.killpg if to == "group" else os.kill
    err = _stopped(process, lambda pid: send(pid, signal.SIGINT))
    assert process.returncode == 130 and "sweep interrupted" in err, err
    _checkpointed_where_it_stopped(long)
    assert json.loads((short / "state.json").read_text())["generation"] == 3


def _rows(run) -> int:
    try:
        return len((run / "metrics.csv").read_text().splitlines()) - 1
    except FileNotFoundError:
        return 0


def test_an_interrupt_at_once_waits_for_the_writing_in_hand():
    reached = []
    with StopRequests() as stop:
        signal.raise_signal(signal.SIGINT)  # the first: a request
        assert stop.requested == "SIGINT"
        with pytest.raises(KeyboardInterrupt):
            with stop.held():
                signal.raise_signal(signal.SIGINT)  # the second: once the writing is done
                reached.append("the rest of the checkpoint")
    assert reached == ["the rest of the checkpoint"]
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # restored


def test_a_sweep_worker_stops_on_the_event_and_now_on_sigusr1(monkeypatch, tmp_path):
    event = threading.Event()
    monkeypatch.setattr(stops, "_stop_event", event)
    with StopRequests() as stop:
        assert stop.requested is None
        event.set()
        assert stop.requested == "the sweep's stop"
        with pytest.raises(KeyboardInterrupt), stop.held():
            signal.raise_signal(signal.SIGUSR1)
    spec = RunSpec("late", RunConfig().with_overrides(EASY).to_toml(), str(tmp_path / "late"))
    with pytest.raises(KeyboardInterrupt, match="not started"):
        run_one(spec)  # a run the pool had queued when the sweep stopped
    assert not (tmp_path / "late").exists()


def test_a_metrics_line_cut_by_a_kill_is_not_a_row(tmp_path):
    path = tmp_path / "metrics.csv"
    path.write_text("generation,eval_G\r\n1,0.5\r\n2,0.7\r\n3,0.")
    assert read_metrics(path) == [{"generation": 1.0, "eval_G": 0.5},
                                  {"generation": 2.0, "eval_G": 0.7}]  # fmt: skip
