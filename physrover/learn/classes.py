"""Policies of a team of agent classes (``[[agents]]``, :mod:`physrover.config.agents`).

Every agent keeps its own population, as in the paper; an agent's policies have its
class's shape, ``n_in_c -> hidden -> 2`` with ``n_in_c`` its class's sensor size (``U +
1`` outputs for a picking class:
:func:`~physrover.domain.agents.classes.pick_count`)
(:class:`~physrover.learn.policies.PolicyLayout`). The populations stay one (R, k, P)
array, P the largest class's genome, a smaller class's genomes in the first P_c entries
(the rest are never read: evolution mutates them, harmlessly). The world's observations
are (E, R, D) with D the widest class's, a class's in its first ``n_in_c`` columns and 0
after; a class's policies read their columns, and a fitness critic of an agent sees its
class's observations, zero-padded (a weight on a padded input never moves: the input is
always 0).

A team whose classes all steer (none picks) plays as one
:class:`~physrover.learn.rollout.TeamPolicy` of ``D -> hidden -> 2`` networks, each
class's genomes re-laid with zero input weights on the columns past its own
(:meth:`ClassLayouts.padded`), so a learner's whole episode is one compiled call, as the
paper's. Bit for bit what the class's own network gives: each hidden unit adds ``b1`` and
then its inputs in order (:func:`~physrover.learn.forward.forward_team`), and the padded
terms come last and are ``0 * 0 = +0``, which leaves every sum as it was (a sum of ``-0``
would become ``+0``, which nothing downstream tells apart).

:func:`team_layout` gives a domain's layout: the paper's single
:class:`~physrover.learn.policies.PolicyLayout` without classes (the same code as
before), a :class:`ClassLayouts` with them.
"""

from __future__ import annotations

import numpy as np

from physrover.domain.agents.classes import class_rows, pick_count
from physrover.domain.sensing.sensor import sensor_size
from physrover.learn.policies import PolicyLayout
from physrover.learn.rollout import TeamPolicy


class ClassLayouts:
    """The policy layouts of a team's classes, with PolicyLayout's ``init``, ``prepare``
    and ``act`` over the padded (R, k, P) genomes (module docstring)."""

    def __init__(self, hidden: int, domain, *network: str):
        self.rows = class_rows(domain)
        dims = [sensor_size(c.sensor or domain.sensor, domain) for c in domain.agents]
        outs = [pick_count(domain, c) + 1 if a.action == "pick" else 2
                for c, a in enumerate(domain.agents)]  # fmt: skip
        self.layouts = [PolicyLayout(hidden, d, n, *network)
                        for d, n in zip(dims, outs, strict=True)]  # fmt: skip
        self.hidden = hidden
        self.n_in = max(dims)
        self.size = max(layout.size for layout in self.layouts)
        self.picks = any(layout.n_out != 2 for layout in self.layouts)
        self.tanh_hidden = self.layouts[0].activation == "tanh"

    def init(self, shape: tuple[int, int], rng: np.random.Generator) -> np.ndarray:
        """(R, k, P) genomes: each class's initialised as PolicyLayout does, class by
        class in ``[[agents]]`` order from ``rng``; padding 0."""
        n_agents, k = shape
        out = np.zeros((n_agents, k, self.size), dtype=np.float32)
        for rows, layout in zip(self.rows, self.layouts, strict=True):
            out[rows, :, : layout.size] = layout.init((rows.stop - rows.start, k), rng)
        return out

    def prepare(self, genomes: np.ndarray) -> TeamPolicy | MixedTeamPolicy:
        """The policy ``obs (E, R, n_in) -> actions (E, R, 2)`` of fixed (E, R, P) genomes:
        one :class:`~physrover.learn.rollout.TeamPolicy` of the :meth:`padded` genomes
        unless a class picks (module docstring)."""
        genomes = np.asarray(genomes)
        if genomes.shape[-1] != self.size:
            raise ValueError(f"genomes must have {self.size} parameters, got {genomes.shape[-1]}")
        if self.picks:
            return MixedTeamPolicy(genomes, self)
        return TeamPolicy(self.padded(genomes), self.hidden, self.n_in, self.tanh_hidden)

    def padded(self, genomes: np.ndarray) -> np.ndarray:
        """(E, R, P_D) float32 genomes of ``D -> hidden -> 2`` networks (D = ``n_in``, the
        widest class's) from (E, R, P) class genomes: a class's ``W1 (n_in_c x H)`` in the
        first rows of ``W1 (D x H)``, zero rows after, then its ``b1 | W2 | b2``."""
        if all(layout.n_in == self.n_in for layout in self.layouts):  # already laid out
            return np.asarray(genomes, dtype=np.float32)  # (not a copy if float32 already)
        H = self.hidden
        rest = H + 2 * H + 2  # b1 | W2 | b2
        out = np.zeros((*genomes.shape[:2], self.n_in * H + rest), dtype=np.float32)
        for rows, layout in zip(self.rows, self.layouts, strict=True):
            w1 = layout.n_in * H
            out[:, rows, :w1] = genomes[:, rows, :w1]
            out[:, rows, self.n_in * H :] = genomes[:, rows, w1 : w1 + rest]
        return out

    def act(self, genomes: np.ndarray, obs: np.ndarray) -> np.ndarray:
        """(E, R, 2) actions of (E, R, P) genomes on (E, R, n_in) observations."""
        return self.prepare(genomes)(obs)


class MixedTeamPolicy:
    """Each class's policies on its agents' rows and its observation columns."""

    def __init__(self, genomes: np.ndarray, layouts: ClassLayouts):
        pairs = zip(layouts.rows, layouts.layouts, strict=True)
        self.parts = [(rows, layout.n_in, layout.prepare(genomes[:, rows, : layout.size]))
                      for rows, layout in pairs]  # fmt: skip
        self.shape = genomes.shape[:2]

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        out = np.empty((*self.shape, 2), dtype=np.float32)
        for rows, n_in, policy in self.parts:
            out[:, rows] = policy(obs[:, rows, :n_in])
        return out


def team_layout(learn, domain) -> PolicyLayout | ClassLayouts:
    """The policies' layout of ``domain``'s team (module docstring), of the network
    ``learn`` (a :class:`~physrover.config.LearnConfig`) says: ``hidden``, ``activation``,
    ``weight_init``."""
    network = (learn.activation, learn.weight_init)
    if not domain.agents:
        return PolicyLayout(learn.hidden, sensor_size(domain.sensor, domain), 2, *network)
    return ClassLayouts(learn.hidden, domain, *network)


__all__ = ["ClassLayouts", "MixedTeamPolicy", "team_layout"]
