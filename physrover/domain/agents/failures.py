"""Agents that fail mid-episode (``[failures]``, :mod:`physrover.config.failures`).

Each team's agents carry the step they fail at, ``at`` (E, R) int64 (:data:`NEVER` for an
agent that does not fail), drawn at every reset (:func:`draw_failures`). Agent i of team e
is *alive* at state t while ``t < at[e, i]``; the compiled step (:mod:`physrover.domain.step`)
reads it in three places, all compiled away when no agent can fail (the plan's
``failures`` is None):

- the move into state t (:func:`~physrover.domain.motion.ideal.move_team`): an agent not
  alive at t does not move, its command recorded as 0 (a motion model stepped from Python
  gets a 0 command, :func:`halt_commands`: the physical rover brakes to rest under its
  finite force, a body still);
- the score of state t (:func:`~physrover.domain.scoring.captures.score_team`): an agent
  not alive is in range of no POI (Eq. 13), so it helps no capture, and D's counterfactual
  without it (Eq. 1) differs from G only through the captures it helped while alive;
- the observation of state t (:func:`silence`): 0.

Its body stays where it stopped, and its teammates' sensors still see it there.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import types
from numba.extending import overload

NEVER = np.iinfo(np.int64).max
"""The failure step of an agent that does not fail."""


class Failures(NamedTuple):
    """The plan's part for failing agents: when each agent of each team fails."""

    at: np.ndarray
    """(E, R) int64: the step each agent fails at in this episode (:data:`NEVER`: it does not)."""

    @classmethod
    def build(cls, config, n_teams: int) -> Failures | None:
        """The part for ``n_teams`` teams of ``config``, None if no agent can fail."""
        if not config.failures.on:
            return None
        return cls(np.full((n_teams, config.n_rovers), NEVER, dtype=np.int64))


def draw_failures(config, rngs) -> np.ndarray:
    """(len(rngs), R) int64: the failure steps of one episode of each team, team e's drawn
    from ``rngs[e]`` (after its start state; nothing is drawn unless ``n_failing > 0``):
    the ``given`` agents at their steps, then ``n_failing`` of the others, uniformly without
    replacement, each at a step drawn uniformly from ``between`` (default 0 .. ``steps``)."""
    f = config.failures
    at = np.full((len(rngs), config.n_rovers), NEVER, dtype=np.int64)
    for agent, step in f.given:
        at[:, agent] = step
    if f.n_failing:
        first, last = f.between or (0, config.steps)
        pool = np.setdiff1d(np.arange(config.n_rovers), [a for a, _ in f.given])
        for e, rng in enumerate(rngs):
            agents = rng.choice(pool, size=f.n_failing, replace=False)
            at[e, agents] = rng.integers(first, last + 1, size=f.n_failing)
    return at


def alive_at(at: np.ndarray, t) -> np.ndarray:
    """(E, R) bool: which agents are alive at state ``t`` (an int, or (E,) ints: each team's
    own step), from the failure steps ``at`` (E, R)."""
    return np.asarray(t).reshape(-1, 1) < at


def alive_through(at: np.ndarray, n_states: int) -> np.ndarray:
    """(n_states, E, R) bool: :func:`alive_at` at each of states 0 .. n_states - 1."""
    return np.arange(n_states)[:, None, None] < at[None]


def halt_commands(commands: np.ndarray, record: np.ndarray, at: np.ndarray, t, teams=None):
    """Zero the (E, R, 2) ``commands`` (and their ``record``) of the agents not alive at the
    state ``t`` they move into (an int or (E,) ints), of the ``teams`` mask if given: what
    a motion model stepped from Python receives for them."""
    dead = ~alive_at(at, t)
    if teams is not None:
        dead &= teams[:, None]
    commands[dead] = 0.0
    record[dead] = 0.0


def alive(failures, e, t, i):
    """Whether agent i of team e is alive at state t, for compiled kernels: ``failures`` a
    :class:`Failures` or None (no agent can fail: compiled to True)."""
    return failures is None or t < failures.at[e, i]


def silence(failures, e, t, obs):
    """Zero the observations ``obs[e]`` (E, R, n_obs) of team e's agents not alive at t."""
    for i in range(obs.shape[1]):
        if not alive(failures, e, t, i):
            obs[e, i, :] = 0.0


@overload(alive, inline="always")
def _alive_compiled(failures, e, t, i):
    if isinstance(failures, types.NoneType):
        return lambda failures, e, t, i: True
    return lambda failures, e, t, i: t < failures.at[e, i]


@overload(silence, inline="always")
def _silence_compiled(failures, e, t, obs):
    if isinstance(failures, types.NoneType):
        return lambda failures, e, t, obs: None

    def zero(failures, e, t, obs):
        for i in range(obs.shape[1]):
            if not alive(failures, e, t, i):
                for j in range(obs.shape[2]):
                    obs[e, i, j] = 0.0

    return zero


__all__ = ["NEVER", "Failures", "alive", "alive_at", "alive_through", "draw_failures",
           "halt_commands", "silence"]  # fmt: skip
