"""The step, composed once: check and clip, move, sense, score, record.

:func:`step_team` is the one composition of a team's step from the parts a world's plan
(:class:`~physrover.domain.plan.StepPlan`) names. Everything that steps the domain calls it:

- :meth:`RoverWorld.step <physrover.domain.world.RoverWorld.step>`, through
  :func:`step_teams` (every team, one compiled call a step);
- a learner's whole compiled episode (:mod:`physrover.learn.rollout`), once a step after
  its policies chose the commands;
- a motion model stepped before the kernel (the physical model, a user's): the world
  checks and clips the commands (:func:`~physrover.domain.motion.ideal.clip_teams`), the
  model moves the bodies, and :func:`step_teams` senses, scores and records (its plan has
  no ``motion``).

A team's step t (from state t - 1 to state t), in this order:

1. the commands (R, 2) are clipped to [-1, 1] and recorded, and the agents move
   (:func:`~physrover.domain.motion.ideal.move_team`; the classes' gates are judged from
   the positions before anyone moves);
2. the POIs that leave sight at the new state are marked
   (:mod:`physrover.domain.sensing.vanish`), then every agent senses it (the paper's
   density sensor, or each class's lidar); a failed agent's observation is 0
   (:mod:`physrover.domain.agents.failures`);
3. if state t is scored (t <= ``t_final``), captures, G and D's counterfactuals
   (:func:`~physrover.domain.scoring.captures.score_team`, under the POIs' rules);
4. the new positions and headings are recorded.

A NaN command is refused before anything moves (:func:`step_teams` returns False, the
world unchanged).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import types
from numba.extending import overload

from physrover.core.borrow import borrowed
from physrover.core.compiled import jit, jit_inline
from physrover.domain.agents.failures import silence
from physrover.domain.motion.ideal import all_commands_ok, commands_ok, move_team
from physrover.domain.scoring.captures import score_team
from physrover.domain.sensing.classes import sense_classes, sensing_scratch
from physrover.domain.sensing.density import sense_scratch, sense_team
from physrover.domain.sensing.vanish import vanish_team
from physrover.domain.state import WorldState


class StepScratch(NamedTuple):
    """Scratch of :func:`step_team`, made once a call of the kernels that loop over it."""

    free: np.ndarray
    """(R,) bool: the classes' gates."""
    density: np.ndarray
    """The density sensor's (:func:`~physrover.domain.sensing.density.sense_scratch`)."""
    classes: object
    """The classes' sensing's (:func:`~physrover.domain.sensing.classes.sensing_scratch`)."""


@jit
def _density_scratch(density, n_agents):
    if density is not None:
        return sense_scratch(n_agents, density[1])
    return np.zeros((1, 1))


@jit
def _classes_scratch(classes, n_agents):
    if classes is not None:
        return sensing_scratch(classes, n_agents)
    return None


@jit
def step_scratch(density, classes, n_agents):
    """A :class:`StepScratch` for teams of ``n_agents`` under a plan's ``density`` sensor and
    ``classes``' sensing (either may be None). It takes those two, not the plan, so that it
    is compiled once per sensing, not once per plan."""
    return StepScratch(np.ones(n_agents, np.bool_), _density_scratch(density, n_agents),
                       _classes_scratch(classes, n_agents))  # fmt: skip


def _move(e, t, commands, state, actions, headings, motion, free, failures):
    """Move team e into state t with the plan's ``motion`` (None: moved before the kernel). The
    compiled versions below choose by ``motion``'s type, inlined: numba prunes a branch on
    None only in a function's own arguments, and a call per part cost the paper's episode a
    fifth of its time (the arrays' reference counts change at every call)."""
    if motion is not None:
        move_team(e, commands, state, actions, headings, motion.roles, free, failures, t)


def _sense(e, state, obs, density, classes, scratch):
    """Sense team e with the plan's density sensor or classes' table (either may be None)."""
    if density is not None:
        sense_team(e, state, density[0], density[1], density[2], obs, scratch.density)
    if classes is not None:
        sense_classes(e, state, classes, obs, scratch.classes)


@overload(_move, inline="always")
def _move_compiled(e, t, commands, state, actions, headings, motion, free, failures):
    if isinstance(motion, types.NoneType):
        return lambda e, t, commands, state, actions, headings, motion, free, failures: None

    def move(e, t, commands, state, actions, headings, motion, free, failures):
        move_team(e, commands, state, actions, headings, motion.roles, free, failures, t)

    return move


@overload(_sense, inline="always")
def _sense_compiled(e, state, obs, density, classes, scratch):
    if not isinstance(density, types.NoneType):

        def sense(e, state, obs, density, classes, scratch):
            sense_team(e, state, density[0], density[1], density[2], obs, scratch.density)

        return sense
    if not isinstance(classes, types.NoneType):

        def sense(e, state, obs, density, classes, scratch):
            sense_classes(e, state, classes, obs, scratch.classes)

        return sense
    return lambda e, state, obs, density, classes, scratch: None


@jit_inline
def step_team(e, t, commands, plan, state, actions, obs, positions, headings, with_headings,
              scratch, move=True):  # fmt: skip
    """Step t of team ``e`` (module docstring) under ``plan``, a
    :class:`~physrover.domain.plan.StepPlan`: ``commands`` (E, R, 2) as the policies gave
    them, checked by the caller; written: ``actions`` (E, R, 2) float32 the clipped
    commands (unless the plan has no motion), ``obs`` (E, R, n_obs) float32 the new
    observations, ``positions`` (E, R, 2) and ``headings`` (E, R) copies of the new state
    (the headings NaN unless ``with_headings``: nothing under idealised motion reads them,
    :func:`~physrover.domain.motion.ideal.ideal_move`); ``scratch`` a
    :class:`StepScratch`; ``move`` False at reset (state 0: sensed, scored, recorded)."""
    if move:  # False at reset: state 0 is sensed, scored and recorded, not moved into
        _move(e, t, commands, state, actions, with_headings, plan.motion, scratch.free,
              plan.failures)  # fmt: skip
    vanish_team(plan.vanish, e, t, state, plan.failures)
    _sense(e, state, obs, plan.density, plan.classes, scratch)
    silence(plan.failures, e, t, obs)
    if t <= plan.t_final:
        score_team(e, state, plan.d_cap_sq, plan.n_req, t, plan.rules, plan.counted,
                   plan.failures)  # fmt: skip
    for i in range(state.rover_positions.shape[1]):
        positions[e, i, 0] = state.rover_positions[e, i, 0]
        positions[e, i, 1] = state.rover_positions[e, i, 1]
        headings[e, i] = state.rover_headings[e, i]


@jit
def step_teams(commands, t, plan, actions, obs, positions, headings, *state):
    """Step t of every team (:func:`step_team`, team by team while its data is in cache;
    at t = 0, the reset's state 0, nothing moves); ``*state`` the world's
    :class:`~physrover.domain.state.WorldState`. One compiled version serves the reset and
    the steps of a world (each version of this kernel compiles for many seconds: the parts
    are inlined into it). Returns False, having changed nothing, if a command is NaN."""
    if not all_commands_ok(commands):
        return False
    st, plan = borrowed((WorldState(*state), plan))  # no atomic reference counts (core.borrow)
    actions, obs, positions, headings = borrowed((actions, obs, positions, headings))
    scratch = step_scratch(plan.density, plan.classes, st.cos_h.shape[1])
    for e in range(st.cos_h.shape[0]):
        step_team(e, t, commands, plan, st, actions, obs, positions, headings, True, scratch,
                  t > 0)  # fmt: skip
    return True


@jit
def step_teams_at(commands, t, plan, actions, obs, positions, headings, *state):
    """Step ``t[e]`` of each team e with ``t[e] >= 0`` (0: its reset's state 0, nothing
    moves), each at its own step (teams reset apart, a vector env's ``reset_mask``); the
    teams with ``t[e] < 0`` are left as they are. ``t`` (E,) int64; ``actions`` (T, E, R, 2),
    ``positions`` (T + 1, E, R, 2) and ``headings`` (T + 1, E, R) the world's whole
    records, written at each team's own row; the rest as :func:`step_teams`. Returns False,
    having changed nothing, if a command of a team that moves is NaN."""
    for e in range(commands.shape[0]):
        if t[e] > 0 and not commands_ok(commands[e]):
            return False
    st, plan = borrowed((WorldState(*state), plan))  # no atomic reference counts (core.borrow)
    actions, obs, positions, headings = borrowed((actions, obs, positions, headings))
    scratch = step_scratch(plan.density, plan.classes, st.cos_h.shape[1])
    for e in range(st.cos_h.shape[0]):
        te = t[e]
        if te >= 0:
            step_team(e, te, commands, plan, st, actions[max(te - 1, 0)], obs, positions[te],
                      headings[te], True, scratch, te > 0)  # fmt: skip
    return True


__all__ = ["StepScratch", "step_scratch", "step_team", "step_teams", "step_teams_at"]
