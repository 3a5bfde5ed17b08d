"""A coupling curriculum: train at a looser coupling, tighten it as the champion succeeds.

Under tight coupling (the paper's n_req 5-6) D is 0 for every rover until a coupling forms,
so the CCEA and its critics learn from a signal that is almost always 0. With
``[learn] curriculum_start = c`` the training episodes are played at coupling ``c`` (each
POI's ``min(c, n_req_k)``), and after every generation whose champion team scores at least
``curriculum_threshold`` of the POIs' total value (its mean G over the evaluation episodes,
at the training coupling) ``curriculum_patience`` generations in a row, the coupling goes
up by one, until it is the domain's. The feedback (D, G, D++, ...) and the critics see the
training coupling; the learning curve (``eval_G``) is always at the domain's coupling.

The evaluation at the domain's coupling comes from the same episodes: the world records
which agents are in range of each POI at every scored step (``in_range``, Eq. 13), and
:func:`score_at_coupling` applies Eqs. 11-12 at another coupling to those records. This is
exactly the G of the same episode played at that coupling as long as nothing an agent
senses depends on captures, so the curriculum refuses POIs that vanish once captured and
POI rules (ordered, final, typed POIs), whose scoring is not a count (the config says so).

A gradient-based trainer (``method = "mappo"``...) follows the same rule the other way
round (:meth:`CouplingCurriculum.follow`, set up by
:meth:`~physrover.marl.common.Trainer.follow_curriculum`): its evaluation episodes are
played at the domain's coupling (the learning curve) and rescored at the training coupling
for the rule, after every logging point. An off-policy trainer's replay buffer (MADDPG's)
keeps transitions rewarded at the looser coupling until they are overwritten. A hybrid's
learner (:mod:`physrover.learn.hybrid`) trains at the domain's coupling whatever the
CCEA's curriculum does.
"""

from __future__ import annotations

import numpy as np

from physrover.domain.scoring.difference import team_score
from physrover.domain.scoring.influence import replay_captures
from physrover.domain.scoring.rules import PoiRules


def score_at_coupling(in_range: np.ndarray, poi_values: np.ndarray, n_req: np.ndarray,
                      last_step: int, rules) -> np.ndarray:  # fmt: skip
    """G (Eq. 11) of each team's episode at coupling ``n_req`` (K,) int, from the recorded
    in-range sets ``in_range`` (T + 1, E, R, K) bool (Eq. 13, the world's
    ``state.in_range``) of steps 0 .. ``last_step`` and the POI values (E, K): the captures
    replayed by the scoring's own kernel
    (:func:`~physrover.domain.scoring.influence.replay_captures`, Eq. 12 under ``rules``,
    the world's :class:`~physrover.domain.scoring.rules.PoiRules`), nobody left out, and
    :func:`~physrover.domain.scoring.difference.team_score`. Returns (E,) float64."""
    n_teams, n_agents, n_pois = in_range.shape[1:]
    removed = np.zeros((n_teams, 1, last_step + 1, n_agents), dtype=bool)
    captured = np.empty((n_teams, 1, n_pois), dtype=bool)
    replay_captures(in_range, removed, np.asarray(n_req, dtype=np.int64), rules, captured)
    return team_score(captured, poi_values)[:, 0]


def replay_rules(world) -> PoiRules:
    """The POI rules the captures of ``world`` (a :class:`~physrover.domain.world.RoverWorld`)
    are replayed under: its own, or for the paper's POIs (which have none) the rules that
    are the paper's."""
    return world.plan.step.rules or PoiRules.build(world.config, world.n_teams, always=True)


def recorded_G(world, n_req: np.ndarray, rows=slice(None), rules=None) -> np.ndarray:
    """(E',) G of the episodes ``rows`` that ``world`` played last, at coupling ``n_req``
    (K,) int: :func:`score_at_coupling` of its in-range records under ``rules``
    (:func:`replay_rules` of the world if not given; pass them to save building them)."""
    rules = replay_rules(world) if rules is None else rules
    return score_at_coupling(world.state.in_range[:, rows], world.state.poi_values[rows], n_req,
                             world.plan.step.t_final, rules)  # fmt: skip


class CouplingCurriculum:
    """The training coupling of a run and the rule that tightens it (module docstring).

    Args:
        target: (K,) int, the domain's coupling of each POI.
        start: the first training coupling (>= 1, below the largest target).
        threshold: the fraction of the POIs' total value the champion must score.
        patience: generations in a row it must score it before the coupling tightens.
    """

    def __init__(self, target: np.ndarray, start: int, threshold: float, patience: int):
        self.target = np.asarray(target, dtype=np.int64)
        self.threshold, self.patience = float(threshold), int(patience)
        self.coupling = int(start)
        self.streak = 0

    @classmethod
    def of(cls, config) -> CouplingCurriculum | None:
        """The curriculum of a :class:`~physrover.config.RunConfig` (``[learn]
        curriculum_start``, ``_threshold``, ``_patience``), or None without one."""
        learn = config.learn
        if not learn.curriculum_start:
            return None
        return cls(np.array(config.domain.n_req_per_poi), learn.curriculum_start,
                   learn.curriculum_threshold, learn.curriculum_patience)  # fmt: skip

    @property
    def n_req(self) -> np.ndarray:
        """(K,) int64: the coupling the training episodes are played at."""
        return np.minimum(self.target, self.coupling)

    @property
    def train_n_req(self) -> int:
        """The largest coupling any POI is trained at: a learner's ``train_n_req`` stat."""
        return int(self.n_req.max())

    @property
    def done(self) -> bool:
        """Whether the training coupling is the domain's."""
        return bool(np.array_equal(self.n_req, self.target))

    def observe(self, champion_G: float, total_value: float) -> bool:
        """The champion's mean G at the training coupling in a generation, and the POIs'
        total value; returns True if the coupling tightens for the next generation."""
        if self.done:
            return False
        self.streak = self.streak + 1 if champion_G >= self.threshold * total_value else 0
        if self.streak < self.patience:
            return False
        self.coupling += 1
        self.streak = 0
        return True

    def follow(self, played, trained, rules=None) -> None:
        """The rule for a learner that evaluates at the domain's coupling (a gradient-based
        trainer, :class:`~physrover.marl.common.Trainer`): the episodes world ``played``
        played last (the evaluation's, at the domain's coupling) rescored at the training
        coupling, the mean of their G observed; if the coupling tightens, world ``trained``
        plays the next training episodes at the new one. ``rules``: as :func:`recorded_G`."""
        G = recorded_G(played, self.n_req, rules=rules)
        if self.observe(float(G.mean()), float(played.state.poi_values.sum(axis=1).mean())):
            trained.set_coupling(self.n_req)

    def state(self) -> dict:
        return {"coupling": self.coupling, "streak": self.streak}

    def load(self, state: dict) -> None:
        self.coupling, self.streak = int(state["coupling"]), int(state["streak"])


__all__ = ["CouplingCurriculum", "recorded_G", "replay_rules", "score_at_coupling"]
