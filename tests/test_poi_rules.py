"""POIs with rules ([[pois]], issue 33): config, hand-worked scores, a plain-loop oracle."""

import dataclasses

import numpy as np
import pytest
from conftest import play_alike, random_episode, score_paths
from oracles import lab_captured, lab_step_value, score_rules_loops

from physrover.config import ConfigError, DomainConfig, RunConfig
from physrover.domain.scoring.credit import CREDITS
from physrover.domain.scoring.rules import PoiRules
from physrover.domain.world import RoverWorld, StartOverrides

LAB_TOML = """
[domain]
n_req = 2

[[pois]]
value = 1.0

[[pois]]                  # counts only once POI 0 was captured at an earlier step
value = 2.0
after = [0]

[[pois]]                  # its own radius and coupling
value = 2.0
capture_radius = 2.5
n_req = 1

[[pois]]                  # the lab's "final" constraint: only the last scored state counts
value = 4.0
score_at = "final"
"""


def test_pois_tables_round_trip_and_derive_values():
    config = RunConfig.from_toml(LAB_TOML)
    d = config.domain
    assert d.poi_values == (1.0, 2.0, 2.0, 4.0)  # derived, and may repeat
    assert d.n_req_per_poi == (2, 2, 1, 2)
    assert RunConfig.from_toml(config.to_toml()) == config
    assert "[[pois]]" in config.to_toml() and "poi_values" not in config.to_toml()
    assert config.with_overrides({"n_req": 3}).domain.n_req_per_poi == (3, 3, 1, 3)
    # without [[pois]] the config's TOML is what it was
    assert "pois" not in DomainConfig().to_toml()


@pytest.mark.parametrize(
    ("toml", "message"),
    [
        ("[[pois]]\nafter = [0]", "pois[0].after: must list earlier POIs (indices < 0)"),
        ("[[pois]]\nvalue = -1", "pois[0].value: must be positive and finite, got -1.0"),
        ("[[pois]]\ncapture_radius = 0.5", "pois[0].capture_radius: must be >= d_min (1.0)"),
        ("[[pois]]\nn_req = 16", "pois[0].n_req: must be in [1, n_rovers=15], got 16"),
        ('[[pois]]\nscore_at = "fnal"', "(did you mean 'final'?)"),
        (
            "[[pois]]\nvalu = 1",
            "pois[0].valu: unknown PoiRule field (did you mean 'value' or 'value_by'?)",
        ),
        ("[domain]\npoi_values = [1.0]\n[[pois]]", "poi_values: give the POIs as [[pois]] or"),
        (
            '[[pois]]\nscore_at = "final"\n[[pois]]\nafter = [0]',
            "pois[1].after: POI 0 is scored at the final state only",
        ),  # fmt: skip
        ("[domain]\nn_req = [1, 2]\n[[pois]]\n[[pois]]", "n_req: give each POI's coupling"),
        ("pois = 3", "pois: expected a list of [[pois]] tables"),
    ],
)
def test_bad_pois_tables_name_the_field(toml, message):
    with pytest.raises(ConfigError) as info:
        RunConfig.from_toml(toml)
    assert message in str(info.value)


def test_pois_cannot_be_set_from_the_command_line():
    config = RunConfig.from_toml(LAB_TOML)
    for name in ("pois", "poi_values"):
        with pytest.raises(ConfigError, match=r"set \[\[pois\]\] and \[\[agents\]\] tables"):
            config.with_overrides({name: [1.0]})


# -- hand-worked scores: positions set step by step, scored by the compiled kernel ------------


def _scored(pois, paths, poi_positions, n_rovers=None, steps=4, **domain):
    """Score hand-made paths: ``paths[t]`` the (R, 2) positions at step t. Returns the world
    after scoring steps 0 .. len(paths) - 1 (G, D, capture_step)."""
    n_rovers = n_rovers or len(paths[0])
    config = DomainConfig(n_rovers=n_rovers, steps=steps, pois=pois, n_req=1, **domain)
    world = RoverWorld(config, 1)
    world.reset([np.random.default_rng(0)], StartOverrides(
        rover_positions=paths[0], rover_headings=np.zeros(n_rovers),
        poi_positions=poi_positions))  # fmt: skip
    score_paths(world, paths)
    return world


FAR = (50.0, 50.0)
CHAIN = [{"value": 1.0}, {"value": 2.0, "after": [0]}]
CHAIN_POIS = [(0.0, 0.0), (20.0, 0.0)]


def test_a_chain_needs_its_predecessor_at_an_earlier_step():
    # rover 0 reaches POI 0 at step 2; rover 1 is at POI 1 at step 2 only: same step, no
    at_2 = [[FAR, FAR], [FAR, FAR], [(0.0, 0.0), (20.0, 0.0)], [(0.0, 0.0), FAR]]
    world = _scored(CHAIN, at_2, CHAIN_POIS)
    assert world.G[0] == 1.0
    assert list(world.state.capture_step[0]) == [2, -1]
    # rover 1 stays at POI 1 one step more: captured at step 3
    at_3 = [*at_2[:3], [(0.0, 0.0), (20.0, 0.0)]]
    world = _scored(CHAIN, at_3, CHAIN_POIS)
    assert world.G[0] == 3.0
    assert list(world.state.capture_step[0]) == [2, 3]
    # the paper's POIs (no rule) would have counted POI 1 at step 2
    paper = _scored([{"value": 1.0}, {"value": 2.0}], at_2, CHAIN_POIS)
    assert paper.G[0] == 3.0


def test_difference_applies_the_order_to_each_counterfactual():
    # rover 0 captures POI 0 at step 1, rover 1 POI 1 at step 2: G = 3. Without rover 0,
    # POI 0 is never captured, so POI 1 never counts: D_0 = 3; without rover 1, D_1 = 2.
    paths = [[FAR, FAR], [(0.0, 0.0), FAR], [FAR, (20.0, 0.0)]]
    world = _scored(CHAIN, paths, CHAIN_POIS)
    assert world.G[0] == 3.0
    assert list(world.D[0]) == [3.0, 2.0]
    assert list(world.plan.step.rules.step_without[0, 1]) == [1, -1]  # without rover 1: POI 0 at 1


def test_final_pois_count_only_at_the_last_scored_state():
    pois = [{"value": 4.0, "score_at": "final"}]
    early = [[(0.0, 0.0)], [(0.0, 0.0)], [FAR], [FAR], [FAR]]  # steps 0..4, steps = 4
    assert _scored(pois, early, [(0.0, 0.0)]).G[0] == 0.0
    late = [[FAR], [FAR], [FAR], [FAR], [(0.0, 0.0)]]
    assert _scored(pois, late, [(0.0, 0.0)]).G[0] == 4.0
    # under "before-steps" the last scored state is steps - 1 = 3
    w = _scored(pois, late[:4] + [[(0.0, 0.0)]], [(0.0, 0.0)], scored_states="before-steps")
    assert w.plan.step.rules.t_final == 3 and w.G[0] == 0.0
    w = _scored(pois, [[FAR], [FAR], [FAR], [(0.0, 0.0)]], [(0.0, 0.0)],
                scored_states="before-steps")  # fmt: skip
    assert w.G[0] == 4.0


def test_each_poi_has_its_own_capture_radius():
    pois = [{"value": 1.0, "capture_radius": 2.5}, {"value": 2.0}]  # the second: d_cap = 4
    world = _scored(pois, [[(3.0, 0.0)]], [(0.0, 0.0), (6.0, 0.0)])
    assert world.G[0] == 2.0  # 3 > 2.5 from POI 0, 3 <= 4 from POI 1
    assert world.state.in_range[0, 0, 0].tolist() == [False, True]
    assert _scored(pois, [[(2.5, 0.0)]], [(0.0, 0.0), (6.0, 0.0)]).G[0] == 3.0  # on the edge


SIGHTED = [{"name": "rover", "count": 1, "sensor": {"kind": "lidar", "radius": 3.0}},
           {"name": "uav", "count": 1, "sensor": {"kind": "lidar", "radius": 6.0}}]  # fmt: skip


def test_capture_by_sight_is_within_the_agents_and_the_pois_radii():
    poi = {"value": 1.0, "capture_by": "sight", "sense_radius": 5.0}
    at = lambda d_rover, d_uav: [[(d_rover, 0.0), (0.0, d_uav)]]  # noqa: E731
    world = _scored([poi], at(2.9, 5.5), [(0.0, 0.0)], agents=SIGHTED)
    # the rover within its 3; the UAV beyond the POI's 5 although within its own 6
    assert world.state.in_range[0, 0, :, 0].tolist() == [True, False]
    assert world.G[0] == 1.0 and world.D[0].tolist() == [1.0, 0.0]
    world = _scored([poi], at(3.1, 4.9), [(0.0, 0.0)], agents=SIGHTED)
    assert world.state.in_range[0, 0, :, 0].tolist() == [False, True]
    # the lab's POI with a capture radius: in range by either rule
    either = {"value": 1.0, "capture_by": "radius-or-sight", "capture_radius": 1.5,
              "sense_radius": 2.0, "n_req": 2}  # fmt: skip
    world = _scored([either], at(1.4, 1.9), [(0.0, 0.0)], agents=SIGHTED)
    assert world.state.in_range[0, 0, :, 0].tolist() == [True, True]  # by radius, by sight
    assert world.G[0] == 1.0 and world.D[0].tolist() == [1.0, 1.0]  # the coupling needs both
    world = _scored([either], at(1.4, 2.1), [(0.0, 0.0)], agents=SIGHTED)
    assert world.state.in_range[0, 0, :, 0].tolist() == [True, False] and world.G[0] == 0.0
    with pytest.raises(ConfigError, match='capture_radius: is not used under capture_by = "s'):
        DomainConfig(pois=[{"capture_by": "sight", "capture_radius": 2.0}])
    with pytest.raises(ConfigError, match="capture_by: must be one of radius, sight"):
        DomainConfig(pois=[{"capture_by": "sensor"}])


@pytest.mark.parametrize("seed", range(4))
def test_random_episodes_capture_as_the_labs_rule(seed):
    """Agents of two classes with sensors of radius 3 and 6, POIs captured by radius, by
    sight or by either, of sense radius inf, 2.5 or 4: each step's in-range agents are the
    lab's rule written as it is, and G and D are the plain-loop oracle's on them."""
    rng = np.random.default_rng(seed)
    pois = []
    for _ in range(4):
        by = str(rng.choice(["radius", "sight", "radius-or-sight"]))
        radius = 0.0 if by == "sight" else float(rng.choice([1.5, 5.0]))
        pois.append({"value": float(rng.integers(1, 4)), "n_req": int(rng.integers(1, 3)),
                     "capture_by": by, "sense_radius": float(rng.choice([np.inf, 2.5, 4.0])),
                     "capture_radius": radius})  # fmt: skip
    agents = [dict(SIGHTED[0], count=3), dict(SIGHTED[1], count=2, captures=True)]
    world = random_episode(rng, seed, 3, 6.0, steps=20, pois=pois, agents=agents)
    config = world.config
    sensing = [3.0] * 3 + [6.0] * 2
    lab_radius = [-1.0 if p["capture_by"] == "sight" else p["capture_radius"] for p in pois]
    captures = 0
    for e in range(3):
        positions = world.position_history[:, e]
        for t in range(config.steps + 1):
            for k, p in enumerate(pois):
                for i in range(5):
                    d = float(np.hypot(*(positions[t, i] - world.poi_positions[e, k])))
                    if p["capture_by"] == "radius":
                        expected = d <= p["capture_radius"]
                    else:
                        expected = lab_captured(d, sensing[i], lab_radius[k], p["sense_radius"])
                    assert world.state.in_range[t, e, i, k] == expected, (t, i, k, d)
        radius = [[p["capture_radius"] if p["capture_by"] == "radius"
                   else max(lab_radius[k], min(a, p["sense_radius"])) for a in sensing]
                  for k, p in enumerate(pois)]  # fmt: skip
        args = (positions.tolist(), world.poi_positions[e].tolist(), world.poi_values[e].tolist(),
                radius, [p["n_req"] for p in pois], [[]] * 4, [False] * 4,
                list(range(config.steps + 1)))  # fmt: skip
        G, first = score_rules_loops(*args)
        assert world.G[e] == G
        for i in range(5):
            assert world.D[e, i] == G - score_rules_loops(*args, removed=i)[0]
        captures += sum(f >= 0 for f in first)
    assert captures > 0


def test_a_distance_valued_poi_is_worth_its_nearest_agents_distances():
    poi = {"value": 3.0, "value_by": "distance", "n_req": 2}
    world = _scored([poi], [[(0.5, 0.0), (0.0, 2.0), (-3.0, 0.0)]], [(0.0, 0.0)])
    # 2 x 1/max(1, 0.5) x 1/2 = 1: G = 3; without rover 0: 2 / 2 / 3; rover 1: 2 / 1 / 3;
    # rover 2 is not among the two nearest
    assert world.G[0] == 3.0
    np.testing.assert_allclose(world.D[0], [3.0 - 3.0 / 3.0, 3.0 - 3.0 * 2.0 / 3.0, 0.0])
    assert world.state.capture_step[0].tolist() == [0]
    # "any" keeps the best step's value (the lab's sequential), "final" the last state's
    paths = [[(0.5, 0.0), (0.0, 2.0)], [(0.5, 0.0), (0.0, 1.0)], [(0.5, 0.0), (0.0, 3.5)],
             [(0.5, 0.0), (0.0, 3.9)], [FAR, FAR]]  # fmt: skip
    assert _scored([poi], paths, [(0.0, 0.0)]).G[0] == 3.0 * 2.0  # step 1: 2 / 1 / 1
    final = dict(poi, score_at="final")
    assert _scored([final], paths[:4] + [paths[2]], [(0.0, 0.0)]).G[0] == 3.0 * 2.0 / 3.5
    assert _scored([final], paths, [(0.0, 0.0)]).G[0] == 0.0
    for field, value in (("after", [0]), ("require", {"rover": 1})):
        with pytest.raises(ConfigError, match=f'{field}: is not defined for value_by = "dis'):
            DomainConfig(pois=[{}, {"value_by": "distance", field: value}])
    for name in ("ID", "ID-step", "ID-step-system"):  # they replay distance values
        RunConfig.from_dict({"learn": {"feedback": name}, "pois": [poi] * 4})


@pytest.mark.parametrize("seed", range(4))
def test_random_episodes_value_pois_as_the_labs_code(seed):
    """Distance-valued POIs of coupling 1-3, "any" (the lab's sequential) or "final", each
    captured by radius or by sight, over random episodes of rovers and UAVs that do not
    count (the lab's rule counts rovers only): G and every D are the lab's code as it is
    written (the removed agent at an infinite distance), to 1e-12."""
    rng = np.random.default_rng(seed)
    pois = []
    for _ in range(4):
        by = str(rng.choice(["radius", "sight", "radius-or-sight"]))
        pois.append({"value": float(rng.integers(1, 4)), "n_req": int(rng.integers(1, 4)),
                     "value_by": "distance", "capture_by": by,
                     "score_at": str(rng.choice(["any", "final"])),
                     "capture_radius": 0.0 if by == "sight" else float(rng.choice([3.0, 6.0])),
                     "sense_radius": float(rng.choice([np.inf, 4.0]))})  # fmt: skip
    agents = [dict(SIGHTED[0], count=4), dict(SIGHTED[1], count=2, captures=False)]
    world = random_episode(rng, seed, 3, 5.0, steps=15, pois=pois, agents=agents)
    config = world.config
    sensing, counting = [3.0] * 4 + [6.0] * 2, [True] * 4 + [False] * 2
    valued = 0
    for e in range(3):

        def G(removed=-1, e=e):
            total = 0.0
            for k, p in enumerate(pois):
                lab_radius = -1.0 if p["capture_by"] == "sight" else p["capture_radius"]
                if p["capture_by"] == "radius":
                    reach = lambda agent, d, p=p: d <= p["capture_radius"]  # noqa: E731
                else:
                    reach = lambda agent, d, p=p, r=lab_radius: lab_captured(  # noqa: E731
                        d, sensing[agent], r, p["sense_radius"]
                    )
                steps = [config.steps] if p["score_at"] == "final" else range(config.steps + 1)
                values = [lab_step_value(world.position_history[t, e], world.poi_positions[e, k],
                                          counting, reach, p["n_req"], removed)
                          for t in steps]  # fmt: skip
                total += p["value"] * max(values)
            return total

        assert world.G[e] == pytest.approx(G(), rel=1e-12, abs=1e-12)
        for i in range(6):
            assert world.D[e, i] == pytest.approx(G() - G(i), rel=1e-12, abs=1e-12), i
        valued += world.G[e] > 0
    assert valued > 0  # some POI was worth something


# -- random episodes: the compiled scores against the plain-loop oracle ---------------------


@pytest.mark.parametrize("motion", ["ideal", "physics"])
@pytest.mark.parametrize("seed", range(6))
def test_random_episodes_score_as_the_oracle(seed, motion):
    rng = np.random.default_rng(seed)
    n_pois, n_rovers = 5, 6
    pois = []
    for k in range(n_pois):
        earlier = [j for j in range(k) if rng.random() < 0.4]
        final = rng.random() < 0.2
        pois.append({"value": float(rng.integers(1, 4)), "n_req": int(rng.integers(1, 3)),
                     "capture_radius": float(rng.choice([0.0, 2.0, 6.0])),
                     "after": earlier, "score_at": "final" if final else "any"})  # fmt: skip
    for k in range(n_pois):  # a rule may not wait for a final POI
        pois[k]["after"] = [j for j in pois[k]["after"] if pois[j]["score_at"] == "any"]
    scored_states = ["all", "before-steps"][seed % 2]
    world = random_episode(rng, seed, 4, 6.0, n_rovers=n_rovers, steps=25, pois=pois,
                            motion=motion, scored_states=scored_states)  # fmt: skip
    config = world.config
    radius = [p["capture_radius"] or config.d_cap for p in pois]
    after = [p["after"] for p in pois]
    final = [p["score_at"] == "final" for p in pois]
    last = config.steps if scored_states == "all" else config.steps - 1
    steps = list(range(last + 1))
    captures = 0
    for e in range(4):
        args = (world.position_history[:, e].tolist(), world.poi_positions[e].tolist(),
                world.poi_values[e].tolist(), radius, config.n_req_per_poi, after, final,
                steps)  # fmt: skip
        G, first = score_rules_loops(*args)
        assert world.G[e] == G
        assert world.state.capture_step[e].tolist() == first
        for i in range(n_rovers):
            assert world.D[e, i] == G - score_rules_loops(*args, removed=i)[0]
        captures += sum(f >= 0 for f in first)
    assert captures > 0  # the layouts are tight enough that the rules are exercised


def test_rules_that_mirror_the_paper_give_the_paper_episode():
    """[[pois]] with the paper's values and no rule, scored through the rules' kernel
    (built as if a rule were set): the paper's episode bit for bit (the generalised kernel
    reduces to Eqs. 11-13, which is why the plan may leave rules that mirror the paper's
    out)."""
    paper = DomainConfig(n_req=2)
    mirror = DomainConfig(n_req=2, pois=[{"value": v} for v in paper.poi_values])
    worlds = [RoverWorld(c, 3) for c in (paper, mirror)]
    assert worlds[1].plan.step.rules is None  # compiled away: the paper's POIs
    rules = PoiRules.build(mirror, 3, always=True)
    step = worlds[1].plan.step._replace(rules=rules)
    worlds[1].plan = dataclasses.replace(worlds[1].plan, step=step)
    rng = np.random.default_rng(7)
    actions = rng.uniform(-1, 1, (paper.steps, 3, paper.n_rovers, 2))
    play_alike(worlds, actions)
    a, b = worlds
    np.testing.assert_array_equal(a.observations, b.observations)
    np.testing.assert_array_equal(a.position_history, b.position_history)
    np.testing.assert_array_equal(a.state.in_range, b.state.in_range)
    np.testing.assert_array_equal(a.G, b.G)
    np.testing.assert_array_equal(a.D, b.D)
    assert a.G.max() > 0 or a.state.in_range.any()


def test_d_plus_plus_refuses_ordered_and_final_pois():
    ordered = DomainConfig(pois=CHAIN)
    with pytest.raises(ConfigError, match="D\\+\\+ is not defined for POIs with after, require"):
        CREDITS["D++"].check(ordered)
    CREDITS["D++"].check(DomainConfig(pois=[{"value": 1.0, "capture_radius": 2.0}]))
    with pytest.raises(ConfigError, match="feedback: D\\+\\+ is not defined"):
        RunConfig.from_toml('[learn]\nfeedback = "D++"\n[[pois]]\nscore_at = "final"')


def test_a_sweep_takes_pois_in_its_base_and_grids_n_req(tmp_path):
    from physrover.experiment.sweep import Sweep

    path = tmp_path / "s.toml"
    path.write_text('[sweep]\nname = "ruled"\nseeds = 1\n[grid]\nn_req = [1, 2]\n'
                    '[[base.pois]]\nvalue = 1.0\n[[base.pois]]\nvalue = 2.0\nafter = [0]\n'
                    "n_req = 1\n")  # fmt: skip
    sweep = Sweep.load(path)
    configs = [sweep.base.with_overrides({"n_req": n}) for n in (1, 2)]
    assert [c.domain.n_req_per_poi for c in configs] == [(1, 1), (2, 1)]
    assert configs[1].domain.pois[1].after == (0,)


def test_the_ccea_trains_on_ruled_pois_and_resumes_bit_identically(tmp_path):
    """A short run of the paper's method on ordered POIs: the metrics are the world's G
    (the rules' path, not the fused episode) and a resumed run equals an unbroken one."""
    from conftest import assert_same_run

    from physrover.experiment.training import train

    config = RunConfig.from_toml(LAB_TOML).with_overrides(
        {"n_rovers": 6, "population": 6, "method": "D", "checkpoint_every": 2}
    )
    full = train(config, tmp_path / "full", generations=5, progress=False)
    part = train(config, tmp_path / "part", generations=3, progress=False)
    train(None, part, resume=True, generations=5, progress=False)
    assert_same_run(full, part)
    assert "[[pois]]" in (full / "config.toml").read_text()


TYPED = """
[domain]
n_req = 1
[[agents]]
name = "rover"
count = 2
[[agents]]
name = "uav"
captures = false
[[pois]]
value = 3.0
require = { rover = 1, uav = 1 }
[[pois]]
value = 1.0
"""


def test_a_typed_poi_needs_each_class_it_names():
    pois = [(0.0, 0.0), (20.0, 0.0)]

    def typed(paths):
        domain = DomainConfig.from_toml(TYPED).replace(steps=max(len(paths) - 1, 1))
        world = RoverWorld(domain, 1)
        world.reset([np.random.default_rng(0)], StartOverrides(
            rover_positions=np.asarray(paths[0], dtype=float), rover_headings=np.zeros(3),
            poi_positions=np.asarray(pois)))  # fmt: skip
        score_paths(world, paths)
        return world

    # two rovers but no UAV, then the UAV alone: never both classes at one step
    world = typed([[(1, 0), (0, 1), FAR], [FAR, FAR, (1, 0)]])
    assert world.G[0] == 0.0
    # a rover and the UAV at step 1: captured; the UAV counts for this POI only
    world = typed([[FAR, FAR, FAR], [(1, 0), FAR, (0, 1)]])
    assert world.G[0] == 3.0 and world.D[0].tolist() == [3.0, 0.0, 3.0]
    assert world.state.in_range[1, 0, :, 0].tolist() == [True, False, True]
    # at the plain POI (n_req 1) the UAV is never in range: it does not capture
    world = typed([[FAR, FAR, (20, 0)]])
    assert world.G[0] == 0.0 and not world.state.in_range[0, 0, 2, 1]


@pytest.mark.parametrize(
    ("rule", "message"),
    [("require = { uvs = 1 }", "pois[0].require: unknown class 'uvs' (did you mean 'uav'?)"),
     ("require = { uav = 2 }", "pois[0].require.uav: must be in [1, 1] (the class's count)"),
     ("require = { uav = 0 }", "pois[0].require.uav: must be an integer >= 1, got 0"),
     ("require = { uav = 1 }\nn_req = 1", "pois[0].require: give n_req or require, not both")],
)  # fmt: skip
def test_bad_typed_couplings_name_the_field(rule, message):
    text = TYPED.replace("require = { rover = 1, uav = 1 }", rule)
    with pytest.raises(ConfigError) as info:
        DomainConfig.from_toml(text)
    assert message in str(info.value)
    assert DomainConfig.from_toml(DomainConfig.from_toml(TYPED).to_toml()).pois[0].require == {
        "rover": 1, "uav": 1}  # fmt: skip


def test_a_video_draws_a_sighted_pois_ring_at_its_sense_radius_and_labels_the_rule():
    from types import SimpleNamespace

    from physrover.viz.classes import poi_rule_label, ring_pixels

    pois = [{"capture_by": "sight", "sense_radius": 2.0}, {"capture_by": "sight"},
            {"capture_by": "radius-or-sight", "capture_radius": 1.5}, {}]  # fmt: skip
    domain = DomainConfig(pois=pois, agents=SIGHTED, n_req=1)
    tf = SimpleNamespace(scale=10.0)
    assert [ring_pixels(tf, domain, k) for k in range(4)] == [20, 1, 15, 40]  # d_cap 4
    assert [poi_rule_label(domain, k) for k in range(4)] == [
        "by sight", "by sight", "by radius-or-sight", ""]  # fmt: skip


def test_the_labs_quartz_fixture_scores_as_the_lab_recorded():
    """The lab's own fixture (``tests/data/lab-quartz``: AADILab/influence-shaping's
    ``test/resources/quartz``, its commit in ``expected.json``): a rover and a UAV, five
    hidden POIs valued by distance (coupling 1, capture and observation radius 1000,
    ``sequential``), the recorded 150-step path of evaluation team 6 of generation 0. The
    lab's ``fitness.csv`` gives the team 1.200821119854093 and the rover the same (its
    IndirectDifference: without the rover no POI is worth anything); physrover's G and the
    rover's D are that value (to the last bit where it was written; asserted to 1e-12, as
    the lab's ``np.linalg.norm`` and our square root may round apart)."""
    import json
    from pathlib import Path

    folder = Path(__file__).parent / "data" / "lab-quartz"
    meta = json.loads((folder / "expected.json").read_text())
    paths = np.loadtxt(folder / "joint_traj.csv", delimiter=",", skiprows=1).reshape(-1, 2, 2)
    poi = {"value": 1.0, "n_req": 1, "capture_radius": 1000.0, "sense_radius": 1000.0,
           "capture_by": "radius-or-sight", "value_by": "distance"}  # fmt: skip
    agents = [{"name": "rover", "count": 1, "sensor": {"kind": "lidar", "radius": 5.0}},
              {"name": "uav", "count": 1, "captures": False,
               "sensor": {"kind": "lidar", "radius": 1000.0}}]  # fmt: skip
    world = _scored([poi] * 5, paths, meta["poi_positions"], steps=len(paths) - 1,
                    agents=agents)  # fmt: skip
    expected = meta["expected_rewards"]["rover_0"]
    assert world.G[0] == pytest.approx(meta["team_fitness"], rel=1e-12)
    assert world.D[0, 0] == pytest.approx(expected, rel=1e-12)
    assert world.D[0, 1] == 0.0  # the UAV does not count (its ID credit is not yet here)


def test_pois_spawn_by_rules_of_their_own_each_team_from_its_generator():
    """``[[pois]] spawn``: a fixed POI where it is put, a box's uniform in its box, a
    circle's on its circle, the scenario's where the scenario puts it; team e's draws from
    its own generator, after the scenario's (which draws as without the rules)."""
    pois = [{"value": 1.0}, {"value": 2.0, "spawn": "fixed", "spawn_positions": [[3.0, -4.0]]},
            {"value": 3.0, "spawn": "box", "spawn_box": [5.0, 6.0, -2.0, 0.0]},
            {"value": 4.0, "spawn": "circle", "spawn_circle": [-7.0, 1.0, 2.5]}]  # fmt: skip
    ruled = DomainConfig(pois=pois, n_req=1)
    plain = DomainConfig(poi_values=(1.0, 2.0, 3.0, 4.0), n_req=1)
    worlds = [RoverWorld(ruled, 40), RoverWorld(plain, 40)]
    for world in worlds:
        world.reset([np.random.default_rng([9, e]) for e in range(40)])
    xy, ring = worlds[0].poi_positions, worlds[1].poi_positions
    np.testing.assert_array_equal(xy[:, 0], ring[:, 0])  # the scenario's, unchanged
    np.testing.assert_array_equal(worlds[0].rover_positions, worlds[1].rover_positions)
    assert (xy[:, 1] == [3.0, -4.0]).all()
    assert (
        (xy[:, 2, 0] >= 5) & (xy[:, 2, 0] <= 6) & (xy[:, 2, 1] >= -2) & (xy[:, 2, 1] <= 0)
    ).all()
    np.testing.assert_allclose(np.hypot(xy[:, 3, 0] + 7.0, xy[:, 3, 1] - 1.0), 2.5)
    assert np.ptp(xy[:, 2], axis=0).min() > 0.5 and np.ptp(xy[:, 3], axis=0).min() > 2.0
    alone = RoverWorld(ruled, 1)
    alone.reset([np.random.default_rng([9, 17])])
    np.testing.assert_array_equal(alone.poi_positions[0], xy[17])
    text = DomainConfig(pois=[{"value": 1.0}], n_req=1).to_toml()
    assert "\nspawn = " not in text and "spawn_box" not in text  # as before the rules existed


@pytest.mark.parametrize(
    ("table", "message"),
    [
        ({"spawn": "disc"}, "pois[0].spawn: "),
        ({"spawn": "fixed"}, "pois[0].spawn_positions: need one [x, y] per POI (1)"),
        ({"spawn": "box", "spawn_box": [1.0, 0.0, 0.0, 1.0]}, "pois[0].spawn_box: need"),
        ({"spawn": "circle", "spawn_circle": [0.0, 0.0]}, "pois[0].spawn_circle: need"),
    ],
)
def test_bad_poi_spawns_are_one_line_errors(table, message):
    with pytest.raises(ConfigError) as error:
        DomainConfig(pois=[{"value": 1.0, **table}], n_req=1)
    assert str(error.value).startswith(message) and "\n" not in str(error.value)
