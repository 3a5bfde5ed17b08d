""":func:`play_episode` plays one episode of every team of a world under a :class:`TeamPolicy`
(one genome per agent of each team): the learners' hot path. Where the world's whole step
is compiled (idealised motion and built-in sensors, agent classes, lidars and POI rules
included: :attr:`RoverWorld.compiled <physrover.domain.world.RoverWorld.compiled>`) the
whole episode is one compiled call, :func:`policy_episode`: for each team, every step's
policy forward pass (:func:`~physrover.learn.forward.forward_team`) and then the world's
own step (:func:`physrover.domain.step.step_team`), team by team while the team's data is
in cache. Otherwise (physical motion, a user's part) it steps the world, calling the
policy's compiled forward pass in between.

Both give the same results, bit for bit: the same step in the same order on the same
numbers (``tests/test_rollout.py`` plays the same teams both ways, for every fitness
method's use). The one difference: the compiled episode may skip the heading angles
(``headings=False``, what the CCEA asks for: nothing under idealised motion reads them, and
libm's atan2 is a sixth of the world's step), which are then NaN in ``heading_history``
and the state.
"""

from __future__ import annotations

import numpy as np

from physrover.core.borrow import borrowed
from physrover.core.compiled import dims, jit
from physrover.domain.motion.ideal import commands_ok
from physrover.domain.state import WorldState
from physrover.domain.step import step_scratch, step_team
from physrover.domain.world import RoverWorld
from physrover.learn.forward import forward_team, policy_forward


class TeamPolicy:
    """Fixed genomes for the rovers of E teams, as a policy ``obs (E, R, n_in) -> actions
    (E, R, 2)`` (the per-step path) that :func:`play_episode` can also compile into the
    episode.

    Args:
        genomes: (E, R, P) float32 genomes in the layout of
            :class:`~physrover.learn.policies.PolicyLayout`.
        hidden: H, the hidden units.
        n_in: the observation size.
        tanh_hidden: a tanh hidden layer (the lab's) instead of ReLU (the paper's).
    """

    def __init__(self, genomes: np.ndarray, hidden: int, n_in: int, tanh_hidden: bool = False):
        self.genomes = np.ascontiguousarray(genomes, dtype=np.float32)
        self.hidden, self.n_in = int(hidden), int(n_in)
        self.tanh_hidden = bool(tanh_hidden)
        self.dims = dims(self.n_in)

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        obs = np.ascontiguousarray(obs, dtype=np.float32)
        if obs.shape[-1] != self.n_in:
            raise ValueError(f"observations must have {self.n_in} inputs, got {obs.shape}")
        out = np.empty((*self.genomes.shape[:-1], 2), dtype=np.float32)
        policy_forward(self.genomes, self.hidden, obs, out, self.dims, self.tanh_hidden)
        return out

    def play(self, world: RoverWorld, obs: np.ndarray, headings: bool = True) -> None:
        """:func:`play_episode` of this policy (what ``RoverVectorEnv.play_episode`` calls)."""
        play_episode(world, obs, self, headings)


@jit
def policy_episode(genomes, hidden, tanh_hidden, in_dims, headings, plan, observations,
                   actions, position_history, heading_history, *state):  # fmt: skip
    """Steps 1 .. T of an episode of every team (after the world's reset, which sensed and
    scored step 0), the policies choosing the commands: for each team and step, the forward
    pass of its agents' ``genomes`` (E, R, P) on ``observations[t]`` (a tanh hidden layer
    if ``tanh_hidden``), then the world's step
    (:func:`~physrover.domain.step.step_team` under ``plan``, the world's
    :class:`~physrover.domain.plan.StepPlan`) into ``observations[t + 1]`` (the last step's
    into scratch), the records and the histories (headings NaN unless ``headings``).
    ``*state`` is the world's :class:`~physrover.domain.state.WorldState`, arrays one by
    one. Returns False if a policy gives a NaN command (the world is then mid-episode:
    reset it)."""
    st, plan = borrowed((WorldState(*state), plan))  # no atomic reference counts (core.borrow)
    genomes, observations, actions = borrowed((genomes, observations, actions))
    position_history, heading_history = borrowed((position_history, heading_history))
    n_teams, n_rovers = st.cos_h.shape
    steps = observations.shape[0]
    h = np.empty(hidden, np.float32)
    commands = np.empty((n_teams, n_rovers, 2), np.float32)
    last_obs = np.empty((n_teams, n_rovers, observations.shape[3]), np.float32)
    scratch = step_scratch(plan.density, plan.classes, n_rovers)
    for e in range(n_teams):
        for t in range(steps):
            forward_team(genomes[e], hidden, observations[t, e], commands[e], in_dims, h,
                         tanh_hidden)  # fmt: skip
            if not commands_ok(commands[e]):
                return False
            obs = observations[t + 1] if t + 1 < steps else last_obs
            step_team(e, t + 1, commands, plan, st, actions[t], obs, position_history[t + 1],
                      heading_history[t + 1], headings, scratch)  # fmt: skip
    return True


def play_episode(world: RoverWorld, obs: np.ndarray, policy, headings: bool = True) -> None:
    """Play the episode of a just reset ``world`` (its observations ``obs``) under
    ``policy`` to its end: one compiled call if the world's step is compiled and ``policy``
    is a :class:`TeamPolicy`, else a step loop calling ``policy(obs)``. ``headings=False``
    lets the compiled episode skip the heading angles (module docstring). The world ends at
    its last step (``world.done``), its records filled as by ``steps`` calls of
    ``world.step``.
    """
    if world.t != 0:
        raise RuntimeError(f"play_episode starts from a reset world, not from step {world.t}")
    if not (world.compiled and isinstance(policy, TeamPolicy)):
        for _ in range(world.config.steps):
            obs = world.step(policy(obs))
        return
    if policy.genomes.shape[:2] != (world.n_teams, world.n_rovers):
        raise ValueError(
            f"genomes must be for {world.n_teams} teams of {world.n_rovers} rovers, "
            f"got shape {policy.genomes.shape}"
        )
    if policy.n_in != world.obs_dim:
        raise ValueError(f"policies take {policy.n_in} inputs, the sensor gives {world.obs_dim}")
    genomes, hidden, tanh_hidden, in_dims, with_headings = (
        policy.genomes,
        policy.hidden,
        policy.tanh_hidden,
        policy.dims,
        bool(headings),
    )
    world.play(lambda *records: policy_episode(genomes, hidden, tanh_hidden, in_dims,
                                               with_headings, *records))  # fmt: skip
