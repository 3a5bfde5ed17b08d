"""experiments/plateau_reading.py on hand-made episodes: two episodes of 5 rovers, four POIs
of value 1-4, n_req 2, whose records (who is near which POI at each step, which POI was
captured) are written by hand and every column of the reading worked out by hand."""

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from conftest import load_file

from physrover.config import DomainConfig, LearnConfig, RunConfig
from physrover.marl.configs import MAPPOConfig

ROOT = Path(__file__).parent.parent


def _episodes():
    """(T + 1 = 3, E = 2, R = 5, K = 4) in_range and (E, K) capture steps.

    Episode 0: rovers 0-2 at POI 4 at step 1 (captured, one surplus rover), rover 3 alone
    at POI 3 (one short of n_req 2), rover 4 never near a POI.
    Episode 1: rovers 0-1 at POI 1 at step 0 and rover 4 there alone at step 2 (captured,
    the group is 2); rovers 2-3 at POI 2 at step 2 (captured); POIs 3-4 empty."""
    near = np.zeros((3, 2, 5, 4), dtype=bool)
    near[1, 0, [0, 1, 2], 3] = True
    near[1, 0, 3, 2] = True
    near[0, 1, [0, 1], 0] = True
    near[2, 1, 4, 0] = True
    near[2, 1, [2, 3], 1] = True
    capture_step = np.array([[-1, -1, -1, 1], [0, 2, -1, -1]])
    return near, capture_step


def _reading(monkeypatch, config, near, capture_step):
    module = load_file(ROOT / "experiments" / "plateau_reading.py", "plateau_reading")
    # at the end, POIs at (+-10, 0), (0, +-10); rover r at (r, 0), but rover 4 of episode 1
    # at (0, 13): distances to the nearest POI 10, 9, 8, 7, 6 and 10, 9, 8, 7, 3
    pois = np.array([[10.0, 0.0], [-10.0, 0.0], [0.0, 10.0], [0.0, -10.0]])
    rovers = np.stack([np.arange(5.0), np.zeros(5)], axis=-1)[None].repeat(2, axis=0)
    rovers[1, 4] = (0.0, 13.0)
    state = SimpleNamespace(in_range=near, capture_step=capture_step, rover_positions=rovers,
                            poi_positions=pois[None].repeat(2, axis=0))  # fmt: skip
    env = SimpleNamespace(world=SimpleNamespace(state=state, G=np.array([4.0, 3.0])))
    monkeypatch.setattr(module, "load_run_config", lambda run_dir: config)
    monkeypatch.setattr(module, "play_champion", lambda run_dir, episodes: (0, env))
    return module.reading(Path("runs/n_req=2_seed=0"), episodes=2)


def _config(**learn) -> RunConfig:
    domain = DomainConfig(n_rovers=5, n_req=2, poi_values=(1.0, 2.0, 3.0, 4.0))
    return RunConfig(domain=domain, learn=LearnConfig(**learn))


def test_every_column_is_the_hand_worked_value(monkeypatch):
    row = _reading(monkeypatch, _config(method="max-critic", feedback="D++"), *_episodes())
    assert row == {
        "run": "n_req=2_seed=0", "method": "max-critic", "feedback": "D++", "n_req": 2,
        "seed": 0, "G": 3.5,
        "captured_1": 0.5, "captured_2": 0.5, "captured_3": 0.0, "captured_4": 0.5,
        "most_common_set": "{4}", "its_share": 0.5,  # a tie: the first episode's set
        "group_at_1": 1.0, "group_at_2": 1.0, "group_at_3": 0.5, "group_at_4": 1.5,
        "idle_rovers": 0.5, "surplus_rovers": 0.5, "one_short": 0.5,
        "end_to_poi": 8.0,  # the median of 10, 9, 8, 7, 6, 10, 9, 8, 7, 3
    }  # fmt: skip


def test_a_trainer_s_feedback_is_its_own_reward(monkeypatch):
    """MAPPO learns from [mappo] reward; [learn] feedback (D by default) is not its signal."""
    config = RunConfig(
        domain=_config(method="mappo").domain,
        learn=LearnConfig(method="mappo"),
        settings=MAPPOConfig(reward="D++"),
    )
    assert config.learn.feedback == "D"
    assert _reading(monkeypatch, config, *_episodes())["feedback"] == "D++"


def test_captures_by_another_rule_are_refused(monkeypatch):
    """A capture without n_req rovers at once (another POI rule) would make the group
    columns meaningless: the reading stops."""
    near, capture_step = _episodes()
    capture_step[0, 2] = 1  # POI 3 of episode 0 had one rover
    with pytest.raises(SystemExit, match="not n_req rovers at once"):
        _reading(monkeypatch, _config(method="max-critic"), near, capture_step)
