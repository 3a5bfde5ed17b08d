"""IndirectDifference (issue 33): hand-worked credits, a plain-loop oracle on random
episodes, and D where nobody influences anyone."""

import dataclasses

import numpy as np
import pytest
from conftest import random_episode, score_paths
from oracles import indirect_difference_loops, lab_captured, lab_influence_sets, lab_step_value

from physrover.config import ConfigError, DomainConfig, LearnConfig, RunConfig
from physrover.domain.scoring.credit import CREDITS, ByClass, team_credit
from physrover.domain.scoring.influence import replay_captures
from physrover.domain.scoring.rules import PoiRules
from physrover.domain.world import RoverWorld, StartOverrides
from physrover.learn.ccea import CCEA

ROVER_AND_TWO_UAVS = """
[domain]
n_req = 1
[[agents]]
name = "rover"
[[agents]]
name = "uav"
count = 2
captures = false
action = "world"
influence_radius = 5.0
"""


CREDIT_RULES = {"ID": ("trajectory", "all-or-nothing"), "ID-step": ("step", "all-or-nothing"),
                "ID-step-local": ("step", "local"), "ID-step-system": ("step", "system"),
                "ID-step-difference": ("step", "difference")}  # fmt: skip


def _episode(paths, pois=((0.0, 0.0),), values=(2.0,), domain=None):
    """The world after hand-made paths (``paths[t]``: every agent's position at step t) of
    ``domain`` (default: a rover and two UAVs)."""
    domain = (domain or DomainConfig.from_toml(ROVER_AND_TWO_UAVS)).replace(
        steps=len(paths) - 1, poi_values=values)  # fmt: skip
    world = RoverWorld(domain, 1)
    world.reset([np.random.default_rng(0)], StartOverrides(
        rover_positions=np.asarray(paths[0], dtype=float), rover_headings=np.zeros(3),
        poi_positions=np.asarray(pois, dtype=float)))  # fmt: skip
    score_paths(world, paths, record=True)
    return world


def _credits(world):
    return {name: CREDITS[name](world)[0].tolist() for name in ("D", "ID", "ID-step")}


FAR, AWAY = (40.0, 0.0), (-40.0, 0.0)  # a rover far from the POI; a UAV far from all
AT = (1.0, 0.0)  # the rover on the POI (within d_cap = 4)


def test_a_uav_near_at_the_capture_is_credited_with_it():
    world = _episode([[FAR, AWAY, AWAY], [AT, (3.0, 0.0), AWAY], [FAR, AWAY, AWAY]])
    assert world.G[0] == 2.0
    assert _credits(world) == {"D": [2.0, 0.0, 0.0], "ID": [2.0, 2.0, 0.0],
                               "ID-step": [2.0, 2.0, 0.0]}  # fmt: skip


def test_trajectory_credit_needs_no_presence_at_the_capture():
    # the UAV is near the rover at steps 0 and 2, not at the capture (step 1)
    world = _episode([[FAR, (42.0, 0.0), AWAY], [AT, AWAY, AWAY], [FAR, (41.0, 0.0), AWAY]])
    assert _credits(world) == {"D": [2.0, 0.0, 0.0], "ID": [2.0, 2.0, 0.0],
                               "ID-step": [2.0, 0.0, 0.0]}  # fmt: skip


def test_the_most_present_and_the_present_at_the_step_differ():
    # UAV 1 (agent 1) near the rover at steps 0, 2 and 3; UAV 2 only at the capture, step 1
    paths = [[FAR, (41.0, 0.0), AWAY], [AT, AWAY, (2.0, 0.0)], [FAR, (39.0, 0.0), AWAY],
             [FAR, (40.5, 0.0), AWAY]]  # fmt: skip
    assert _credits(_episode(paths)) == {"D": [2.0, 0.0, 0.0], "ID": [2.0, 2.0, 0.0],
                                         "ID-step": [2.0, 0.0, 2.0]}  # fmt: skip


def test_ties_go_to_the_lower_index_and_nobody_near_credits_nobody():
    tie = _episode([[FAR, AWAY, AWAY], [AT, (2.0, 0.0), (0.0, 0.0)], [FAR, AWAY, AWAY]])
    assert _credits(tie) == {"D": [2.0, 0.0, 0.0], "ID": [2.0, 2.0, 0.0],
                             "ID-step": [2.0, 2.0, 0.0]}  # fmt: skip
    alone = _episode([[FAR, AWAY, AWAY], [AT, AWAY, AWAY], [FAR, AWAY, AWAY]])
    assert _credits(alone) == {"D": [2.0, 0.0, 0.0], "ID": [2.0, 0.0, 0.0],
                               "ID-step": [2.0, 0.0, 0.0]}  # fmt: skip


def test_the_labs_step_credits_share_split_or_pool_a_step():
    """Both UAVs near the rover at its capture (step 1), UAV 2 alone near it at step 2:
    AllOrNothing credits the lower index, Local both, Difference neither (nobody is alone
    at the capture), System every agent (a UAV far from everyone too)."""
    both = [[FAR, AWAY, AWAY], [AT, (2.0, 0.0), (0.0, 0.0)], [FAR, AWAY, (41.0, 0.0)]]
    credits = {name: CREDITS[name](_episode(both))[0].tolist()
               for name in ("ID-step", "ID-step-local", "ID-step-difference")}  # fmt: skip
    assert credits == {"ID-step": [2.0, 2.0, 0.0], "ID-step-local": [2.0, 2.0, 2.0],
                       "ID-step-difference": [2.0, 0.0, 0.0]}  # fmt: skip
    alone = [[FAR, AWAY, AWAY], [AT, (2.0, 0.0), AWAY], [FAR, AWAY, AWAY]]
    assert CREDITS["ID-step-difference"](_episode(alone))[0].tolist() == [2.0, 2.0, 0.0]
    assert CREDITS["ID-step-system"](_episode(alone))[0].tolist() == [2.0, 2.0, 2.0]
    assert CREDITS["ID-step-local"](_episode(alone))[0].tolist() == [2.0, 2.0, 0.0]


def test_without_influencers_every_credit_is_d():
    scenario = {"kind": "uniform", "half_size": 6.0, "min_separation": 1.0}
    world = RoverWorld(DomainConfig(n_req=2, n_rovers=6, scenario=scenario), 8)
    world.reset([np.random.default_rng(e) for e in range(8)])
    rng = np.random.default_rng(0)
    for _ in range(world.config.steps):
        world.step(rng.uniform(-1, 1, (8, 6, 2)))
    assert world.G.max() > 0
    for name in CREDIT_RULES:
        np.testing.assert_array_equal(CREDITS[name](world), world.D)


def test_replay_with_nothing_removed_is_the_episode():
    world = RoverWorld(DomainConfig(n_req=2, n_rovers=6), 5)
    world.reset([np.random.default_rng(e) for e in range(5)])
    rng = np.random.default_rng(1)
    for _ in range(world.config.steps):
        world.step(rng.uniform(-1, 1, (5, 6, 2)))
    removed = np.zeros((5, 2, world.config.steps + 1, 6), dtype=bool)
    removed[:, 1, :, 3] = True  # set 1: rover 3's whole trajectory, D's counterfactual
    out = np.empty((5, 2, 4), dtype=bool)
    rules = PoiRules.build(world.config, 5, always=True)
    replay_captures(world.state.in_range, removed, world.n_req, rules, out)
    np.testing.assert_array_equal(out[:, 0], world.state.captured)
    np.testing.assert_array_equal(out[:, 1], world.state.captured_without[:, 3])


MIXED = """
[domain]
n_req = 2
steps = 30
scenario = {{ kind = "uniform", half_size = 6.0, min_separation = 1.0 }}
[[pois]]
value = 1.0
[[pois]]
value = 2.0
require = {{ rover = 1, uav = 1 }}
[[pois]]
value = 3.0
after = [0]
[[pois]]
value = 4.0
score_at = "{last}"
[[agents]]
name = "rover"
count = 4
[[agents]]
name = "uav"
count = 2
captures = false
action = "world"
influence_radius = 3.0
"""


@pytest.mark.parametrize("name", list(CREDIT_RULES))
@pytest.mark.parametrize("seed", range(4))
def test_random_episodes_credit_as_the_oracle(seed, name):
    timescale, rule = CREDIT_RULES[name]
    text = MIXED.format(last=["any", "final"][seed % 2])
    if seed >= 2:
        text = text.replace("steps = 30", 'steps = 30\nscored_states = "before-steps"')
    domain = DomainConfig.from_toml(text)
    world = RoverWorld(domain, 8)
    world.reset([np.random.default_rng([seed, e]) for e in range(8)])
    rng = np.random.default_rng(seed)
    for _ in range(domain.steps):
        world.step(rng.uniform(-1, 1, (8, 6, 2)))
    credit = CREDITS[name](world)
    pois = domain.pois
    last = domain.steps if domain.scored_states == "all" else domain.steps - 1
    influence, counted = [0.0] * 4 + [3.0] * 2, [True] * 4 + [False] * 2
    differs = 0
    for e in range(8):
        score_args = (world.poi_positions[e].tolist(), world.poi_values[e].tolist(),
                      [domain.d_cap] * 4, domain.n_req_per_poi, [list(p.after) for p in pois],
                      [p.score_at == "final" for p in pois], list(range(last + 1)))  # fmt: skip
        expected = indirect_difference_loops(world.position_history[:, e].tolist(),
                                             score_args, influence, counted, timescale, rule,
                                             require=[{}, {0: 1, 1: 1}, {}, {}],
                                             classes=[0] * 4 + [1] * 2)  # fmt: skip
        assert credit[e].tolist() == expected
        differs += int((credit[e] != world.D[e]).any())
    assert world.G.max() > 0
    assert differs > 0 or rule == "difference"  # the UAVs earned something D does not give
    assert world.state.captured[:, 1].any()  # the typed POI (a rover and a UAV) was captured


LAB_CREDITS = {"ID": ("trajectory", ""), "ID-step": ("timestep", "AllOrNothing"),
               "ID-step-local": ("timestep", "Local"), "ID-step-system": ("timestep", "System"),
               "ID-step-difference": ("timestep", "Difference"),
               "ID-step-all-or-nothing-lab": ("timestep", "AllOrNothing-lab")}  # fmt: skip


@pytest.mark.parametrize("seed", range(3))
def test_distance_valued_pois_credit_as_the_labs_code(seed):
    """POIs valued by distance (the lab's only kind), "any" (its sequential) or "final",
    captured by radius or by sight, hidden from rovers or not, four rovers and two UAVs of
    influence radius 5 (the lab's): every credit equals the lab's code written as it is
    (``computer.hpp``'s influence arrays, ``custom_env.py``'s values; the one change in
    :func:`lab_influence_sets`), a removed agent left out, to 1e-12."""
    rng = np.random.default_rng(seed)
    pois = []
    for _ in range(4):
        by = str(rng.choice(["radius", "sight"]))
        hidden = ["uav"] if rng.integers(2) else []
        pois.append({"value": float(rng.integers(1, 4)), "n_req": int(rng.integers(1, 3)),
                     "value_by": "distance", "capture_by": by, "visible_to": hidden,
                     "score_at": str(rng.choice(["any", "final"])),
                     "capture_radius": 0.0 if by == "sight" else 3.0})  # fmt: skip
    agents = [{"name": "rover", "count": 4, "sensor": {"kind": "lidar", "radius": 3.0}},
              {"name": "uav", "count": 2, "captures": False, "influence_radius": 5.0,
               "sensor": {"kind": "lidar", "radius": 6.0}}]  # fmt: skip
    world = random_episode(rng, seed, 8, 5.0, steps=12, pois=pois, agents=agents)
    steps = world.config.steps
    counting, sensing = [True] * 4 + [False] * 2, [3.0] * 4 + [6.0] * 2
    credits = {name: CREDITS[name](world) for name in LAB_CREDITS}
    seen = set()
    for e in range(8):
        path = world.position_history[:, e]

        def G(removed=frozenset(), e=e, path=path):
            total = 0.0
            for k, p in enumerate(pois):
                radius = -1.0 if p["capture_by"] == "sight" else p["capture_radius"]
                reach = lambda i, d, r=radius: lab_captured(d, sensing[i], r, np.inf)  # noqa: E731
                times = [steps] if p["score_at"] == "final" else range(steps + 1)
                total += p["value"] * max(
                    lab_step_value(path[t], world.poi_positions[e, k], counting, reach,
                                   p["n_req"], {i for (s, i) in removed if s == t})
                    for t in times
                )  # fmt: skip
            return total

        complete = [[[int(u >= 4 and k < 4 and np.linalg.norm(path[t, u] - path[t, k]) <= 5.0)
                      for k in range(6)] for u in range(6)] for t in range(steps + 1)]  # fmt: skip
        for name, (timescale, credit) in LAB_CREDITS.items():
            for i in range(6):
                removed = lab_influence_sets(complete, i, timescale, credit)
                removed |= {(t, i) for t in range(steps + 1)}
                expected = G() - G(frozenset(removed))
                assert credits[name][e, i] == pytest.approx(expected, rel=1e-12, abs=1e-12)
                seen.add((name, expected != G() - G(frozenset((t, i) for t in range(steps + 1)))))
    assert world.G.max() > 0
    assert all((name, True) in seen for name in LAB_CREDITS)  # each credit differed from D


def test_a_class_takes_its_own_feedback_and_g_on_top():
    """The lab's per-agent reward_type and add_G: the rover on D (the run's), the UAVs on
    ID-step plus G; each column is its signal's column of the same episode."""
    world = _episode([[FAR, AWAY, AWAY], [AT, (3.0, 0.0), AWAY], [FAR, AWAY, AWAY]])
    uav = {**world.config.agents[1].table(), "feedback": "ID-step", "feedback_plus_G": True}
    domain = world.config.replace(agents=[world.config.agents[0], uav])
    credit = team_credit("D", domain)
    assert isinstance(credit, ByClass)
    assert credit(world)[0].tolist() == [2.0, 2.0 + 2.0, 0.0 + 2.0]  # D; ID-step + G
    assert not credit.per_step_defined  # no per-step G on top
    rover_own = domain.replace(agents=[{**domain.agents[0].table(), "feedback": "G"},
                                       domain.agents[1]])  # fmt: skip
    assert team_credit("D", rover_own)(world)[0].tolist() == [2.0, 4.0, 2.0]
    assert team_credit("ID-step", world.config) is CREDITS["ID-step"]  # nobody differs
    with pytest.raises(ConfigError, match="agents\\[1\\].feedback: unknown credit signal 'IDs"):
        domain.replace(agents=[domain.agents[0], {**uav, "feedback": "IDstep"}])
    rover = domain.agents[0].table()
    ordered = {"domain": {"n_req": 1}, "pois": [{}, {"after": [0]}],
               "agents": [rover, {**uav, "feedback": "D++"}]}  # fmt: skip
    with pytest.raises(ConfigError, match="feedback: D\\+\\+ is not defined for POIs with after"):
        RunConfig.from_dict(ordered)


def test_manual_assignment_removes_the_listed_agents_only():
    """The lab's ``assignment = manual``: G minus G without the listed agents; the agent
    itself stays unless listed, and a class that lists nobody is credited 0."""
    world = _episode([[FAR, AWAY, AWAY], [AT, (3.0, 0.0), AWAY], [FAR, AWAY, AWAY]])
    uav = {**world.config.agents[1].table(), "manual_removal": [0]}
    domain = world.config.replace(agents=[world.config.agents[0], uav])
    world = _episode([[FAR, AWAY, AWAY], [AT, (3.0, 0.0), AWAY], [FAR, AWAY, AWAY]],
                     domain=domain)  # fmt: skip
    assert CREDITS["ID-manual"](world)[0].tolist() == [0.0, 2.0, 2.0]
    mixed = domain.replace(agents=[domain.agents[0], {**uav, "feedback": "ID-manual"}])
    assert team_credit("D", mixed)(world)[0].tolist() == [2.0, 2.0, 2.0]
    itself = domain.replace(agents=[domain.agents[0], {**uav, "manual_removal": [1, 2]}])
    world = _episode([[FAR, AWAY, AWAY], [AT, (3.0, 0.0), AWAY], [FAR, AWAY, AWAY]],
                     domain=itself)  # fmt: skip
    assert CREDITS["ID-manual"](world)[0].tolist() == [0.0, 0.0, 0.0]  # UAVs never count
    with pytest.raises(ConfigError, match=r"agents\[1\].manual_removal: agents are 0 .. 2 in a"):
        domain.replace(agents=[domain.agents[0], {**uav, "manual_removal": [3]}])


def test_the_ccea_trains_each_class_on_its_own_feedback():
    """A rollout's credit is the composed one: the UAVs' columns are ID-step's, the rovers'
    D's (the run's), for the same teams."""
    run = RunConfig.from_toml(MIXED.format(last="any") + "[learn]\npopulation = 4\n")
    classes = [run.domain.agents[0], {**run.domain.agents[1].table(), "feedback": "ID-step"}]
    ccea = CCEA(dataclasses.replace(run, domain=run.domain.replace(agents=classes)))
    plain = CCEA(run)
    n = ccea.n_played + run.learn.eval_episodes
    index = np.tile(np.arange(n)[:, None] % 4, (1, 6))
    G, credit = ccea.rollout(index)
    G_plain, D = plain.rollout(index)
    np.testing.assert_array_equal(G, G_plain)
    np.testing.assert_array_equal(credit[:, :4], D[:, :4])
    np.testing.assert_array_equal(credit[:, 4:], CREDITS["ID-step"](ccea.env.world)[:, 4:])
    assert (credit[:, 4:] != D[:, 4:]).any()  # a case that tells the two apart


def test_the_credits_are_feedback_names():
    assert LearnConfig(feedback="ID").feedback == "ID"
    assert LearnConfig(feedback="ID-step").feedback == "ID-step"


def test_the_labs_all_or_nothing_gives_agent_0_the_steps_nobody_influenced():
    """A UAV first in the team (agent 0), then the rover and a second UAV: the rover
    captures at step 1 with nobody near. physrover's AllOrNothing credits nobody with that
    step (the UAVs get 0); the lab's code gives it to agent 0, the far UAV (2); where the
    second UAV is near at the capture, both rules credit it alone."""
    uav = '\ncaptures = false\naction = "world"\ninfluence_radius = 5.0\n'
    uav_first = DomainConfig.from_toml(
        '[domain]\nn_req = 1\n[[agents]]\nname = "lead"'
        + uav
        + '[[agents]]\nname = "rover"\n[[agents]]\nname = "uav"'
        + uav
    )
    alone = [[AWAY, FAR, AWAY], [AWAY, AT, AWAY], [AWAY, FAR, AWAY]]
    lab = CREDITS["ID-step-all-or-nothing-lab"]
    assert CREDITS["ID-step"](_episode(alone, domain=uav_first))[0].tolist() == [0.0, 2.0, 0.0]
    assert lab(_episode(alone, domain=uav_first))[0].tolist() == [2.0, 2.0, 0.0]
    near = [[AWAY, FAR, AWAY], [AWAY, AT, (3.0, 0.0)], [AWAY, FAR, AWAY]]
    for name in ("ID-step", "ID-step-all-or-nothing-lab"):
        assert CREDITS[name](_episode(near, domain=uav_first))[0].tolist() == [0.0, 2.0, 2.0]
