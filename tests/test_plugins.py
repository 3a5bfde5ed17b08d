"""A researcher's own parts reach the command line: ``physrover --import``, a sweep's
``[sweep] imports`` and ``PHYSROVER_IMPORT`` (physrover.core.plugins)."""

import json
import multiprocessing
import os
import re
import subprocess
import sys
from concurrent.futures import ProcessPoolExecutor

import pytest

from physrover.cli.main import main
from physrover.config import ConfigError, RunConfig
from physrover.core import plugins
from physrover.core.registry import CREDITS, SCENARIOS
from physrover.experiment.execute import run_one
from physrover.experiment.sweep import RunSpec, Sweep
from physrover.experiment.training import train

# A scenario (the ring's rovers, POIs on a line) and a credit (G for every rover), in a file
# of their own; NAME makes the registered names unique to each test that writes one.
PARTS = """
import dataclasses
from typing import ClassVar

import numpy as np

from physrover.domain.scoring.credit import Credit, register_credit
from physrover.domain.scenarios import Scenario, StartState, register_scenario, spawn_in_disc


@register_scenario
@dataclasses.dataclass(frozen=True)
class Line(Scenario):
    kind: ClassVar[str] = "NAME-line"
    spacing: float = 3.0

    def draw(self, rngs, n_rovers, poi_values):
        positions, headings = spawn_in_disc(rngs, n_rovers, 1.5)
        pois = np.zeros((len(rngs), len(poi_values), 2))
        pois[..., 0] = self.spacing * (1 + np.arange(len(poi_values)))
        values = np.broadcast_to(poi_values, pois.shape[:2]).copy()
        return StartState(positions, headings, pois, values)

    def extent(self):
        return self.spacing * 8


class TeamG(Credit):
    def __call__(self, world):
        return np.repeat(world.G[:, None], world.n_rovers, axis=1)


register_credit("NAME-G", TeamG())
"""

TINY = ["--set", "n_rovers=3", "--set", "n_req=1", "--set", "population=4", "--set",
        "eval_episodes=2", "--set", "steps=10", "--generations", "2", "--quiet"]  # fmt: skip


@pytest.fixture(autouse=True)
def _own_environment(monkeypatch):
    """Each test starts with nothing loaded (so nothing exported) and leaves behind neither
    PHYSROVER_IMPORT nor a changed sys.path for the tests that follow."""
    monkeypatch.setenv(plugins.ENV, "")  # (delenv of an unset name would restore nothing)
    monkeypatch.setattr(plugins, "_loaded", {})
    monkeypatch.setattr(plugins, "_failed", {})
    monkeypatch.setattr(sys, "path", list(sys.path))


def _parts(directory, name):
    path = directory / f"{name.replace('-', '_')}.py"
    path.write_text(PARTS.replace("NAME", name))
    return path


def _physrover(*argv, cwd, env=None):
    """``physrover ARGV`` in a fresh process (what a new shell or a spawned worker sees)."""
    code = "import sys; from physrover.cli import main; sys.exit(main(sys.argv[1:]))"
    return subprocess.run([sys.executable, "-c", code, *argv], cwd=cwd, capture_output=True,
                          text=True, env={**os.environ, **(env or {})})  # fmt: skip


def test_train_with_a_file_of_ones_own_parts(tmp_path, capsys):
    path = _parts(tmp_path, "plugin-a")
    out = tmp_path / "run"
    argv = ["--import", str(path), "train", *TINY, "--set", "scenario=plugin-a-line",
            "--set", "spacing=2.5", "--set", "feedback=plugin-a-G", "--out", str(out)]  # fmt: skip
    assert main(argv) == 0
    config = RunConfig.load(out / "config.toml")
    assert config.domain.scenario.kind == "plugin-a-line" and config.domain.scenario.spacing == 2.5
    assert config.learn.feedback == "plugin-a-G"
    (segment,) = json.loads((out / "provenance.json").read_text())["segments"]
    recorded = segment["imports"][str(path.resolve())]  # which file, and its digest
    assert recorded == {"file": str(path.resolve()), "sha256": recorded["sha256"]}
    assert len(recorded["sha256"]) == 16
    # Loaded once per process: a second command with the same file registers nothing twice.
    assert main(["--import", str(path), "info", "--set", "scenario=plugin-a-line"]) == 0
    assert 'kind = "plugin-a-line"' in capsys.readouterr().out
    assert os.environ[plugins.ENV] == str(path.resolve())  # for child processes
    # A new process without the file: the run's error says what it was made with.
    result = _physrover(
        "evaluate", str(out), "--episodes", "1", cwd=tmp_path, env={plugins.ENV: ""}
    )
    assert result.returncode == 2
    assert re.search(r"unknown (scenario|credit signal) 'plugin-a-", result.stderr)
    assert f"the run was made with --import {path.resolve()}" in result.stderr
    result = _physrover("--import", "plugin_a.py", "evaluate", str(out), "--episodes", "1",
                        cwd=tmp_path, env={plugins.ENV: ""})  # fmt: skip
    assert result.returncode == 0, result.stderr


def test_a_module_by_name_from_the_current_directory_is_its_file(tmp_path, monkeypatch, capsys):
    path = _parts(tmp_path, "plugin-b")
    monkeypatch.chdir(tmp_path)
    assert main(["--import", "plugin_b", "methods"]) == 0
    assert "plugin-b-line" in capsys.readouterr().out
    assert "plugin-b-line" in SCENARIOS and "plugin-b-G" in CREDITS
    assert os.environ[plugins.ENV] == str(path)  # any child finds it, whatever its directory
    assert plugins.load(["./plugin_b.py", str(path)]) == 2 * plugins.load(["plugin_b"])  # one


def test_a_file_imported_by_name_first_is_not_loaded_again(tmp_path, monkeypatch):
    path = _parts(tmp_path, "plugin-e")
    monkeypatch.syspath_prepend(str(tmp_path))
    import plugin_e  # noqa: F401  (as a script of the researcher's would)

    assert plugins.load([str(path)]) == ["plugin_e"]  # not a second copy that re-registers


def test_a_file_imports_its_siblings(tmp_path):
    (tmp_path / "helpers_f.py").write_text("SPACING = 7.0\n")
    path = tmp_path / "parts_f.py"
    path.write_text("import helpers_f\n" + PARTS.replace("NAME", "plugin-f").replace(
        "spacing: float = 3.0", "spacing: float = helpers_f.SPACING"))  # fmt: skip
    plugins.load([str(path)])
    assert SCENARIOS["plugin-f-line"]().spacing == 7.0


def test_what_cannot_be_imported_is_one_line_naming_it(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["--import", "no_such_parts_module", "methods"]) == 2
    err = capsys.readouterr().err
    assert "cannot import 'no_such_parts_module': no installed module" in err
    assert f"no_such_parts_module.py in {tmp_path}" in err
    assert main(["--import", str(tmp_path / "missing.py"), "methods"]) == 2
    assert "missing.py: no such file" in capsys.readouterr().err
    # The name of a part never imported says where parts come from.
    assert main(["info", "--set", "scenario=plugin-z-line"]) == 2
    assert "physrover --import" in capsys.readouterr().err


def test_a_module_that_fails_half_way_fails_the_same_way_again(tmp_path):
    broken = tmp_path / "broken_parts.py"
    broken.write_text(PARTS.replace("NAME", "plugin-g") + "raise RuntimeError('a bug')\n")
    for _ in range(2):  # not "already registered" the second time: the module's own error
        with pytest.raises(RuntimeError, match="a bug"):
            main(["--import", str(broken), "methods"])


def test_a_sweep_names_its_parts_and_its_workers_import_them(tmp_path):
    parts_dir = tmp_path / "sweeps"
    parts_dir.mkdir()
    _parts(parts_dir, "plugin-c")
    sweep_file = parts_dir / "lines.toml"
    sweep_file.write_text(
        '[sweep]\nname = "lines"\nseeds = 1\nimports = ["plugin_c"]\n\n'
        "[base.domain]\nn_rovers = 3\nn_req = 1\nsteps = 10\n\n"
        '[base.scenario]\nkind = "plugin-c-line"\n\n'
        "[base.learn]\ngenerations = 2\npopulation = 4\neval_episodes = 2\n\n"
        "[grid]\nspacing = [2.0, 4.0]\n"
    )
    # A bare name is looked up beside the sweep file, not only in the current directory.
    assert Sweep.load(sweep_file).imports == ("plugin_c",)
    bad = tmp_path / "bad.toml"
    bad.write_text('[sweep]\nimports = "plugin_c.py"\n')
    with pytest.raises(ConfigError, match="imports: must be a list"):
        Sweep.load(bad)
    root = tmp_path / "root"
    assert main(["sweep", str(sweep_file), "--workers", "2", "--root", str(root)]) == 0
    for spacing in (2.0, 4.0):
        run = root / "lines" / f"spacing={spacing}_seed=0"
        assert RunConfig.load(run / "config.toml").domain.scenario.spacing == spacing
        assert len((run / "metrics.csv").read_text().splitlines()) == 1 + 2


def test_a_spawned_worker_imports_what_the_environment_names(tmp_path):
    """A worker that inherits no registrations (the spawn start method, Python 3.14's
    default forkserver, a Ray worker) trains a run that names the parts (sweep.run_one)."""
    path = _parts(tmp_path, "plugin-d")
    plugins.load([str(path)])  # the parent: exports PHYSROVER_IMPORT
    config = RunConfig().with_overrides(
        {
            "scenario": "plugin-d-line",
            "n_rovers": 3,
            "n_req": 1,
            "steps": 10,
            "generations": 2,
            "population": 4,
            "eval_episodes": 2,
        }  # fmt: skip
    )
    spec = RunSpec("d", config.to_toml(), str(tmp_path / "d"))
    with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")) as pool:
        name, _seconds, error = pool.submit(run_one, spec).result()
    assert error is None and name == "d"
    assert len((tmp_path / "d" / "metrics.csv").read_text().splitlines()) == 1 + 2


def test_resuming_with_a_changed_parts_file_warns(tmp_path):
    path = _parts(tmp_path, "plugin-h")
    plugins.load([str(path)])
    config = RunConfig().with_overrides(
        {
            "scenario": "plugin-h-line",
            "n_rovers": 3,
            "n_req": 1,
            "steps": 10,
            "population": 4,
            "eval_episodes": 2,
            "checkpoint_every": 2,
        }  # fmt: skip
    )
    out = train(config, tmp_path / "run", generations=2, progress=False)
    data = json.loads((out / "provenance.json").read_text())
    data["segments"][0]["imports"][str(path)]["sha256"] = "0" * 16  # as if edited since
    (out / "provenance.json").write_text(json.dumps(data))
    with pytest.warns(RuntimeWarning, match=r"plugin_h\.py changed since generation 0 on"):
        train(None, out, resume=True, generations=4, progress=False)
