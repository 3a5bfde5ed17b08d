"""RoverWorld: E independent teams of R agents stepped together.

The world holds the one :class:`~physrover.domain.state.WorldState`, the records of the
episode and the plan of its step (:mod:`physrover.domain.plan`), built once from the config:

- the scenario (:mod:`physrover.domain.scenarios`) draws the start state at reset, and the
  classes' spawn rules (:func:`~physrover.domain.agents.classes.spawn`) move their agents;
- every step is the one composition of :mod:`physrover.domain.step` (check and clip, move,
  sense, score, record), one compiled call for every team; a motion model stepped from
  Python (the physical model, a user's) moves the bodies between the check and the rest,
  so every model senses and scores identically.

Arrays carry the team axis first: positions (E, R, 2), headings (E, R), observations
(E, R, n_obs), actions (E, R, 2). The world records each agent's trajectory of
(observation, action) pairs for the fitness critics; a learner's whole episode is one
compiled call of the same step (:meth:`RoverWorld.play`). Plain numpy versions of the same
equations live in the tests (``tests/oracles.py``), which compare the two.
"""

from __future__ import annotations

import inspect
import warnings
from collections.abc import Sequence

import numpy as np

from physrover.config import DomainConfig
from physrover.core.compiled import bind
from physrover.core.registry import DYNAMICS
from physrover.domain.agents.failures import alive_at, halt_commands
from physrover.domain.motion.ideal import clip_teams
from physrover.domain.plan import build_plan
from physrover.domain.scoring.difference import difference
from physrover.domain.start import StartDraws, StartOverrides, write_start
from physrover.domain.state import WorldState, start_episode
from physrover.domain.step import step_teams, step_teams_at

ACTION_DIM = 2
"""Action components per rover: (forward, left) in the rover's frame."""


class RoverWorld:
    """E teams of the multi-rover domain, reset and stepped together.

    Args:
        config: the domain (its scenario, motion model and sensor included).
        n_teams: E, the number of independent teams.

    The state is ``state`` (a :class:`~physrover.domain.state.WorldState`), also read
    through ``rover_positions`` (E, R, 2), ``rover_headings`` (E, R), ``poi_positions``
    (E, K, 2), ``poi_values`` (E, K) and ``poi_counts`` (E, K), the rovers within ``d_cap`` of
    each POI at the current step (Eq. 13); ``t`` is the number of steps taken; ``G`` (E,)
    and ``D`` (E, R) are the scores so far. ``observations`` (steps, E, R, n_obs) and
    ``actions`` (steps, E, R, 2), float32, hold the trajectory: row t is the pair (s_t, a_t)
    of step t, valid for t < ``self.t``; ``position_history`` (steps + 1, E, R, 2) and
    ``heading_history`` (steps + 1, E, R) the states after reset and every step, valid for
    rows <= ``self.t``. All of these are updated in place and reused by the next episode:
    copy what you keep (the envs' infos hold copies).
    """

    def __init__(self, config: DomainConfig, n_teams: int):
        if not isinstance(config, DomainConfig):
            raise TypeError(f"config must be a DomainConfig, got {type(config).__name__}")
        if int(n_teams) < 1:
            raise ValueError(f"n_teams must be >= 1, got {n_teams}")
        self.config = config
        self.n_teams = int(n_teams)
        self.n_rovers = config.n_rovers
        self.n_pois = config.n_pois
        self.sensor = config.sensor
        self.dynamics = DYNAMICS[config.motion](config, self.n_teams)
        self.plan = build_plan(config, self.dynamics, self.n_teams)
        """The plan of the step (:class:`~physrover.domain.plan.Plan`)."""
        if self.plan.python_parts:
            warnings.warn(
                f"physrover: {', '.join(self.plan.python_parts)} brings no compiled kernel: "
                "the world calls it from Python after every step",
                stacklevel=2,
            )
        self.obs_dim = self.plan.obs_dim
        """Observations per agent: the largest class's (a smaller class's are zero-padded)."""
        obstacles = config.scenario.obstacle_capsules()
        self.state = WorldState.zeros(
            self.n_teams, self.n_rovers, self.n_pois, config.steps, len(obstacles)
        )
        self.state.obstacles[:] = obstacles
        shape = (config.steps, self.n_teams, self.n_rovers)
        self.observations = np.zeros((*shape, self.obs_dim), dtype=np.float32)
        self.actions = np.zeros((*shape, ACTION_DIM), dtype=np.float32)
        states = (config.steps + 1, self.n_teams, self.n_rovers)
        self.position_history = np.zeros((*states, 2))
        self.heading_history = np.zeros(states)
        self._clipped = np.zeros((self.n_teams, self.n_rovers, ACTION_DIM))
        self._bound, self._bound_plan = None, None  # step_teams compiled for the plan
        self.fresh_teams = 0
        """Under the scenario's redraw = "generation", the last this many teams draw their own
        start states (the CCEA's evaluation episodes); the others share one, or
        ``start_groups`` in turn (:class:`~physrover.domain.start.StartDraws`)."""
        self.start_groups = 1
        self.starts = StartDraws(config, self.n_teams)
        self.team_t = np.full(self.n_teams, -1, dtype=np.int64)
        """(E,) the steps each team has taken in its episode (-1 before its first reset),
        all equal to :attr:`t` unless some teams were reset apart (``reset(..., teams=)``)."""
        self._t: int | None = -1  # the teams' common step (None while they differ)
        self._last_obs = np.zeros((self.n_teams, self.n_rovers, self.obs_dim), dtype=np.float32)
        self._bound_at, self._bound_at_plan = None, None  # step_teams_at, once teams differ

    @property
    def t(self) -> int:
        """The steps taken in the episode (-1 before the first reset), the same in every
        team; a RuntimeError while teams reset apart are at different steps (read
        :attr:`team_t`)."""
        if self._t is None:
            raise RuntimeError("the teams are at different steps (some were reset apart): "
                               "read team_t")  # fmt: skip
        return self._t

    # -- state -------------------------------------------------------------------------------

    def reset(
        self,
        rngs: Sequence[np.random.Generator],
        overrides: StartOverrides | None = None,
        teams: np.ndarray | None = None,
    ) -> np.ndarray:
        """Start a new episode in every team; returns the (E, R, n_obs) float32 observations.

        The scenario draws the start state, team e from ``rngs[e]`` alone (so a team's start
        state depends only on its own generator), then shares draws as its ``redraw`` mode
        says (:mod:`physrover.domain.scenarios`). It draws even where ``overrides`` give
        parts of the start, so the generators advance identically with and without them.

        ``teams``, an (E,) bool mask (a vector env's ``reset_mask``): only those teams start
        again, each as a reset of it alone would start it (their generators alone draw, under
        ``redraw = "episode"`` or ``"never"``); the others keep their state and step, and
        their rows of the returned observations are their last ones.
        """
        if len(rngs) != self.n_teams:
            raise ValueError(f"need one generator per team ({self.n_teams}), got {len(rngs)}")
        if teams is not None:
            teams = self._mask(teams)
            teams = None if teams.all() else teams  # every team: the lock-step reset
        if teams is not None and self.config.scenario.redraw == "generation":
            raise ValueError(
                "teams reset apart need the scenario's redraw = 'episode' or "
                "'never' (under 'generation' a reset's teams share a draw)"
            )
        rows = slice(None) if teams is None else np.flatnonzero(teams)
        drawing = rngs if teams is None else [rngs[e] for e in rows]
        start = self.starts.draw(drawing, self.fresh_teams, self.start_groups)
        write_start(self.state, rows, start, overrides, self.n_teams)
        if teams is None:
            self.dynamics.reset(self.state)  # may push overlapping spawns apart
        else:  # their generators alone drew
            self._apart(self.dynamics.reset)(self.state, teams=teams)
        start_episode(self.state, teams)
        if self.plan.step.rules is not None:
            self.plan.step.rules.start(teams)
        if self.plan.step.failures is not None:  # drawn after the start, shared as it is
            self.plan.step.failures.at[rows] = self.starts.failures(
                drawing, self.fresh_teams, self.start_groups
            )
        if teams is None:
            return self._step(self._clipped, 0)  # state 0: sensed, scored and recorded
        return self._step_at(self._clipped, np.where(teams, 0, -1))

    def step(self, actions: np.ndarray) -> np.ndarray:
        """Apply (E, R, 2) actions (clipped to [-1, 1]); returns (E, R, n_obs) float32
        observations."""
        if self._t is None:  # teams at different steps
            return self.step_teams(actions, np.ones(self.n_teams, dtype=bool))
        if self.t < 0:
            raise RuntimeError("call reset() before step()")
        if self.t >= self.config.steps:
            raise RuntimeError(f"the episode is over after {self.config.steps} steps; reset()")
        actions = np.asarray(actions)
        expected = (self.n_teams, self.n_rovers, ACTION_DIM)
        if actions.shape != expected:
            raise ValueError(f"actions must have shape {expected}, got {actions.shape}")
        t = self.t
        if self.plan.step.motion is None:  # a motion model stepped from Python moves first
            if not clip_teams(actions, self._clipped, self.actions[t]):
                raise ValueError("actions contain NaN")
            if self.plan.step.failures is not None:
                halt_commands(self._clipped, self.actions[t], self.plan.step.failures.at, t + 1)
            self.dynamics.step(self.state, self._clipped)
            return self._step(self._clipped, t + 1)
        # float64 (the clip is in float64 either way, so float32 commands give the same
        # state): one compiled step for every dtype a caller passes
        return self._step(np.array(actions, dtype=np.float64), t + 1)

    def step_teams(self, actions: np.ndarray, teams: np.ndarray) -> np.ndarray:
        """Step the ``teams`` (an (E,) bool mask) alone, each from its own step
        (:attr:`team_t`), under their rows of the (E, R, 2) ``actions``; the other teams
        keep their state, and their rows of the returned observations are their last."""
        teams = self._mask(teams)
        over = teams & ((self.team_t < 0) | (self.team_t >= self.config.steps))
        if over.any():
            raise RuntimeError(f"teams {np.flatnonzero(over).tolist()} have no step to take "
                               "(reset them)")  # fmt: skip
        actions = np.asarray(actions)
        expected = (self.n_teams, self.n_rovers, ACTION_DIM)
        if actions.shape != expected:
            raise ValueError(f"actions must have shape {expected}, got {actions.shape}")
        commands = np.where(teams[:, None, None], actions, 0.0).astype(np.float64)
        if self.plan.step.motion is None:  # a motion model stepped from Python moves first
            record = np.empty(commands.shape, dtype=np.float32)
            if not clip_teams(commands, self._clipped, record):
                raise ValueError("actions contain NaN")
            if self.plan.step.failures is not None:
                halt_commands(self._clipped, record, self.plan.step.failures.at,
                              self.team_t + 1, teams)  # fmt: skip
            self._apart(self.dynamics.step)(self.state, self._clipped, teams=teams)
            for e in np.flatnonzero(teams):
                self.actions[self.team_t[e], e] = record[e]
            commands = self._clipped
        return self._step_at(commands, np.where(teams, self.team_t + 1, -1))

    def _mask(self, teams) -> np.ndarray:
        mask = np.asarray(teams)
        if mask.shape != (self.n_teams,) or mask.dtype != bool or not mask.any():
            raise ValueError(f"teams must be an ({self.n_teams},) bool mask with a True, got "
                             f"{mask.dtype} {mask.shape}")  # fmt: skip
        return mask

    def _apart(self, method):
        """The motion model's ``reset`` or ``step``, if it moves some teams alone."""
        if "teams" not in inspect.signature(method).parameters:
            raise ValueError(f"motion model {self.config.motion!r} cannot move some teams "
                             f"alone: its {method.__name__} takes no teams mask")  # fmt: skip
        return method

    def _step_at(self, commands: np.ndarray, at: np.ndarray) -> np.ndarray:
        """The compiled step of each team e to its state ``at[e]`` (0: its reset's state 0;
        -1: left as it is; :func:`~physrover.domain.step.step_teams_at`) and its records."""
        obs = self._last_obs.copy()
        args = (commands, at, self.plan.step, self.actions, obs, self.position_history,
                self.heading_history, self.state)  # fmt: skip
        if self._bound_at_plan is not self.plan:
            self._bound_at = bind(step_teams_at, *args, packed=True)
            self._bound_at_plan = self.plan
        if not self._bound_at(*args):
            raise ValueError("actions contain NaN")
        moved = at >= 0
        self.plan.observe_in_python(self.state, self.config.d_min, obs,
                                    np.where(moved, at, self.team_t))  # fmt: skip
        self.team_t[moved] = at[moved]
        rows = np.flatnonzero(moved & (at < self.config.steps))
        self.observations[at[rows], rows] = obs[rows]
        common = self.team_t[0]
        self._t = int(common) if (self.team_t == common).all() else None
        self._last_obs = obs
        return obs

    def _step(self, commands: np.ndarray, t: int) -> np.ndarray:
        """The compiled step to state ``t`` (state 0 at reset: nothing moves) and its
        records, from (E, R, 2) float64 C-contiguous ``commands``; returns the new
        observations."""
        obs = np.empty((self.n_teams, self.n_rovers, self.obs_dim), dtype=np.float32)
        actions = self.actions[max(t - 1, 0)]  # step t's clipped commands (none at reset)
        args = (commands, t, self.plan.step, actions, obs, self.position_history[t],
                self.heading_history[t], self.state)  # fmt: skip
        if self._bound_plan is not self.plan:  # step_teams for this plan's types (once)
            self._bound = bind(step_teams, *args, packed=True)
            self._bound_plan = self.plan
        ok = self._bound(*args)
        if not ok:
            raise ValueError("actions contain NaN")
        self.plan.observe_in_python(self.state, self.config.d_min, obs, t)
        self._t, self._last_obs = t, obs
        self.team_t[:] = t
        if t < self.config.steps:
            self.observations[t] = obs
        return obs

    def play(self, episode) -> None:
        """Play the rest of the episode of a just reset world with a compiled ``episode``
        (:mod:`physrover.learn.rollout`): ``episode(plan, observations, actions,
        position_history, heading_history, *state)`` -> False if a command was NaN (the
        world is then mid-episode: reset it). It steps with :func:`step_team`, so the
        world ends at its last step (``done``), its records filled as by ``steps`` calls
        of :meth:`step`."""
        if self.t != 0:
            raise RuntimeError(f"a compiled episode starts from a reset world, not step {self.t}")
        if self.plan.step.motion is None or self.plan.python_sensors:
            raise RuntimeError("only a world whose whole step is compiled plays a compiled episode")
        ok = episode(self.plan.step, self.observations, self.actions, self.position_history,
                     self.heading_history, *self.state)  # fmt: skip
        if not ok:
            raise ValueError("actions contain NaN")
        self._t = self.config.steps
        self.team_t[:] = self._t

    @property
    def n_req(self) -> np.ndarray:
        """(K,) int64: each POI's coupling (Eq. 12)."""
        return self.plan.step.n_req

    def set_coupling(self, n_req) -> None:
        """Each POI's coupling (Eq. 12) from the next reset on: ``n_req`` one int or (K,)
        ints in 1 .. R (a coupling curriculum's, :mod:`physrover.learn.curriculum`). The
        compiled step reads the plan's array, so nothing recompiles; D, D++ and influence
        credit read it too. Refused once an episode has stepped (a reset's state 0 was
        scored at the old coupling: reset again before stepping)."""
        playing = (self.team_t > 0) & (self.team_t < self.config.steps)
        if playing.any():
            raise RuntimeError("the coupling changes between episodes, not at step "
                               f"{self.team_t[playing].max()}")  # fmt: skip
        values = np.broadcast_to(np.asarray(n_req), self.n_req.shape)
        if not np.issubdtype(values.dtype, np.integer) or values.min() < 1 or \
                values.max() > self.n_rovers:  # fmt: skip
            raise ValueError(f"n_req must be ints in 1 .. {self.n_rovers}, got {n_req!r}")
        self.plan.step.n_req[:] = values

    @property
    def compiled(self) -> bool:
        """Whether the whole step is one compiled call (idealised motion, built-in sensors):
        what a whole compiled episode (:meth:`play`) needs."""
        return self.plan.step.motion is not None and not self.plan.python_sensors

    # -- results -----------------------------------------------------------------------------

    @property
    def rover_positions(self) -> np.ndarray:
        return self.state.rover_positions

    @property
    def rover_headings(self) -> np.ndarray:
        return self.state.rover_headings

    @property
    def poi_positions(self) -> np.ndarray:
        return self.state.poi_positions

    @property
    def poi_values(self) -> np.ndarray:
        return self.state.poi_values

    @property
    def poi_counts(self) -> np.ndarray:
        return self.state.poi_counts

    @property
    def done(self) -> bool:
        """Whether every team's episode is over."""
        if self._t is not None:
            return self._t >= self.config.steps
        return bool((self.team_t >= self.config.steps).all())

    @property
    def alive(self) -> np.ndarray:
        """(E, R) bool: which agents are alive at each team's current step (every agent
        unless ``[failures]``; :mod:`physrover.domain.agents.failures`)."""
        if self.plan.step.failures is None:
            return np.ones((self.n_teams, self.n_rovers), dtype=bool)
        return alive_at(self.plan.step.failures.at, self.team_t)

    @property
    def team_done(self) -> np.ndarray:
        """(E,) bool: whether each team's episode is over."""
        return self.team_t >= self.config.steps

    @property
    def G(self) -> np.ndarray:
        """(E,) team score so far (Eq. 11), a copy."""
        return self.state.score.copy()

    @property
    def D(self) -> np.ndarray:
        """(E, R) difference evaluations so far (Eq. 1)."""
        return difference(self.state, self.plan.step.rules)

    def trajectories(self) -> tuple[np.ndarray, np.ndarray]:
        """Views of the recorded (t, E, R, n_obs) observations and (t, E, R, 2) actions."""
        return self.observations[: self.t], self.actions[: self.t]
