"""A researcher's own parts reach the command line: ``physrover --import``, a sweep's
``[sweep] imports`` and ``PHYSROVER_IMPORT`` (physrover.plugins)."""

import json
import os
import subprocess
import sys

import pytest

from physrover import plugins
from physrover.cli import main
from physrover.config import ConfigError, RunConfig
from physrover.registry import CREDITS, SCENARIOS
from physrover.sweep import Sweep

# A scenario (the ring's rovers, POIs on a line) and a credit (G for every rover), in a file
# of their own; NAME makes the registered names unique to each test that writes one.
PARTS = """
import dataclasses
from typing import ClassVar

import numpy as np

from physrover.domain.credit import Credit, register_credit
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
    PHYSROVER_IMPORT nor a changed PYTHONPATH or sys.path for the tests that follow."""
    monkeypatch.setenv(plugins.ENV, "")  # (delenv of an unset name would restore nothing)
    monkeypatch.setenv("PYTHONPATH", os.environ.get("PYTHONPATH", ""))
    monkeypatch.setattr(plugins, "_loaded", {})
    monkeypatch.setattr(sys, "path", list(sys.path))


def _parts(directory, name):
    path = directory / f"{name.replace('-', '_')}.py"
    path.write_text(PARTS.replace("NAME", name))
    return path


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
    assert len(segment["imports"][str(path.resolve())]) == 16  # which file, and its digest
    # Loaded once per process: a second command with the same file registers nothing twice.
    assert main(["--import", str(path), "info", "--set", "scenario=plugin-a-line"]) == 0
    assert 'kind = "plugin-a-line"' in capsys.readouterr().out
    assert str(path.resolve()) in os.environ[plugins.ENV].split(os.pathsep)  # for children


def test_a_module_by_name_from_the_current_directory(tmp_path, monkeypatch, capsys):
    _parts(tmp_path, "plugin-b")
    monkeypatch.chdir(tmp_path)
    assert main(["--import", "plugin_b", "methods"]) == 0
    assert "plugin-b-line" in capsys.readouterr().out
    assert "plugin-b-line" in SCENARIOS and "plugin-b-G" in CREDITS
    assert os.environ[plugins.ENV] == "plugin_b"  # by name, and where a child finds it:
    assert str(tmp_path) in os.environ["PYTHONPATH"].split(os.pathsep)


def test_what_cannot_be_imported_is_one_line_naming_it(tmp_path, capsys):
    assert main(["--import", "no_such_parts_module", "methods"]) == 2
    err = capsys.readouterr().err
    assert "cannot import 'no_such_parts_module': no such module" in err and "./" in err
    assert main(["--import", str(tmp_path / "missing.py"), "methods"]) == 2
    assert "missing.py: no such file" in capsys.readouterr().err
    broken = tmp_path / "broken_parts.py"
    broken.write_text("raise RuntimeError('a bug in the parts')\n")
    with pytest.raises(RuntimeError, match="a bug in the parts"):  # its own traceback
        main(["--import", str(broken), "methods"])
    # The name of a part never imported says where parts come from.
    assert main(["info", "--set", "scenario=plugin-z-line"]) == 2
    assert "physrover --import" in capsys.readouterr().err


def test_a_sweep_names_its_parts_and_its_workers_import_them(tmp_path):
    parts_dir = tmp_path / "sweeps"
    parts_dir.mkdir()
    _parts(parts_dir, "plugin-c")
    sweep_file = parts_dir / "lines.toml"
    sweep_file.write_text(
        '[sweep]\nname = "lines"\nseeds = 1\nimports = ["plugin_c.py"]\n\n'
        "[base.domain]\nn_rovers = 3\nn_req = 1\nsteps = 10\n\n"
        '[base.scenario]\nkind = "plugin-c-line"\n\n'
        "[base.learn]\ngenerations = 2\npopulation = 4\neval_episodes = 2\n\n"
        "[grid]\nspacing = [2.0, 4.0]\n"
    )
    assert Sweep.load(sweep_file).imports == ("plugin_c.py",)  # relative to the sweep file
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


def test_a_fresh_process_imports_what_the_environment_names(tmp_path):
    """What a spawned pool worker or a Ray worker does first (sweep.run_one)."""
    path = _parts(tmp_path, "plugin-d")
    code = ("from physrover import plugins, registry; plugins.load_from_environment(); "
            "print('plugin-d-line' in registry.SCENARIOS)")  # fmt: skip
    env = {**os.environ, plugins.ENV: os.pathsep.join(["", str(path)])}
    result = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                            text=True, check=True)  # fmt: skip
    assert result.stdout.strip() == "True"
