"""The credit seam: each rover's immediate feedback from an episode (paper Section 2.2).

A credit signal turns an episode that a :class:`~physrover.domain.world.RoverWorld` just
played into one number per rover of every team, the *immediate feedback* that the CCEA's
fitness methods use (``[learn] feedback``): the paper's is D (Eq. 1). Built in:

- ``"D"``: the difference evaluation ``D_i = G(z) - G(z_-i)`` with the null counterfactual
  (rover i's whole trajectory removed), from the world's running records;
- ``"G"``: the team score G for every rover of the team;
- ``"D++"``: D with counterfactual partners
  (:func:`physrover.domain.scoring.difference.d_plus_plus`), which credits a rover that
  would have completed a coupling with partners;
- ``"D-partial"``: D where the team captured, else each rover's difference to how near
  the team came to its couplings (an exploration credit, beyond the paper);
- ``"D-regret"``, ``"D++-regret"``: D (D++) less what the rover would have added had it
  stood, for one step, at the POI where it was needed most (beyond the paper;
  :func:`physrover.domain.scoring.difference.regret`);
- ``"proximity"``: MERL's dense per-step reward, each rover's nearness to the nearest
  POI not yet captured (:mod:`physrover.domain.scoring.proximity`; no coupling
  information, the signal of the hybrid's gradient learner, :mod:`physrover.learn.hybrid`);
- ``"ID"``, ``"ID-step"``, ``"ID-step-local"``, ``"ID-step-system"``,
  ``"ID-step-difference"``, ``"ID-step-all-or-nothing-lab"``, ``"ID-manual"``:
  IndirectDifference (:mod:`physrover.domain.scoring.influence`), which credits an agent
  (a UAV) with the captures of the agents it was near.

The gradient-based trainers and the PettingZoo env take the same names (``reward``):
:func:`step_rewards` gives the signal at an episode's last step ("G" stays the team's
increase of G at every step).

A new signal is a :class:`Credit` subclass (a ``__call__(world) -> (E, R)``) and one
:func:`register_credit` call, from any module; its name then works in TOML and
``--set feedback=NAME``. It reads the world after the episode: ``world.G`` (E,),
``world.D`` (E, R), ``world.state`` (a :class:`~physrover.domain.state.WorldState`: captures
per POI with and without each rover, who was in range of which POI at every step),
``world.position_history`` and the trajectories.
"""

from __future__ import annotations

import numpy as np

from physrover.config import check
from physrover.core.registry import CREDITS
from physrover.domain.scoring.difference import (
    d_plus_plus,
    partial_difference,
    regret,
    step_credits,
)
from physrover.domain.scoring.influence import (
    STEP_RULES,
    indirect_difference,
    manual_difference,
)
from physrover.domain.scoring.proximity import proximity_now, proximity_steps


class Credit:
    """An immediate feedback signal; see the module docstring."""

    per_step_defined = False
    """Whether :meth:`per_step` gives the signal at every step (a fitness critic's per-step
    targets, ``[learn] critic_target = "step"``)."""
    dense = False
    """Whether a per-step learner gets the signal at every step (:meth:`now`) rather than
    the episode's at its last step (:func:`step_rewards`)."""

    def __call__(self, world) -> np.ndarray:
        """(E, R) float64 feedback of each rover of each team for the episode ``world`` just
        played."""
        raise NotImplementedError

    def check(self, domain) -> None:
        """Raise :class:`~physrover.config.ConfigError` (field ``feedback``) if the signal is
        not defined for ``domain`` (a :class:`~physrover.config.DomainConfig`); a run's
        config calls it when it is built. Every domain, by default."""

    def per_step(self, world) -> np.ndarray:
        """(T + 1, E, R) float64: the signal of each step taken alone (row t: step t's
        record), for signals with ``per_step_defined``."""
        raise NotImplementedError(f"{type(self).__name__} has no per-step form")

    def now(self, world) -> np.ndarray:
        """(E, R) float64: the signal of the world's latest step, for ``dense`` signals
        (row ``world.t`` of :meth:`per_step`)."""
        raise NotImplementedError(f"{type(self).__name__} is not a dense signal")


def check_counted_pois(domain, signal: str) -> None:
    """ConfigError (field ``feedback``) unless every POI of ``domain`` is captured by a count
    of agents in range at any step: ``signal`` replays such counts."""
    ruled = any(p.scored_by_rule for p in domain.pois)
    check(not ruled, "feedback", f'{signal} is not defined for POIs with after, require, '
          'score_at = "final" or value_by = "distance" ([[pois]])')  # fmt: skip


class Difference(Credit):
    """D of Eq. 1, the paper's immediate feedback."""

    per_step_defined = True

    def __call__(self, world) -> np.ndarray:
        return world.D

    def per_step(self, world) -> np.ndarray:
        return step_credits(world.state, world.n_req, "D")


class TeamScore(Credit):
    """G (Eq. 11) for every rover of the team."""

    per_step_defined = True

    def __call__(self, world) -> np.ndarray:
        return np.repeat(world.G[:, None], world.n_rovers, axis=1)

    def per_step(self, world) -> np.ndarray:
        return step_credits(world.state, world.n_req, "G")


class DPlusPlus(Credit):
    """D++ (Rahmattalabi et al. 2016): :func:`physrover.domain.scoring.difference.d_plus_plus`."""

    per_step_defined = True

    def __call__(self, world) -> np.ndarray:
        return d_plus_plus(world.state, world.n_req)

    def per_step(self, world) -> np.ndarray:
        return step_credits(world.state, world.n_req, "D++")

    def check(self, domain) -> None:
        """D++'s partners complete couplings at any step: not defined for ordered (``after``),
        typed (``require``) or final-state POIs."""
        check_counted_pois(domain, "D++")


class PartialCoupling(Credit):
    """D where the team captured, else each rover's difference to the team's progress
    toward its couplings (:func:`physrover.domain.scoring.difference.partial_difference`)."""

    def __call__(self, world) -> np.ndarray:
        return partial_difference(world.state, world.n_req)

    def check(self, domain) -> None:
        """Progress toward a coupling is a count of rovers in range: not defined for
        ordered, typed or final-state POIs."""
        check_counted_pois(domain, "D-partial")


class Regret(Credit):
    """A credit ``base`` (D or D++) less each rover's regret for where it was
    (:func:`physrover.domain.scoring.difference.regret`); ``name``: the signal's own."""

    def __init__(self, base: Credit, name: str):
        self.base, self.name = base, name

    def __call__(self, world) -> np.ndarray:
        return self.base(world) - regret(world.state, world.n_req)

    def check(self, domain) -> None:
        """A relocated rover completes a coupling by count: not defined for ordered, typed
        or final-state POIs, nor for agents that never count toward one."""
        check_counted_pois(domain, self.name)
        check(all(a.captures for a in domain.agents), "feedback",
              f"{self.name} is not defined for agents that never capture ([[agents]] "
              "captures = false)")  # fmt: skip


class Proximity(Credit):
    """MERL's proximity reward (:mod:`physrover.domain.scoring.proximity`): each step,
    min(1, d_cap / distance to the nearest POI not yet captured); the episode's credit is
    its sum over steps 1..t. Dense: a per-step learner gets it at every step."""

    per_step_defined = True
    dense = True

    def __call__(self, world) -> np.ndarray:
        return proximity_steps(world)[1 : world.t + 1].sum(axis=0)

    def per_step(self, world) -> np.ndarray:
        return proximity_steps(world)

    def now(self, world) -> np.ndarray:
        return proximity_now(world)


class IndirectDifference(Credit):
    """IndirectDifference (:mod:`physrover.domain.scoring.influence`) over a ``timescale``:
    "trajectory" (``ID``) or "step" (``ID-step``), where ``rule`` (one of
    :data:`~physrover.domain.scoring.influence.STEP_RULES`) says who owns an influenced
    agent's step."""

    def __init__(self, timescale: str, rule: str = "all-or-nothing"):
        self.timescale, self.rule = timescale, rule

    def __call__(self, world) -> np.ndarray:
        return indirect_difference(world, self.timescale, self.rule)


class ManualIndirectDifference(Credit):
    """The lab's IndirectDifference with ``assignment = manual``
    (:func:`physrover.domain.scoring.influence.manual_difference`): G minus G without the
    agents a class lists in ``manual_removal``."""

    def __call__(self, world) -> np.ndarray:
        return manual_difference(world)


class ByClass(Credit):
    """The run's signal ``name`` for every agent but those of a class (``[[agents]]``) that
    names its own ``feedback`` (the lab's per-agent ``reward_type``), each plus G where its
    class sets ``feedback_plus_G`` (the lab's ``add_G``). Each signal is computed once per
    episode for the whole team and its class's columns taken."""

    def __init__(self, name: str, domain):
        self.name = name
        self.groups = []  # (signal, agent indices, plus G) per class that differs
        start = 0
        for c in domain.agents:
            agents = np.arange(start, start + c.count)
            start += c.count
            if c.feedback not in ("", name) or c.feedback_plus_G:
                self.groups.append((c.feedback or name, agents, c.feedback_plus_G))
        self.names = {name} | {signal for signal, _, _ in self.groups}
        self.per_step_defined = not any(plus for _, _, plus in self.groups) and all(
            CREDITS[n].per_step_defined for n in self.names
        )

    def _compose(self, values) -> np.ndarray:
        out = np.array(values(self.name), dtype=np.float64)
        for signal, agents, plus in self.groups:
            if signal != self.name:
                out[..., agents] = values(signal)[..., agents]
            if plus:
                out[..., agents] += values("G")[..., agents]
        return out

    def __call__(self, world) -> np.ndarray:
        cache = {}
        return self._compose(lambda n: cache.setdefault(n, CREDITS[n](world)))

    def per_step(self, world) -> np.ndarray:
        cache = {}
        return self._compose(lambda n: cache.setdefault(n, CREDITS[n].per_step(world)))

    def check(self, domain) -> None:
        for n in sorted(self.names):
            CREDITS[n].check(domain)


def team_credit(name: str, domain) -> Credit:
    """The credit of a team of ``domain`` (a :class:`~physrover.config.DomainConfig`) under
    the run's signal ``name``: the registered signal, or :class:`ByClass` where an agent
    class names its own ``feedback`` or ``feedback_plus_G``."""
    if not any(c.feedback not in ("", name) or c.feedback_plus_G for c in domain.agents):
        return CREDITS[name]
    return ByClass(name, domain)


def step_rewards(name: str, world, last_step: bool, team_reward: np.ndarray) -> np.ndarray:
    """Each rover's reward of one step for a per-step learner (MAPPO, MADDPG, the PettingZoo
    env) under the credit signal ``name``: "G" is the team's increase of G at every step
    (``team_reward`` (E,), the env's reward: each rover's rewards sum to G, a dense
    signal); a dense signal (``Credit.dense``: "proximity") is its value at this step;
    any other registered signal (:data:`~physrover.core.registry.CREDITS`: D, D++, ID, a
    user's) is the signal of the episode ``world`` just played, at its last step
    (``last_step``), and 0 before, so each rover's rewards sum to it. Returns (E, R)."""
    if name == "G":
        return np.repeat(np.asarray(team_reward, dtype=np.float64)[:, None], world.n_rovers,
                         axis=1)  # fmt: skip
    credit = team_credit(name, world.config)
    if credit.dense:
        return np.asarray(credit.now(world), dtype=np.float64)
    if not last_step:
        return np.zeros((world.n_teams, world.n_rovers))
    return np.asarray(credit(world), dtype=np.float64)


def register_credit(name: str, credit: Credit, *, replace: bool = False) -> Credit:
    """Make ``credit`` the signal named ``name`` (``[learn] feedback = "NAME"``)."""
    if not isinstance(credit, Credit):
        raise TypeError(f"a credit signal must be a Credit instance, got {type(credit).__name__}")
    return CREDITS.register(name, credit, replace=replace)


register_credit("D", Difference())
register_credit("G", TeamScore())
register_credit("D++", DPlusPlus())
register_credit("D-partial", PartialCoupling())
register_credit("D-regret", Regret(Difference(), "D-regret"))
register_credit("D++-regret", Regret(DPlusPlus(), "D++-regret"))
register_credit("proximity", Proximity())
register_credit("ID", IndirectDifference("trajectory"))
register_credit("ID-step", IndirectDifference("step"))
for _rule in STEP_RULES[1:]:
    register_credit(f"ID-step-{_rule}", IndirectDifference("step", _rule))
register_credit("ID-manual", ManualIndirectDifference())
