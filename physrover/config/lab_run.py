"""A whole lab config (``env`` and ``ccea``) as a physrover run: :func:`lab_run`, on
:func:`physrover.config.lab.lab_domain` (its module docstring gives the conventions), with
notes on what physrover runs otherwise.
"""

from __future__ import annotations

from typing import Any

from physrover.config.base import ConfigError
from physrover.config.lab import get, lab_domain
from physrover.config.learn import LearnConfig
from physrover.config.run import RunConfig


def _learn(ccea: dict, notes: list[str]) -> dict[str, Any]:
    """The ``[learn]`` table of a lab config's ``ccea`` section, appending to ``notes`` what
    physrover does otherwise (module docstring of :func:`lab_run`)."""
    hidden = get(get(ccea, "network", "ccea"), "hidden_layers", "ccea.network")
    hidden = [hidden] if isinstance(hidden, int) else list(hidden)
    if len(hidden) != 1:
        raise ConfigError("ccea.network.hidden_layers", f"physrover's policies have one hidden "
                          f"layer, got {hidden}")  # fmt: skip
    mutation = get(ccea, "mutation", "ccea")
    if float(mutation.get("mean", 0.0)) != 0.0:
        raise ConfigError("ccea.mutation.mean", f"physrover's noise has mean 0, got "
                          f"{mutation['mean']}")  # fmt: skip
    selection = get(get(ccea, "selection", "ccea"), "n_elites_binary_tournament",
                     "ccea.selection")  # fmt: skip
    formation = (ccea.get("team_formation") or {}).get("type", "random_teams")
    formations = {"random_teams": "random", "softmax_teams": "softmax", "fixed_teams": "rank"}
    if formation not in formations:
        raise ConfigError("ccea.team_formation.type", f"random_teams, softmax_teams or "
                          f"fixed_teams, got {formation!r}")  # fmt: skip
    rollouts = int(ccea.get("evaluation", {}).get("multi_rollout", {}).get("num_rollouts", 1))
    if rollouts < 1:
        raise ConfigError("ccea.evaluation.multi_rollout.num_rollouts", f"must be >= 1, got "
                          f"{rollouts}")  # fmt: skip
    return {"method": "D", "generations": int(get(ccea, "num_generations", "ccea")),
            "population": int(get(get(ccea, "populations", "ccea"), "agent_population_size",
                                   "ccea.populations")),
            "hidden": int(hidden[0]), "activation": "tanh", "weight_init": "uniform",
            "mutation": "gauss",
            "mutation_rate": float(get(mutation, "independent_probability", "ccea.mutation")),
            "mutation_scale": float(get(mutation, "std_deviation", "ccea.mutation")),
            "team_formation": formations[formation], "softmax_temperature": 1.0,
            "selection": "elites",
            "n_individual_elites": int(get(selection, "n_individual_elites", "ccea.selection")),
            "n_team_elites": int(get(selection, "n_team_elites", "ccea.selection")),
            "n_team_fitness_elites": int(selection.get(
                "n_individual_elites_based_on_team_fitness", 0)),
            "rollouts": rollouts,
            "eval_episodes": rollouts,  # the lab's test team on num_rollouts fresh seeds
            "eval_team": "champion" if ccea.get("evaluation", {}).get(
                "test_adhoc_team_switch", False) else "best-team"}  # fmt: skip


def lab_run(lab: dict) -> tuple[RunConfig, list[str]]:
    """The :class:`~physrover.config.RunConfig` of a whole lab config (``env`` and
    ``ccea``), and notes on what physrover does otherwise. The CCEA: ``[learn] method =
    "D"`` (a policy's fitness is its feedback, the mean over the lab's ``num_rollouts``
    episodes on starts shared by every team: ``rollouts``), each
    class's own feedback, Gaussian mutation, the lab's elites selection and team elites,
    random, softmax (temperature 1) or ranked (``fixed_teams``) teams, its test team (the
    best team by G, or with ``test_adhoc_team_switch`` the champion: ``eval_team``) on
    ``num_rollouts`` fresh episodes; ``num_trials`` trials are seeds (``physrover sweep``).
    Refused: more hidden layers, a mutation mean."""
    notes: list[str] = []
    domain = lab_domain(lab)
    learn = _learn(lab["ccea"], notes)
    learn["feedback"] = domain.agents[0].feedback or "D"
    seed = (lab.get("debug", {}).get("random_seed") or {}).get("set_seed")
    if seed is not None:
        learn["seed"] = int(seed)
    notes.append("scored states: the T + 1 positions here; the lab's training paths hold 3 "
                 "a step (raw, clamped to the agent's box, to the map)")  # fmt: skip
    radii = [a.sensor.radius for a in domain.agents]
    if any(p.sense_radius < max(radii) for p in domain.pois):
        notes.append("a POI's observation radius also limits who senses it here (the lab: "
                     "only who captures it by sight)")  # fmt: skip
    if lab["env"]["pois"].get("hidden_pois") and not any(
        not a.captures and a.sensor.kind == "lidar" for a in domain.agents
    ):
        notes.append("hidden POIs but no UAV that senses them: every agent senses them here "
                     "(physrover cannot hide a POI from all)")  # fmt: skip
    network = lab["ccea"].get("network", {})
    rover_v, uav_v = network.get("rover_max_velocity"), network.get("uav_max_velocity")
    if rover_v != uav_v and any(not a.captures and a.action == "world" for a in domain.agents):
        notes.append(f"the lab moves its first UAV at rover_max_velocity ({rover_v}) under dxdy "
                     f"(ccea_lib.py: ind <= num_rovers); here every UAV at {uav_v}")  # fmt: skip
    trials = lab.get("experiment", {}).get("num_trials")
    if trials:
        notes.append(f"{trials} trials: one run per seed, e.g. physrover sweep with seeds = "
                     f"{trials}")  # fmt: skip
    return RunConfig(domain, LearnConfig.from_dict(learn)), notes


__all__ = ["lab_run"]
