"""The lab's own reward tests, run on physrover (issue 43).

``tests/data/lab-rewards/cases.json`` holds every reward assertion of AADILab/influence-
shaping's ``test/env/rewards`` suite (its commit in the file): the config each test built
(a lab YAML config as a dict), the agents' paths and the rewards the lab expects. They were
recorded by running the lab's test methods with stubs in place of its C++ environment, so
they are the lab's values, not ours. Here each config goes through
:func:`physrover.config.lab.lab_domain`, the paths are played on physrover's world, and
every agent's credit (its class's ``feedback``) must equal the lab's to 1e-9.

The lab's helpers: ``assert_path_rewards`` checks every agent's reward after the reset and
after each step of the path (the rewards over the path so far); ``assert_correct_rewards``
and ``reset_rewards`` the rewards at the reset; ``assert_final_rewards`` the rewards after
the whole path; ``G`` the team score after it.
"""

import json
from pathlib import Path

import numpy as np
import pytest
from conftest import score_paths

from physrover.config.lab import lab_domain
from physrover.domain.scoring.credit import team_credit
from physrover.domain.world import RoverWorld

DATA = json.loads((Path(__file__).parent / "data" / "lab-rewards" / "cases.json").read_text())
CASES = {case["id"]: case for case in DATA["cases"]}


def _spawns(config: dict) -> list[list[float]]:
    agents = config["env"]["agents"]
    return [a["position"]["fixed"] for a in [*agents["rovers"], *agents["uavs"]]]


def _rewards(config: dict, path: list) -> tuple[np.ndarray, float]:
    """Each agent's credit and G after the positions ``path`` (``path[0]``: the spawn),
    every position scored (a path of one position: the reset's, held one step)."""
    path = path if len(path) > 1 else [path[0], path[0]]
    domain = lab_domain(config, steps=len(path) - 1)
    world = RoverWorld(domain, 1)
    world.reset([np.random.default_rng(0)])
    np.testing.assert_array_equal(world.position_history[0, 0], path[0])  # the lab's spawns
    score_paths(world, [np.asarray(p, dtype=float) for p in path], record=True)
    credit = team_credit("G", domain)(world)[0]
    return credit, float(world.G[0])


def _checks(case: dict):
    """(description, physrover's value(s), the lab's) for every assertion of a case."""
    config, paths, expected = case["config"], case["paths"], case["expected"]
    path = [_spawns(config), *paths]
    helper = case["helper"]
    if helper == "assert_path_rewards":
        for t, want in enumerate(expected[: len(path)]):
            yield f"step {t}", _rewards(config, path[: t + 1])[0][: len(want)], want
    elif helper == "assert_correct_rewards":
        yield "reset", _rewards(config, path[:1])[0][: len(expected)], expected
    elif helper == "assert_final_rewards":
        yield "final", _rewards(config, path)[0][: len(expected)], expected
    elif helper == "assert_np_close:G":
        yield "G", _rewards(config, path)[1], expected
    elif helper == "assert_np_close:reset_rewards":
        yield "reset", _rewards(config, path[:1])[0], expected
    elif helper == "assert_np_close:reset_rewards[i]":
        yield "reset", _rewards(config, path[:1])[0][case["agent_index"]], expected
    else:
        raise AssertionError(f"unknown helper {helper}")


@pytest.mark.parametrize("case_id", sorted(CASES))
def test_the_labs_reward_assertions_hold(case_id):
    case = CASES[case_id]
    mismatches = []
    for what, ours, lab in _checks(case):
        if not np.allclose(ours, lab, rtol=0.0, atol=1e-9):
            mismatches.append(f"{what}: physrover {np.round(ours, 12).tolist()}, lab {lab}")
    assert not mismatches, "; ".join(mismatches)


def test_the_data_is_the_labs_whole_suite():
    assert DATA["lab_commit"] == "8a71aa8c34af43b849178d0efbf2f12ce7e2e284"
    assert len(CASES) == len(DATA["cases"]) == 164
    assert sum(len(c["expected"]) if isinstance(c["expected"], list) else 1
               for c in DATA["cases"]) > 300  # fmt: skip
