"""The lab's code on random trajectories, replayed on physrover (issue 43).

``tests/data/lab-random/cases.json`` holds random lab configs and joint paths with the G and
every agent's reward that the lab's own code computed (its C++ core, built here; the
recorder and its conventions: ``tests/data/lab-random/record.py``). Each config goes through
:func:`physrover.config.lab.lab_domain`, the paths are scored on physrover's world, and G and
every agent's credit must equal the lab's to 1e-9. The lab's AllOrNothing is replayed with
its own rule (``ID-step-all-or-nothing-lab``; physrover's default ``ID-step`` differs where
nobody influenced a step, a documented difference).
"""

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
from conftest import score_paths

from physrover.config.lab import lab_domain
from physrover.domain.scoring.credit import team_credit
from physrover.domain.world import RoverWorld

DATA = json.loads((Path(__file__).parent / "data" / "lab-random" / "cases.json").read_text())


def _physrover(case: dict) -> tuple[float, np.ndarray]:
    paths = np.asarray(case["paths"], dtype=float)  # (agents, T + 1, 2)
    domain = lab_domain(case["config"], steps=paths.shape[1] - 1)
    lab_rule = {"ID-step": "ID-step-all-or-nothing-lab"}
    agents = tuple(dataclasses.replace(a, feedback=lab_rule.get(a.feedback, a.feedback))
                   for a in domain.agents)  # fmt: skip
    domain = dataclasses.replace(domain, agents=agents)
    world = RoverWorld(domain, 1)
    world.reset([np.random.default_rng(0)])
    np.testing.assert_array_equal(world.position_history[0, 0], paths[:, 0])  # the spawns
    score_paths(world, list(paths.transpose(1, 0, 2)), record=True)
    return float(world.G[0]), np.asarray(team_credit("G", domain)(world)[0])


def test_the_cases_are_the_labs_and_cover_every_rule():
    cases = DATA["cases"]
    assert DATA["lab_commit"].startswith("8a71aa8") and len(cases) >= 300
    envs = [c["config"]["env"] for c in cases]
    agents = [a for env in envs for kind in ("rovers", "uavs") for a in env["agents"][kind]]
    rewards = {a["reward_type"] for a in agents}
    timescales = {(a["IndirectDifference"]["automatic"]["timescale"],
                   a["IndirectDifference"]["automatic"]["credit"])
                  for a in agents if a["reward_type"] == "IndirectDifference"
                  and "IndirectDifference" in a}  # fmt: skip
    assert rewards == {"Global", "Difference", "IndirectDifference"} and len(timescales) == 8
    pois = [p for env in envs for kind in ("rover_pois", "hidden_pois") for p in env["pois"][kind]]
    assert {p.get("constraint", "final") for p in pois} == {"final", "sequential"}
    assert sum(c["G"] > 0 for c in cases) >= len(cases) // 4  # not a suite of zeros


@pytest.mark.parametrize("chunk", range(6))
def test_physrover_scores_the_labs_random_trajectories_as_the_lab(chunk):
    mismatches = []
    for j, case in enumerate(DATA["cases"][chunk::6]):
        G, credit = _physrover(case)
        if not (abs(G - case["G"]) <= 1e-9 and np.allclose(credit, case["rewards"], rtol=0,
                                                          atol=1e-9)):  # fmt: skip
            mismatches.append(f"case {chunk + 6 * j}: G {G} vs {case['G']}, "
                              f"{np.round(credit, 9).tolist()} vs {case['rewards']}")  # fmt: skip
    assert not mismatches, "\n".join(mismatches[:10])
