"""``physrover import-lab``: the lab's shipped example config as physrover TOML, and the
lab configs physrover refuses, each in one line naming the lab's key (issue 43)."""

import copy
from pathlib import Path

import pytest
import yaml

from physrover.cli.main import main
from physrover.config import ConfigError, RunConfig
from physrover.config.lab import lab_domain
from physrover.config.lab_run import lab_run

EXAMPLE = Path(__file__).parent / "data" / "lab-example" / "config.yaml"


def test_the_labs_example_config_becomes_a_run_that_says_what_differs(tmp_path, capsys):
    out = tmp_path / "run.toml"
    assert main(["import-lab", str(EXAMPLE), "-o", str(out)]) == 0
    err = capsys.readouterr().err
    assert "hidden layer" not in err  # the lab's network: tanh, U(-1, 1), as the lab's
    assert "note: 50 trials: one run per seed" in err
    text = out.read_text()
    assert text.startswith("# config.yaml, a config of the paper's lab")
    assert "# - scored states: the T + 1 positions here" in text
    run = RunConfig.load(out)
    assert run == lab_run(yaml.safe_load(EXAMPLE.read_text()))[0]  # the file is the run
    learn, domain = run.learn, run.domain
    # ccea: 50 policies, one hidden layer of 15, Gaussian mutation p 0.5 sd 0.1, softmax
    # teams, 10 individual and 10 team elites, 2000 generations of 50 steps, one rollout
    assert (learn.population, learn.hidden, learn.generations, domain.steps) == (50, 15, 2000, 50)
    assert (learn.activation, learn.weight_init) == ("tanh", "uniform")
    assert (learn.mutation, learn.mutation_rate, learn.mutation_scale) == ("gauss", 0.5, 0.1)
    assert (learn.team_formation, learn.selection) == ("softmax", "elites")
    assert (learn.n_individual_elites, learn.n_team_elites, learn.method) == (10, 10, "D")
    # env: the hidden POI on a random circle of radius 10 around (25, 25): the origin here
    assert domain.scenario.kind == "ring-random" and domain.scenario.poi_ring_radius == 10.0
    assert domain.scenario.redraw == "generation"
    rover, uav = domain.agents
    assert rover.spawn_positions == ((0.0, 0.0),) and rover.bounds == (-25.0, 25.0, -25.0, 25.0)
    assert (rover.feedback, uav.feedback) == ("ID-step", "ID-step")  # AllOrNothing, timestep
    assert (rover.captures, uav.captures, uav.influence_radius) == (True, False, 5.0)
    # one_minus_inverse_distance_over_observation_radius, sum, 90 degree sectors, default 0
    assert (rover.sensor.measure, rover.sensor.compose, rover.sensor.sectors) == (
        "linear", "density", 4)  # fmt: skip
    assert (rover.sensor.radius, uav.sensor.radius, rover.sensor.empty) == (5.0, 25.0, 0.0)
    (poi,) = domain.pois
    assert (poi.capture_by, poi.capture_radius, poi.value_by) == ("radius-or-sight", 5.0,
                                                                 "distance")  # fmt: skip
    assert poi.visible_to == ("uav",) and poi.score_at == "any"  # hidden, sequential
    # its rovers sense by RoverLidar: the lab's disappear_bool does nothing there
    assert poi.disappear == "never"


def _example() -> dict:
    return yaml.safe_load(EXAMPLE.read_text())


def _with(path: str, value) -> dict:
    """The example config with the key at dotted ``path`` (``[i]`` for list items) set."""
    lab = copy.deepcopy(_example())
    *parents, last = path.replace("[", ".").replace("]", "").split(".")
    node = lab
    for key in parents:
        node = node[int(key)] if key.isdigit() else node[key]
    node[int(last) if last.isdigit() else last] = value
    return lab


def test_poi_subtypes_are_sensed_by_the_uavs_that_observe_them():
    """The lab's SmartLidar: a hidden POI with a subtype is sensed only by the UAVs whose
    observable_subtypes list it; a rover POI's subtype is never read. Two UAVs observing
    different subtypes become two classes, each POI visible to its own."""
    lab = copy.deepcopy(_example())
    uav = lab["env"]["agents"]["uavs"][0]
    lab["env"]["agents"]["uavs"] = [dict(uav, observable_subtypes=["red"]),
                                    dict(uav, observable_subtypes=["blue", "green"])]  # fmt: skip
    hidden = lab["env"]["pois"]["hidden_pois"][0]
    lab["env"]["pois"]["hidden_pois"] = [dict(hidden, subtype="red"),
                                         dict(hidden, subtype="green"), dict(hidden)]  # fmt: skip
    lab["env"]["pois"]["rover_pois"] = [dict(hidden, subtype="red")]
    domain = lab_domain(lab)
    assert [c.name for c in domain.agents] == ["rover", "uav_1", "uav_2"]
    seen = [set(p.visible_to) for p in domain.pois]
    # the rover POI by both UAVs, its subtype unread (the rover's RoverLidar senses no
    # POI), then the hidden ones: red by uav_1, green by uav_2, no subtype by both UAVs
    assert seen == [{"uav_1", "uav_2"}, {"uav_1"}, {"uav_2"}, {"uav_1", "uav_2"}]
    lab["env"]["pois"]["hidden_pois"][0]["subtype"] = "violet"
    with pytest.raises(ConfigError, match=r"hidden_pois\[0\]\.subtype: no UAV observes 'violet'"):
        lab_domain(lab)


def test_pois_that_spawn_by_rules_of_their_own_take_them_as_pois_spawn():
    """The lab's per-POI spawn rules (a box of its own, here, where the example's POI is on
    a circle): the POI's table takes the rule, the scenario places it explicitly, and every
    reset draws it in its box, the same draw for the teams of a generation."""
    import numpy as np

    from physrover.domain.world import RoverWorld

    box = {"low_x": 10.0, "high_x": 14.0, "low_y": 30.0, "high_y": 31.0}
    lab = _with("env.pois.hidden_pois[0].position",
                {"spawn_rule": "random_uniform", "random_uniform": box})  # fmt: skip
    domain = lab_domain(lab)
    (poi,) = domain.pois
    assert (poi.spawn, poi.spawn_box) == ("box", (10.0, 14.0, 30.0, 31.0))
    assert domain.scenario.kind == "explicit" and domain.scenario.redraw == "generation"
    world = RoverWorld(domain, 3)
    seen = []
    for seed in range(20):
        world.reset([np.random.default_rng([seed, e]) for e in range(3)])
        xy = world.poi_positions[:, 0]
        assert (xy == xy[0]).all()  # one draw per generation
        assert 10 <= xy[0, 0] <= 14 and 30 <= xy[0, 1] <= 31
        seen.append(xy[0].copy())
    assert np.ptp(np.array(seen), axis=0).min() > 0.5  # drawn afresh each time


@pytest.mark.parametrize(("path", "value", "message"), [
    ("env.agents.rovers[0].action", {"type": "teleport"},
     "env.agents.rovers[0].action.type: dxdy or pick_uav, got 'teleport'"),
    ("env.agents.rovers[0].policy", {"type": "follow"},
     "env.agents.rovers[0].policy.type: network, or follow with pick_uav, got 'follow' with"),
    ("env.agents.uavs[0].sensor", {"type": "Camera"},
     "env.agents.uavs[0].sensor.type: SmartLidar, RoverLidar or UavDistanceLidar, got"),
    ("env.agents.rovers[0].reward_type", "Shaped",
     "env.agents.rovers[0].reward_type: unknown 'Shaped'"),
    ("env.agents.rovers[0].resolution", 70, "env.agents.rovers[0].resolution: must divide 360"),
    ("env.pois.hidden_pois[0].constraint", "eventually",
     "env.pois.hidden_pois[0].constraint: final or sequential, got 'eventually'"),
    ("ccea.network.hidden_layers", [15, 15],
     "ccea.network.hidden_layers: physrover's policies have one hidden layer"),
    ("ccea.team_formation", {"type": "greedy_teams"},
     "ccea.team_formation.type: random_teams, softmax_teams or fixed_teams, got"),
    ("ccea.evaluation.multi_rollout.num_rollouts", 0,
     "ccea.evaluation.multi_rollout.num_rollouts: must be >= 1, got 0"),
])  # fmt: skip
def test_what_physrover_cannot_express_is_refused_in_one_line(path, value, message, tmp_path,
                                                               capsys):  # fmt: skip
    with pytest.raises(ConfigError) as error:
        lab_run(_with(path, value))
    assert str(error.value).startswith(message)
    config = tmp_path / "lab.yaml"
    config.write_text(yaml.safe_dump(_with(path, value)))
    assert main(["import-lab", str(config)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"physrover: error: {message}")


def test_the_labs_first_uav_speed_is_noted_where_it_differs():
    notes = lab_run(_with("ccea.network.uav_max_velocity", 2.0))[1]
    assert any("first UAV at rover_max_velocity (1.0)" in note for note in notes)
    assert not any("first UAV" in note for note in lab_run(_example())[1])


def test_elites_by_team_fitness_map_to_their_field():
    lab = _with("ccea.selection.n_elites_binary_tournament."
                "n_individual_elites_based_on_team_fitness", 5)  # fmt: skip
    assert lab_run(lab)[0].learn.n_team_fitness_elites == 5
    assert lab_run(_example())[0].learn.n_team_fitness_elites == 0


def test_files_that_are_not_lab_configs_say_so(tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    bad.write_text("env: [unclosed")
    assert main(["import-lab", str(bad)]) == 2
    assert "bad.yaml: not YAML" in capsys.readouterr().err
    bad.write_text("- a list\n")
    assert main(["import-lab", str(bad)]) == 2
    assert "not a lab config" in capsys.readouterr().err
    with pytest.raises(ConfigError, match="env: missing: not a lab config"):
        lab_domain({"ccea": {}}, steps=5)


def test_rovers_that_pick_or_follow_a_uav_by_its_distance():
    lab = _example()
    rover = lab["env"]["agents"]["rovers"][0]
    rover.update(action={"type": "pick_uav"}, sensor={"type": "UavDistanceLidar"})
    rover = lab_run(lab)[0].domain.agents[0]
    assert (rover.action, rover.picks, rover.sensor.kind) == ("pick", ("uav",), "distances")
    assert (rover.sensor.classes, rover.sensor.radius) == (("uav",), 5.0)
    lab["env"]["agents"]["rovers"][0]["policy"] = {"type": "follow"}
    assert lab_run(lab)[0].domain.agents[0].action == "follow"


def test_a_rover_class_splits_where_its_agents_differ_but_not_for_a_spawn():
    lab = _example()
    second = copy.deepcopy(lab["env"]["agents"]["rovers"][0])
    second["position"]["fixed"] = [30.0, 25.0]
    lab["env"]["agents"]["rovers"].append(second)
    domain = lab_domain(lab)
    assert [a.name for a in domain.agents] == ["rover", "uav"]  # one class, two spawns
    assert domain.agents[0].spawn_positions == ((0.0, 0.0), (5.0, 0.0))
    third = copy.deepcopy(second)
    third["reward_type"] = "Difference"
    lab["env"]["agents"]["rovers"].append(third)
    domain = lab_domain(lab)
    assert [(a.name, a.count, a.feedback) for a in domain.agents] == [
        ("rover_1", 2, "ID-step"), ("rover_2", 1, "D"), ("uav", 1, "ID-step")]  # fmt: skip
    assert domain.agents[0].moves_with == ()  # needs_uav_to_move is false in the example


def test_a_hidden_poi_nobody_senses_is_noted_not_refused():
    """The lab scores a hidden POI no agent senses (no UAVs, rovers on RoverLidar);
    physrover cannot hide a POI from every class, so every agent senses it, with a note."""
    lab = _example()
    lab["env"]["agents"]["uavs"] = []
    run, notes = lab_run(lab)
    assert [a.name for a in run.domain.agents] == ["rover"] and run.domain.pois[0].visible_to == ()
    assert any(note.startswith("hidden POIs but no UAV that senses them") for note in notes)
