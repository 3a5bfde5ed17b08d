"""Run directories and TOML files of the previous layout still load and resume exactly.

``tests/data/run-0.1.0`` was written by physrover 0.1.0 (commit 04b2d4a, before the config
was split into [domain], [physics], [scenario] and [sensor] tables): its [domain] table holds
the physical model's and the ring scenario's fields. It ran 2 generations of max-critic
under physical motion.

Since 0.2.0 the policies' output tanh is our own correctly rounded one
(:func:`physrover.learn.forward.tanh32`) instead of numpy's, which differed from it in the
last bit for a quarter of its arguments: a run of the new release plays the old release's
runs to float32 rounding, not bit for bit (the old layout's run still resumes, and its
resumed generations are the new release's own).
"""

import csv
import shutil
from pathlib import Path

import numpy as np

from physrover.config import PhysicsConfig, RunConfig
from physrover.experiment.store import load_champions, load_run_config
from physrover.experiment.training import train

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


def _same_to_rounding(a: list[dict], b: list[dict]) -> None:
    """Equal generation numbers and G; fitness and critic loss to float32 rounding."""
    assert len(a) == len(b)
    for x, y in zip(a, b, strict=True):
        assert (x["generation"], x["eval_G"], x["train_G_mean"]) == (
            y["generation"], y["eval_G"], y["train_G_mean"])  # fmt: skip
        for key in ("fitness_mean", "critic_loss"):
            np.testing.assert_allclose(float(x[key]), float(y[key]), rtol=1e-6)


def test_old_run_resumes_as_a_fresh_run_of_the_new_release(tmp_path):
    old = tmp_path / "old"
    shutil.copytree(OLD_RUN, old)
    train(None, old, resume=True, generations=3, progress=False)
    fresh = train(load_run_config(OLD_RUN).with_overrides({"generations": 3}), tmp_path / "new",
                  progress=False)  # fmt: skip
    assert len(_rows(old)) == 3
    assert _rows(old)[:2] == _rows(OLD_RUN)  # the old release's generations are kept
    _same_to_rounding(_rows(old), _rows(fresh))  # and the new release plays them alike
    np.testing.assert_allclose(load_champions(old)[1], load_champions(fresh)[1], rtol=1e-5)


def test_the_sensor_once_named_quadrants_still_loads():
    text = RunConfig().to_toml().replace('kind = "density"', 'kind = "quadrants"')
    assert 'kind = "quadrants"' in text
    config = RunConfig.from_toml(text)
    assert config == RunConfig() and config.domain.sensor.kind == "density"
