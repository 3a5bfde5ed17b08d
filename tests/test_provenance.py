"""provenance.json: every start and resume of a run records the code and machine."""

import json
import shutil
import warnings
from pathlib import Path

import numpy as np
import pytest

import physrover
from physrover.config import RunConfig
from physrover.core.compiled import source_digest
from physrover.experiment import provenance
from physrover.experiment.provenance import PACKAGE_DIR, code_fingerprint, read_provenance
from physrover.experiment.store import record_provenance
from physrover.experiment.training import train

EASY = dict(n_rovers=3, n_req=1, population=20, steps=50, method="D", checkpoint_every=3)


def test_fingerprint_is_the_sources_not_the_place(tmp_path):
    assert PACKAGE_DIR == Path(physrover.__file__).resolve().parent  # every wing, not one
    copy = tmp_path / "copy" / "physrover"
    shutil.copytree(PACKAGE_DIR, copy, ignore=shutil.ignore_patterns("__pycache__"))
    assert source_digest(copy) == code_fingerprint()
    kernel_cache = copy / "core" / "compiled.py"
    kernel_cache.write_text(kernel_cache.read_text() + "\n# edited\n")
    assert source_digest(copy) != code_fingerprint()
    kernel_cache.write_text((PACKAGE_DIR / "core" / "compiled.py").read_text())
    assert source_digest(copy) == code_fingerprint()
    (copy / ".#lock.py").symlink_to(copy / "gone")  # an editor's dangling lock: skipped
    (copy / "notes.txt").write_text("not a source")
    assert source_digest(copy) == code_fingerprint()
    kernel_cache.rename(copy / "core" / "compiled2.py")  # same bytes, other file: other code
    assert source_digest(copy) != code_fingerprint()
    assert source_digest(tmp_path / "copy" / "empty") == ""  # no sources: no fingerprint


def test_a_run_records_a_segment_per_start_and_resume(tmp_path):
    config = RunConfig().with_overrides(EASY)
    out = train(config, tmp_path / "run", generations=5, progress=False)
    (first,) = read_provenance(out)
    assert first["from_generation"] == 0
    assert first["physrover"] == physrover.__version__
    assert first["code"] == code_fingerprint() and len(first["code"]) == 64
    assert first["numpy"] == np.__version__ and first["cpu"] and first["llvm_cpu"]
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the same code: no warning
        train(None, out, resume=True, generations=8, progress=False)
    segments = read_provenance(out)
    assert [s["from_generation"] for s in segments] == [0, 5]  # generation 5: the end's checkpoint
    assert segments[1]["code"] == first["code"]


def test_resuming_with_other_code_warns_and_is_recorded(tmp_path):
    config = RunConfig().with_overrides(EASY)
    out = train(config, tmp_path / "run", generations=4, progress=False)
    data = json.loads((out / "provenance.json").read_text())
    data["segments"][0].update(code="0" * 64, physrover="0.0.1")  # as if trained by another
    (out / "provenance.json").write_text(json.dumps(data))
    with pytest.warns(RuntimeWarning, match=r"generation 4 with other code .*0\.0\.1, code 0{12}"):
        train(None, out, resume=True, generations=6, progress=False)
    assert [s["code"] for s in read_provenance(out)] == ["0" * 64, code_fingerprint()]


def test_resuming_on_another_cpu_warns(tmp_path):
    config = RunConfig().with_overrides(EASY)
    out = train(config, tmp_path / "run", generations=4, progress=False)
    data = json.loads((out / "provenance.json").read_text())
    data["segments"][0].update(llvm_cpu="a-cpu-of-the-future")
    (out / "provenance.json").write_text(json.dumps(data))
    with pytest.warns(RuntimeWarning, match="compiled for another CPU .*a-cpu-of-the-future"):
        train(None, out, resume=True, generations=5, progress=False)


def test_a_finished_run_resumed_records_nothing(tmp_path):
    out = train(RunConfig().with_overrides(EASY), tmp_path / "run", generations=3,
                progress=False)  # fmt: skip
    train(None, out, resume=True, progress=False)  # already at its 3 generations
    assert [s["from_generation"] for s in read_provenance(out)] == [0]


def test_segments_a_resume_goes_back_past_are_dropped(tmp_path, monkeypatch):
    """Segments from 0, 5 and 8; a resume from generation 5 (the run's state put back to
    its checkpoint at 5, say) keeps the one from 0 and replaces the others with its own.
    Two segments from one generation: the first left nothing past it (a run that crashed
    before its first checkpoint restarts from generation 0), only the second stays."""
    out = tmp_path / "run"
    out.mkdir()
    for start in (0, 5, 8):
        record_provenance(out, start, 100)
    assert [s["from_generation"] for s in read_provenance(out)] == [0, 5, 8]
    record_provenance(out, 5, 100)
    assert [s["from_generation"] for s in read_provenance(out)] == [0, 5]
    monkeypatch.setattr(provenance, "code_fingerprint", lambda: "f" * 64)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no warning: the replaced segment trained nothing
        record_provenance(out, 0, 100)
    assert [s["code"] for s in read_provenance(out)] == ["f" * 64]
    monkeypatch.setattr(provenance, "code_fingerprint", lambda: None)  # sources unknown
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # unknown code is not compared
        record_provenance(out, 3, 100)
    assert read_provenance(tmp_path) == []  # not a run: no segments
