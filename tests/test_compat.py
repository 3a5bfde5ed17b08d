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
import warnings
from pathlib import Path

import numpy as np
import pytest

from physrover.config import ConfigError, PhysicsConfig, RunConfig
from physrover.experiment.store import load_champions, load_run_config
from physrover.experiment.training import train
from physrover.learn.configs import CriticConfig, SampledConfig

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


# ``tests/data/run-0.5-max-critic`` and ``run-0.5-average`` were written by physrover 0.5
# (commit 7350262: every method's settings in one flat [learn]), 2 generations each, with
# ``--set critic_hidden=4 replay_pairs=100 pair_batch=5 pair_batches=2 n_samples=3`` for
# both (0.5 took a setting of another method's and ignored it).
RUNS_05 = {m: Path(__file__).parent / "data" / f"run-0.5-{m}" for m in ("max-critic", "average")}


def test_a_05_run_reads_its_settings_from_learn_with_one_note():
    note = (
        r"^\[learn\] critic_hidden, replay_pairs, pair_batch, pair_batches \(and 12 at their "
        r"defaults\) moved to \[critic\] in physrover 0.6; n_samples ignored \('max-critic' "
        r"has no such setting\) \(`physrover info` writes the new layout\)$"
    )
    with pytest.warns(UserWarning, match=note) as notes:
        critic = load_run_config(RUNS_05["max-critic"])
    assert len(notes) == 1
    assert critic.settings == CriticConfig(critic_hidden=4, replay_pairs=100, pair_batch=5,
                                           pair_batches=2)  # fmt: skip
    with pytest.warns(UserWarning, match=r"^\[learn\] n_samples moved to \[sampled\] in "
                      r"physrover 0.6; critic_hidden, replay_pairs, pair_batch, pair_batches "
                      r"ignored \('average' has no such setting\)"):  # fmt: skip
        average = load_run_config(RUNS_05["average"])
    assert average.settings == SampledConfig(n_samples=3)
    text = average.to_toml()  # written in the new layout, it reads back the same, quietly
    assert "[sampled]\nn_samples = 3" in text and "critic_hidden" not in text
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert RunConfig.from_toml(text) == average


@pytest.mark.parametrize("method", sorted(RUNS_05))
def test_a_05_run_resumes_bit_identically(tmp_path, method):
    old = tmp_path / "old"
    shutil.copytree(RUNS_05[method], old)
    with pytest.warns(UserWarning, match="moved to"):
        config = load_run_config(old)
        train(None, old, resume=True, generations=4, progress=False)
    fresh = train(config.with_overrides({"generations": 4}), tmp_path / "new", progress=False)
    assert _rows(old)[:2] == _rows(RUNS_05[method])  # 0.5's generations are kept
    assert _rows(old) == _rows(fresh)  # and 0.6 plays them, and the rest, bit for bit
    np.testing.assert_array_equal(load_champions(old)[1], load_champions(fresh)[1])


def test_a_method_given_another_methods_table_is_an_error_naming_both():
    text = '[learn]\nmethod = "average"\n[critic]\ncritic_hidden = 4\n'
    with pytest.raises(ConfigError, match=r"critic: a \[critic\] table, but method is "
                       r"'average' \(its table is \[sampled\]\)"):  # fmt: skip
        RunConfig.from_toml(text)
    with pytest.raises(ConfigError, match=r"n_samples: is a setting of \[sampled\] \(average, "
                       r"leniency\), not of method 'D'"):  # fmt: skip
        RunConfig().with_overrides({"method": "D", "n_samples": 3})
