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

import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from physrover.config import DomainConfig
from physrover.core.compiled import bind
from physrover.core.registry import DYNAMICS
from physrover.domain.agents.classes import spawn
from physrover.domain.motion.ideal import clip_teams
from physrover.domain.plan import build_plan
from physrover.domain.scenarios import StartState
from physrover.domain.scoring.difference import difference
from physrover.domain.state import WorldState, start_episode
from physrover.domain.step import step_teams

ACTION_DIM = 2
"""Action components per rover: (forward, left) in the rover's frame."""


@dataclass(frozen=True)
class StartOverrides:
    """Parts of a start state given explicitly (``reset(options=...)``); any field left
    ``None`` is drawn by the scenario as usual.

    Each array is given either for one team (shapes below) or with a leading team axis E.

    Attributes:
        rover_positions: (R, 2) world positions.
        rover_headings: (R,) radians.
        poi_positions: (K, 2) world positions.
        poi_values: (K,) POI values (positive).
    """

    rover_positions: Any = None
    rover_headings: Any = None
    poi_positions: Any = None
    poi_values: Any = None

    @classmethod
    def from_options(cls, options: Mapping[str, Any] | None) -> StartOverrides | None:
        """Build from a gymnasium ``reset(options=...)`` dict; unknown keys are errors."""
        if not options:
            return None
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(options) - known)
        if unknown:
            raise ValueError(
                f"unknown reset option {unknown[0]!r}; known options: {', '.join(sorted(known))}"
            )
        return cls(**options)


def _given(given: Any, drawn: np.ndarray) -> Any:
    """An override if it is given, else the drawn value."""
    return drawn if given is None else given


def _team_array(name: str, value: Any, shape: tuple[int, ...], n_teams: int) -> np.ndarray:
    """``value`` as a float64 array of shape (E, *shape), broadcast from ``shape`` if needed."""
    arr = np.asarray(value, dtype=np.float64)
    if arr.shape == shape:
        arr = np.broadcast_to(arr, (n_teams, *shape))
    elif arr.shape != (n_teams, *shape):
        raise ValueError(f"{name} must have shape {shape} or {(n_teams, *shape)}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite")
    return arr


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
        start states (the CCEA's evaluation episodes); the others share one."""
        self._fixed_start: StartState | None = None  # redraw = "never"
        self.t = -1  # not reset yet

    # -- state -------------------------------------------------------------------------------

    def reset(
        self, rngs: Sequence[np.random.Generator], overrides: StartOverrides | None = None
    ) -> np.ndarray:
        """Start a new episode in every team; returns the (E, R, n_obs) float32 observations.

        The scenario draws the start state, team e from ``rngs[e]`` alone (so a team's start
        state depends only on its own generator), then shares draws as its ``redraw`` mode
        says (:mod:`physrover.domain.scenarios`). It draws even where ``overrides`` give
        parts of the start, so the generators advance identically with and without them.
        """
        if len(rngs) != self.n_teams:
            raise ValueError(f"need one generator per team ({self.n_teams}), got {len(rngs)}")
        e, r, k = self.n_teams, self.n_rovers, self.n_pois
        start = self._draw(rngs)
        o = overrides or StartOverrides()
        state = self.state
        state.rover_positions[:] = _team_array(
            "rover_positions", _given(o.rover_positions, start.rover_positions), (r, 2), e
        )
        state.rover_headings[:] = _team_array(
            "rover_headings", _given(o.rover_headings, start.rover_headings), (r,), e
        )
        state.poi_positions[:] = _team_array(
            "poi_positions", _given(o.poi_positions, start.poi_positions), (k, 2), e
        )
        values = _team_array("poi_values", _given(o.poi_values, start.poi_values), (k,), e)
        if np.any(values <= 0):
            raise ValueError("poi_values must be positive")
        state.poi_values[:] = values
        self.dynamics.reset(state)  # may push overlapping spawns apart
        start_episode(state)
        if self.plan.step.rules is not None:
            self.plan.step.rules.start()
        self.t = 0
        return self._step(self._clipped, 0)  # state 0: sensed, scored and recorded

    def _draw(self, rngs: Sequence[np.random.Generator]) -> StartState:
        """The scenario's start states for this reset, under its redraw mode."""
        scenario, values = self.config.scenario, np.asarray(self.config.poi_values, dtype=float)
        start = scenario.draw(rngs, self.n_rovers, values)
        if not isinstance(start, StartState):
            raise TypeError(f"{type(scenario).__name__}.draw must return a StartState")
        if self.config.agents:  # the classes' spawn rules, drawn after the scenario
            start = start._replace(rover_positions=np.array(start.rover_positions, float))
            spawn(start.rover_positions, self.config, rngs)
        if scenario.redraw == "episode":
            return start
        if scenario.redraw == "never":
            if self._fixed_start is None:
                rng = np.random.default_rng(scenario.layout_seed)
                fixed = scenario.draw([rng], self.n_rovers, values)
                if self.config.agents:
                    fixed = fixed._replace(rover_positions=np.array(fixed.rover_positions, float))
                    spawn(fixed.rover_positions, self.config, [rng])
                self._fixed_start = StartState(*(a[0] for a in fixed))
            shared, first = self.n_teams, self._fixed_start
        else:  # "generation": team 0's draw for every team but the fresh ones
            shared = self.n_teams - min(self.fresh_teams, self.n_teams - 1)
            first = StartState(*(np.asarray(a)[0] for a in start))
        out = [np.array(a, dtype=np.float64) for a in start]
        for arr, row in zip(out, first, strict=True):
            arr[:shared] = row
        return StartState(*out)

    def step(self, actions: np.ndarray) -> np.ndarray:
        """Apply (E, R, 2) actions (clipped to [-1, 1]); returns (E, R, n_obs) float32
        observations."""
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
            self.dynamics.step(self.state, self._clipped)
            return self._step(self._clipped, t + 1)
        # float64 (the clip is in float64 either way, so float32 commands give the same
        # state): one compiled step for every dtype a caller passes
        return self._step(np.array(actions, dtype=np.float64), t + 1)

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
        self._observe_in_python(obs)
        self.t = t
        if t < self.config.steps:
            self.observations[t] = obs
        return obs

    def _observe_in_python(self, obs: np.ndarray) -> None:
        """The classes whose sensor brings no kernel, observed from Python into their rows
        (the columns past a class's size 0)."""
        for rows, sensor, view, size in self.plan.python_sensors:
            if view is not None:  # a class-aware sensor (a lidar's subclass)
                obs[:, rows] = 0.0
                sensor.observe_class(self.state, self.config.d_min, obs, view, rows)
                continue
            scratch = np.zeros((self.n_teams, self.n_rovers, size), dtype=np.float32)
            sensor.observe(self.state, self.config.d_min, scratch)
            obs[:, rows] = 0.0
            obs[:, rows, :size] = scratch[:, rows]

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
        self.t = self.config.steps

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
        if 0 < self.t < self.config.steps:
            raise RuntimeError(f"the coupling changes between episodes, not at step {self.t}")
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
        return self.t >= self.config.steps

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
