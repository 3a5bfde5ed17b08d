"""A run survives anything: a kill or a full disk at any step of a checkpoint, a storm of
SIGKILLs at random instants, a truncated or corrupted state.npz. After each, the resumed
run ends bit-identical to an uninterrupted one (conftest.assert_same_run).

The crashes happen in a process of their own (tests/crashes.py), which forks a child per
crash: the children die for real (SIGKILL) or exit on the error, as a user's run would.
"""

import json
import subprocess
import sys
from pathlib import Path

import crashes
import numpy as np
import pytest
from conftest import assert_same_run

from physrover.cli.main import main
from physrover.experiment.store import RunError, last_checkpoint, load_state, read_metrics
from physrover.experiment.training import train
from physrover.learn.ccea import CCEA

HERE = Path(__file__).parent
pytestmark = pytest.mark.skipif(not hasattr(__import__("os"), "fork"), reason="needs fork")


def _crashes(*args) -> dict:
    done = subprocess.run([sys.executable, str(HERE / "crashes.py"), *map(str, args)],
                          capture_output=True, text=True, timeout=300)  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    return json.loads(done.stdout.strip().splitlines()[-1])


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    out = tmp_path_factory.mktemp("reference") / "run"
    return train(crashes.config(), out, progress=False)


# The I/O calls of a checkpoint, in order: the champion snapshot, state.npz (with the
# rename of the previous one to state.prev.npz when there is one), state.json. Each is
# written to a temporary file, fsynced, renamed into place, and the directory fsynced.
FIRST = ["write", "fsync", "replace", "fsync"] * 3  # nothing to keep yet
LATER = FIRST[:6] + ["replace"] + FIRST[6:]


@pytest.mark.parametrize(
    "learner, generation, steps",
    [("ccea", 2, FIRST), ("ccea", 4, LATER), ("mappo", 4, LATER), ("maddpg", 4, LATER)],
    ids=["first", "later", "mappo", "maddpg"],
)
@pytest.mark.long
def test_a_fault_at_any_step_of_a_checkpoint_resumes_bit_identically(
    learner, generation, steps, tmp_path
):
    report = _crashes("faults", tmp_path, generation, learner)
    assert report["steps"] == steps  # the test covers every step the checkpoint takes
    scenarios = report["scenarios"]
    modes = [s["mode"] for s in scenarios]
    assert modes.count("kill") == len(steps) + 1  # before each call, and after the last
    assert modes.count("torn") == 3 and modes.count("enospc") == len(steps)
    previous = generation - 2 if generation > 2 else None
    for s in scenarios:
        out = tmp_path / s["dir"]
        if s["mode"] == "enospc":  # a clear error, the previous checkpoint intact
            assert s["status"] == "exit 2", s
            assert "No space left on device" in s["error"] and "\n" not in s["error"], s
            assert str(out) in s["error"], s  # names the file
            assert s["temporaries"] == 0, s  # no temporary file left behind
            # state.npz is in place once its directory's fsync is reached: the call before
            # state.json's four
            assert s["saved"] == (generation if s["step"] >= len(steps) - 4 else previous), s
        else:
            assert s["status"] == "SIGKILL", s
            assert s["saved"] in (previous, generation), s
        assert s["resumed"] == "exit 0", s
        assert not list(out.rglob(".*.tmp")), s  # the resume removed what a kill left
        assert_same_run(tmp_path / "reference", out, exact_snapshots=True)


@pytest.mark.long
def test_a_run_killed_30_times_at_random_instants_ends_bit_identical(tmp_path):
    generations = 200
    report = _crashes("kill-loop", tmp_path, 30, 11, generations)
    assert report["kills"] == 30 and report["final"] == "exit 0", report
    landed = [g for g in report["checkpoints_at_kill"] if g is not None]
    assert len(set(landed)) >= 10, report  # the kills fell all over the run
    assert_same_run(tmp_path / "reference", tmp_path / "run", exact_snapshots=True)
    assert len(read_metrics(tmp_path / "run" / "metrics.csv")) == generations


def _run(tmp_path, generations, name="run"):
    return train(crashes.config(), tmp_path / name, generations=generations, progress=False)


def test_a_truncated_checkpoint_resumes_from_the_previous_one_with_a_warning(tmp_path, reference):
    out = _run(tmp_path, 4)  # checkpoints at 2 and 4: state.prev.npz holds 2
    data = (out / "state.npz").read_bytes()
    (out / "state.npz").write_bytes(data[: len(data) // 2])
    with pytest.warns(RuntimeWarning, match=r"state.npz cannot be read .*resuming from "
                      r"state.prev.npz \(generation 2\)"):  # fmt: skip
        train(None, out, resume=True, generations=crashes.GENERATIONS, progress=False)
    assert (out / "state.npz.bad").read_bytes() == data[: len(data) // 2]  # kept aside
    assert_same_run(reference, out, exact_snapshots=True)


def test_a_corrupted_checkpoint_without_a_previous_one_is_a_one_line_error(tmp_path, capsys):
    out = _run(tmp_path, 2)  # one checkpoint only
    data = bytearray((out / "state.npz").read_bytes())
    middle = len(data) // 2
    data[middle : middle + 8] = bytes(b ^ 0xFF for b in data[middle : middle + 8])  # CRC tells
    (out / "state.npz").write_bytes(bytes(data))
    with pytest.raises(RunError, match="state.npz cannot be read .*no earlier checkpoint"):
        load_state(out, CCEA(crashes.config()))
    assert main(["train", "--resume", str(out), "--generations", "4", "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("physrover: error: ") and "state.npz" in err[0]


def test_the_cli_shows_the_fallback_as_one_warning_line(tmp_path, capsys, reference):
    out = _run(tmp_path, 4)
    (out / "state.npz").write_bytes(b"not a zip")
    assert main(["train", "--resume", str(out), "--generations", "6", "--quiet"]) == 0
    err = [line for line in capsys.readouterr().err.splitlines() if "state.prev.npz" in line]
    assert len(err) == 1 and err[0].startswith("physrover: warning: /"), err
    assert err[0].endswith("resuming from state.prev.npz (generation 2)"), err
    assert_same_run(reference, out, exact_snapshots=True)


def test_a_kill_between_the_two_renames_resumes_quietly_from_the_previous_one(
    tmp_path, reference, recwarn
):
    out = _run(tmp_path, 4)
    # At generation 4, state.npz (2) was renamed to state.prev.npz; the kill came before the
    # new state.npz (4) was renamed into place.
    (out / "state.npz").unlink()
    train(None, out, resume=True, generations=crashes.GENERATIONS, progress=False)
    assert not [w for w in recwarn if issubclass(w.category, RuntimeWarning)]
    assert_same_run(reference, out, exact_snapshots=True)


def test_a_checkpoint_of_physrover_0_4_still_resumes(tmp_path, reference):
    """0.4 wrote the metadata to state.json only; its state.npz had no __meta__."""
    out = _run(tmp_path, 4)
    with np.load(out / "state.npz") as data:
        arrays = {k: data[k] for k in data.files if k != "__meta__"}
    np.savez(out / "state.npz", **arrays)
    (out / "state.prev.npz").unlink()
    train(None, out, resume=True, generations=crashes.GENERATIONS, progress=False)
    assert_same_run(reference, out, exact_snapshots=True)
    assert last_checkpoint(out) == crashes.GENERATIONS
