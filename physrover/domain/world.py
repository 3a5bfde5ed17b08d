"""RoverWorld: E independent teams of R rovers stepped together with array operations.

This is the one place that calls sensing (Eqs. 15-16) and scoring (Eqs. 11-14, 1), whichever
motion model moves the rovers, so both motion models sense and score identically.

Arrays carry the team axis first: positions (E, R, 2), headings (E, R), observations
(E, R, 8), actions (E, R, 2). Per step the world

1. clips the actions to [-1, 1] (NaN is an error),
2. moves the rovers with the configured motion model,
3. relates every rover to every rover and POI once (:func:`geometry.relate`),
4. senses (Eqs. 15-16) and scores the step (Eqs. 12-13) from those relations,

and records each rover's trajectory of (observation, action) pairs for the fitness critics.
Steps 2-4 are compiled (:mod:`physrover.domain.kernels`): with idealised motion the whole
step (1-4 and the records) is one kernel call, :func:`~physrover.domain.kernels.ideal_step`;
the physical model moves the rovers with pymunk between the clip and the compiled sensing
and scoring (:func:`~physrover.domain.kernels.observe_and_score`). Plain numpy versions of
the same equations live in the tests (``tests/oracles.py``), which compare the two.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from physrover.config import DomainConfig
from physrover.domain.kernels import heading_trig, ideal_step, observe_and_score
from physrover.domain.scoring import ScoreKeeper
from physrover.domain.sensing import OBS_DIM

ACTION_DIM = 2


@dataclass(frozen=True)
class Scenario:
    """An explicit start state; any field left ``None`` is drawn as usual.

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
    def from_options(cls, options: Mapping[str, Any] | None) -> Scenario | None:
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


def _team_array(name: str, value: Any, shape: tuple[int, ...], n_teams: int) -> np.ndarray:
    """``value`` as a float64 array of shape (E, *shape), broadcast from ``shape`` if needed."""
    arr = np.asarray(value, dtype=np.float64)
    if arr.shape == shape:
        arr = np.broadcast_to(arr, (n_teams, *shape))
    elif arr.shape != (n_teams, *shape):
        raise ValueError(f"{name} must have shape {shape} or {(n_teams, *shape)}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite")
    return np.array(arr)


def make_motion(config: DomainConfig, n_teams: int):
    """The physical model for ``config.motion == "physics"``; None for the idealised model,
    which the world's compiled step moves itself."""
    if config.motion == "ideal":
        return None
    if config.motion == "physics":
        from physrover.domain.physics import PhysicsMotion

        return PhysicsMotion(config, n_teams)
    raise ValueError(f"unknown motion model {config.motion!r}")  # config validation stops this


class RoverWorld:
    """E teams of the multi-rover domain, reset and stepped together.

    Args:
        config: the domain.
        n_teams: E, the number of independent teams.

    After :meth:`reset` the state is in ``rover_positions`` (E, R, 2), ``rover_headings``
    (E, R), ``poi_positions`` (E, K, 2), ``poi_values`` (E, K); ``t`` is the number of steps
    taken; ``G`` (E,) and ``D`` (E, R) are the scores so far, ``poi_counts`` (E, K) the rovers
    within ``d_cap`` of each POI at the current step (Eq. 13). ``observations`` (steps, E, R, 8)
    and ``actions`` (steps, E, R, 2), float32, hold the trajectory: row t is the pair
    (s_t, a_t) of step t, valid for t < ``self.t``; ``position_history`` (steps + 1, E, R, 2)
    and ``heading_history`` (steps + 1, E, R) the states after reset and every step, valid
    for rows <= ``self.t``. All of these are reused by the next episode, and
    ``rover_positions``/``rover_headings`` may be views of the current history row: copy
    what you keep (the envs' infos hold copies).
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
        self.motion = make_motion(config, self.n_teams)
        self.scores = ScoreKeeper(config.n_req)
        shape = (config.steps, self.n_teams, self.n_rovers)
        self.observations = np.zeros((*shape, OBS_DIM), dtype=np.float32)
        self.actions = np.zeros((*shape, ACTION_DIM), dtype=np.float32)
        states = (config.steps + 1, self.n_teams, self.n_rovers)
        self.position_history = np.zeros((*states, 2))
        self.heading_history = np.zeros(states)
        # cos and sin of the headings, kept next to them (see domain.kernels)
        self._cos_h = np.zeros(states[1:])
        self._sin_h = np.zeros(states[1:])
        self.poi_counts = np.zeros((self.n_teams, self.n_pois), dtype=np.int64)
        self._fused = self.motion is None  # idealised: one compiled call per step
        self.t = -1  # not reset yet

    # -- state -------------------------------------------------------------------------------

    def default_poi_positions(self) -> np.ndarray:
        """(K, 2): POIs evenly on the ring, the first at angle 0, the rest counter-clockwise."""
        angles = 2.0 * np.pi * np.arange(self.n_pois) / self.n_pois
        return self.config.poi_ring_radius * np.stack([np.cos(angles), np.sin(angles)], -1)

    def reset(
        self, rngs: Sequence[np.random.Generator], scenario: Scenario | None = None
    ) -> np.ndarray:
        """Start a new episode in every team; returns the (E, R, 8) float32 observations.

        Team e draws its rovers from ``rngs[e]`` alone (so a team's start state depends only
        on its own generator): positions uniform in the spawn disc, headings uniform in
        [-pi, pi). The draws are made even where ``scenario`` overrides them, so the
        generators advance identically with and without a scenario.
        """
        if len(rngs) != self.n_teams:
            raise ValueError(f"need one generator per team ({self.n_teams}), got {len(rngs)}")
        n_teams, n_rovers, cfg = self.n_teams, self.n_rovers, self.config
        u = np.stack([rng.random((n_rovers, 3)) for rng in rngs])  # (E, R, 3)
        radius = cfg.spawn_radius * np.sqrt(u[..., 0])
        angle = 2.0 * np.pi * u[..., 1]
        positions = np.stack([radius * np.cos(angle), radius * np.sin(angle)], axis=-1)
        headings = 2.0 * np.pi * u[..., 2] - np.pi
        poi_positions = self.default_poi_positions()
        poi_values = np.asarray(cfg.poi_values, dtype=np.float64)

        sc = scenario or Scenario()
        if sc.rover_positions is not None:
            positions = _team_array("rover_positions", sc.rover_positions, (n_rovers, 2), n_teams)
        if sc.rover_headings is not None:
            headings = _team_array("rover_headings", sc.rover_headings, (n_rovers,), n_teams)
        if sc.poi_positions is not None:
            poi_positions = sc.poi_positions
        if sc.poi_values is not None:
            poi_values = sc.poi_values
        self.poi_positions = _team_array("poi_positions", poi_positions, (self.n_pois, 2), n_teams)
        self.poi_values = _team_array("poi_values", poi_values, (self.n_pois,), n_teams)
        if np.any(self.poi_values <= 0):
            raise ValueError("poi_values must be positive")

        if self.motion is not None:  # the physical model may push overlapping spawns apart
            positions, headings = self.motion.reset(positions, headings)
        self.rover_positions, self.rover_headings = positions, headings
        self.scores.reset(n_teams, n_rovers, self.poi_values)
        self.t = 0
        obs = self._observe_and_score()
        if self._fused:  # the kernel steps from and into rows of the history
            self.rover_positions = self.position_history[0]
            self.rover_headings = self.heading_history[0]
        return obs

    def step(self, actions: np.ndarray) -> np.ndarray:
        """Apply (E, R, 2) actions (clipped to [-1, 1]); returns (E, R, 8) float32 observations."""
        if self.t < 0:
            raise RuntimeError("call reset() before step()")
        if self.t >= self.config.steps:
            raise RuntimeError(f"the episode is over after {self.config.steps} steps; reset()")
        actions = np.asarray(actions)
        expected = (self.n_teams, self.n_rovers, ACTION_DIM)
        if actions.shape != expected:
            raise ValueError(f"actions must have shape {expected}, got {actions.shape}")
        if self._fused:
            return self._step_compiled(actions)
        if np.isnan(actions.sum()) and np.isnan(actions).any():  # the sum is the cheap test
            raise ValueError("actions contain NaN")
        actions = np.clip(actions, -1.0, 1.0, dtype=np.float64)
        self.actions[self.t] = actions
        self.rover_positions, self.rover_headings = self.motion.step(
            self.rover_positions, self.rover_headings, actions
        )
        self.t += 1
        return self._observe_and_score()

    def _step_compiled(self, actions: np.ndarray) -> np.ndarray:
        """The idealised step as one kernel call: the new state is written straight into
        the history rows, and ``rover_positions``/``rover_headings`` become views of them."""
        if actions.dtype not in (np.float32, np.float64):
            actions = actions.astype(np.float64)
        cfg, scores, t = self.config, self.scores, self.t
        obs = np.empty((self.n_teams, self.n_rovers, OBS_DIM), dtype=np.float32)
        ok = ideal_step(
            actions,
            self.rover_positions,
            self.rover_headings,
            self._cos_h,
            self._sin_h,
            self.actions[t],
            self.position_history[t + 1],
            self.heading_history[t + 1],
            *self._scoring_arguments(),
            obs,
            self.observations[t + 1] if t + 1 < cfg.steps else obs,
        )
        if not ok:
            raise ValueError("actions contain NaN")
        scores.t += 1  # the kernel advanced the keeper's arrays as ScoreKeeper.record does
        self.t = t + 1
        self.rover_positions = self.position_history[t + 1]
        self.rover_headings = self.heading_history[t + 1]
        return obs

    def _observe_and_score(self) -> np.ndarray:
        heading_trig(self.rover_headings, self._cos_h, self._sin_h)
        obs = np.empty((self.n_teams, self.n_rovers, OBS_DIM), dtype=np.float32)
        observe_and_score(self.rover_positions, self._cos_h, self._sin_h,
                          *self._scoring_arguments(), obs)  # fmt: skip
        self.scores.t += 1  # the kernel advanced the keeper's arrays (see ScoreKeeper)
        self.position_history[self.t] = self.rover_positions
        self.heading_history[self.t] = self.rover_headings
        if self.t < self.config.steps:
            self.observations[self.t] = obs
        return obs

    def _scoring_arguments(self) -> tuple:
        """The arguments the compiled kernels share, from ``poi_positions`` to ``score``."""
        cfg, scores = self.config, self.scores
        return (
            self.poi_positions,
            self.poi_values,
            cfg.d_min,
            cfg.d_cap,
            cfg.n_req,
            scores.t,
            scores.captured,
            scores.captured_without,
            scores.capture_step,
            scores.score,
            self.poi_counts,
        )

    # -- results -----------------------------------------------------------------------------

    @property
    def done(self) -> bool:
        return self.t >= self.config.steps

    @property
    def G(self) -> np.ndarray:
        """(E,) team score so far (Eq. 11)."""
        return self.scores.G

    @property
    def D(self) -> np.ndarray:
        """(E, R) difference evaluations so far (Eq. 1)."""
        return self.scores.D

    def trajectories(self) -> tuple[np.ndarray, np.ndarray]:
        """Views of the recorded (t, E, R, 8) observations and (t, E, R, 2) actions so far."""
        return self.observations[: self.t], self.actions[: self.t]
