"""Run directories and TOML files of the previous layout still load and resume exactly.

``tests/data/run-0.1.0`` was written by physrover 0.1.0 (commit 04b2d4a, before the config
was split into [domain], [physics], [scenario] and [sensor] tables): its [domain] table holds
the physical model's and the ring scenario's fields. It ran 2 generations of max-critic
under physical motion.
"""

import csv
import shutil
from pathlib import Path

import numpy as np

from physrover.config import PhysicsConfig, RunConfig
from physrover.runs import load_champions, load_run_config, train

OLD_RUN = Path(__file__).parent / "data" / "run-0.1.0"


def _rows(run: Path) -> list[dict]:
    with open(run / "metrics.csv") as f:
        return [{k: v for k, v in row.items() if k != "wall_seconds"} for row in csv.DictReader(f)]


def test_old_layout_fields_move_to_their_tables():
    config = load_run_config(OLD_RUN)
    d = config.domain
    assert (d.n_rovers, d.n_req, d.steps, d.motion) == (4, 2, 6, "physics")
    assert d.physics == PhysicsConfig(collisions=False, substeps=2)
    assert (d.scenario.kind, d.scenario.poi_ring_radius, d.scenario.spawn_radius) == (
        "ring",
        4.0,
        2.0,
    )
    # Written back in the new layout, it reads back the same.
    text = config.to_toml()
    assert "[physics]\ncollisions = false" in text and '[scenario]\nkind = "ring"' in text
    assert RunConfig.from_toml(text) == config


def test_old_run_resumes_as_a_fresh_run_of_the_new_release(tmp_path):
    old = tmp_path / "old"
    shutil.copytree(OLD_RUN, old)
    train(None, old, resume=True, generations=3, progress=False)
    fresh = train(load_run_config(OLD_RUN).with_overrides({"generations": 3}), tmp_path / "new",
                  progress=False)  # fmt: skip
    assert len(_rows(old)) == 3 and _rows(old) == _rows(fresh)
    # The generations the old release ran are the new release's too.
    assert _rows(old)[:2] == _rows(OLD_RUN)
    np.testing.assert_array_equal(load_champions(old)[1], load_champions(fresh)[1])


def test_the_sensor_once_named_quadrants_still_loads():
    text = RunConfig().to_toml().replace('kind = "density"', 'kind = "quadrants"')
    assert 'kind = "quadrants"' in text
    config = RunConfig.from_toml(text)
    assert config == RunConfig() and config.domain.sensor.kind == "density"
