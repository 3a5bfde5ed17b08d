"""Gymnasium environments over :class:`~physrover.domain.world.RoverWorld`.

``RoverEnv`` is one team (a ``gymnasium.Env``, registered as ``physrover/Rover-v0``);
``RoverVectorEnv`` is E teams natively batched on one world (a ``gymnasium.vector.VectorEnv``
in the pattern of gymnasium's ``CartPoleVectorEnv``, not a SyncVectorEnv of single envs).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import gymnasium
import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from physrover.config import DomainConfig
from physrover.domain.sensing.sensor import sensor_size
from physrover.domain.world import ACTION_DIM, RoverWorld, StartOverrides

ENV_ID = "physrover/Rover-v0"


def resolve_config(
    config: DomainConfig | Mapping[str, Any] | None, fields: Mapping
) -> DomainConfig:
    """A DomainConfig from an optional base (object or mapping) plus field overrides.

    Unknown field names raise :class:`~physrover.config.ConfigError`.
    """
    if config is None:
        return DomainConfig.from_dict(dict(fields))
    if isinstance(config, DomainConfig):
        return config.replace(**fields) if fields else config
    if isinstance(config, Mapping):
        return DomainConfig.from_dict({**config, **fields})
    raise TypeError(f"config must be a DomainConfig or a mapping, got {type(config).__name__}")


def team_spaces(config: DomainConfig) -> tuple[spaces.Box, spaces.Box]:
    """(observation, action) spaces of one team: (R, n_obs) from the sensor, (R, 2).

    The observations are bounded below by 0, as the built-in sensor's densities; a sensor
    with other bounds sets ``low`` and ``high`` attributes (scalars). With agent classes
    (``[[agents]]``) n_obs is the widest class's (a class's observations fill its first
    columns, 0 after) and the bounds span every class's sensor."""
    shape = (config.n_rovers,)
    sensors = [c.sensor or config.sensor for c in config.agents] or [config.sensor]
    low = min(getattr(sensor, "low", 0.0) for sensor in sensors)
    high = max(getattr(sensor, "high", np.inf) for sensor in sensors)
    n_obs = max(sensor_size(sensor, config) for sensor in sensors)  # classes: the widest
    observation = spaces.Box(low, high, shape=(*shape, n_obs), dtype=np.float32)
    action = spaces.Box(-1.0, 1.0, shape=(*shape, ACTION_DIM), dtype=np.float32)
    return observation, action


class RoverEnv(gymnasium.Env):
    """One team of the tightly coupled multi-rover domain (paper Section 4.1).

    ## Description
    R rovers start near the origin; K POIs of value V_k lie on a ring around them. A POI is
    captured when at least ``n_req`` rovers are within ``d_cap`` of it at the same step; the
    team score G sums the values of the POIs captured at any step (Eqs. 11-14).

    ## Action Space
    ``Box(-1, 1, (R, 2), float32)``: per rover a command in its own frame (forward, left).
    Under ``motion="ideal"`` it is the displacement of this step in world units; under
    ``motion="physics"`` the commanded velocity (world units per step). Values are clipped
    to [-1, 1]; NaN raises ``ValueError``.

    ## Observation Space
    ``(R, n_obs)`` float32 from the configured sensor (:mod:`physrover.domain.sensing.sensor`). The
    paper's (``[sensor] kind = "density"``, 4 sectors): ``Box(0, inf, (R, 8), float32)``, per
    rover the rover density in its quadrants 0-3 (Eq. 15) then POI value density in
    quadrants 0-3 (Eq. 16); quadrants 0 behind-right, 1 front-right, 2 front-left, 3
    behind-left.

    ## Rewards
    The increase of G at each step (the first step's reward also includes a capture at
    reset), so the rewards of an episode sum to its G.

    ## Starting State
    Drawn by the configured scenario (:mod:`physrover.domain.scenarios`). The paper's
    (``ring``): POIs evenly on a ring of radius ``poi_ring_radius`` (first at angle 0, then
    counter-clockwise); rovers uniform in a disc of radius ``spawn_radius``; headings uniform
    in [-pi, pi). ``reset(options=...)`` may give ``rover_positions`` (R, 2),
    ``rover_headings`` (R,), ``poi_positions`` (K, 2), ``poi_values`` (K,).

    ## Episode End
    Truncated after ``steps`` steps; never terminated.

    ## Info
    ``"G"`` (score so far), ``"rover_positions"`` (R, 2), ``"rover_headings"`` (R,) and
    ``"D"`` (R,): each rover's difference evaluation (Eq. 1) on the episode's last step
    (``truncated`` True), zeros before; with ``[failures]`` (agents that fail mid-episode,
    :mod:`physrover.config.failures`) also ``"alive"`` (R,) bool, which agents have not
    failed (a failed agent's observation is 0 and its action is ignored). The keys and
    shapes are the same at every step (what TorchRL's wrappers need).

    ## Rendering
    ``render_mode="rgb_array"``: ``render()`` returns an OpenCV-drawn (H, W, 3) uint8 RGB
    frame (:mod:`physrover.viz.render`; size from ``render_config``, a ``RenderConfig``) whose
    view fits the POIs and every position the team has visited so far.

    ## Arguments
    ``RoverEnv(config=None, render_mode=None, render_config=None, **fields)``: any
    :class:`DomainConfig` field by name (e.g. ``n_rovers=4, n_req=2``), over an optional
    base ``config``.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 10}

    def __init__(
        self,
        config: DomainConfig | Mapping[str, Any] | None = None,
        render_mode: str | None = None,
        render_config=None,
        **fields: Any,
    ):
        self.config = resolve_config(config, fields)
        self.render_config = render_config
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(
                f"render_mode must be one of {self.metadata['render_modes']} or None, "
                f"got {render_mode!r}"
            )
        self.render_mode = render_mode
        self.observation_space, self.action_space = team_spaces(self.config)
        self.world = RoverWorld(self.config, n_teams=1)
        self._last_G = 0.0

    def render(self):
        """An (H, W, 3) uint8 RGB frame of the current state (``render_mode="rgb_array"``)."""
        if self.render_mode is None:
            gymnasium.logger.warn("render() needs RoverEnv(render_mode='rgb_array')")
            return None
        from physrover.viz.render import RenderConfig, world_frame

        if self.render_config is None:
            self.render_config = RenderConfig(fps=self.metadata["render_fps"])
        return world_frame(self.world, 0, self.render_config)

    def _info(self) -> dict[str, Any]:
        w = self.world
        info = {
            "G": float(w.G[0]),
            "rover_positions": w.rover_positions[0].copy(),
            "rover_headings": w.rover_headings[0].copy(),
            # Every step, so the keys never change within an episode (TorchRL builds its
            # specs from the first step's): zeros until the last step gives it. (Not NaN:
            # gymnasium's and PettingZoo's determinism checks compare infos with ==.)
            "D": w.D[0].copy() if w.done else np.zeros(w.config.n_rovers),
        }
        if w.plan.step.failures is not None:
            info["alive"] = w.alive[0]
        return info

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        obs = self.world.reset([self.np_random], StartOverrides.from_options(options))
        self._last_G = 0.0
        return obs[0], self._info()

    def step(self, action):
        action = np.asarray(action)
        if action.shape != self.action_space.shape:
            raise ValueError(
                f"action must have shape {self.action_space.shape}, got {action.shape}"
            )
        obs = self.world.step(action[None])
        G = float(self.world.G[0])
        reward, self._last_G = G - self._last_G, G
        return obs[0], reward, False, self.world.done, self._info()


def generator_from_state(state: dict) -> np.random.Generator:
    """A generator restored from ``bit_generator.state`` (PCG64, as gymnasium makes them)."""
    gen = np.random.Generator(np.random.PCG64())
    gen.bit_generator.state = state
    return gen


def _team_generators(seed: int | Sequence[int] | None, n: int) -> list[np.random.Generator]:
    """One generator per team, made as gymnasium's ``Env.reset(seed=...)`` makes its own."""
    if seed is None:
        seeds: Sequence[int | None] = [None] * n
    elif isinstance(seed, (int, np.integer)):
        seeds = [int(seed) + i for i in range(n)]
    else:
        seeds = list(seed)
        if len(seeds) != n:
            raise ValueError(f"need {n} seeds, one per team, got {len(seeds)}")
    return [seeding.np_random(s)[0] for s in seeds]


def _reset_mask(mask: Any, n: int) -> np.ndarray | None:
    """``options["reset_mask"]`` checked as gymnasium's SyncVectorEnv checks it (None if
    not given, or if it resets every team)."""
    if mask is None:
        return None
    if not isinstance(mask, np.ndarray) or mask.dtype != np.bool_ or mask.shape != (n,):
        raise TypeError(f"options['reset_mask'] must be a numpy bool array of shape ({n},), "
                        f"got {type(mask).__name__} {getattr(mask, 'shape', '')}")  # fmt: skip
    if not mask.any():
        raise ValueError("options['reset_mask'] must have at least one True value")
    return None if mask.all() else mask


class RoverVectorEnv(VectorEnv):
    """E teams of the multi-rover domain, natively batched (see :class:`RoverEnv`).

    Spaces per team are those of :class:`RoverEnv`; batched spaces add a leading team axis.
    As with gymnasium's ``SyncVectorEnv`` seeding, after ``reset(seed=s)`` team i starts and
    steps exactly like ``RoverEnv`` after ``reset(seed=s + i)``; ``seed`` may also be a list
    of E seeds. Autoreset mode is ``NEXT_STEP``: the ``step`` after the last step of a
    team's episode resets that team and returns its new first observations with zero
    reward (the others step). ``reset(options={"reset_mask": mask})`` resets the teams of
    the (E,) bool ``mask`` alone, as gymnasium's vector API defines it: each starts as a
    reset of it alone would (its own generator, reseeded with ``seed + i`` if ``seed`` is
    given), the others keep their state, and its infos are masked to the reset teams.
    Teams then run at different steps, each ending after its own ``steps`` steps.

    Infos hold ``"G"`` (E,), ``"rover_positions"`` (E, R, 2), ``"rover_headings"`` (E, R)
    and ``"D"`` (E, R), each with its ``"_name"`` mask as gymnasium's vector envs do, at
    every step: ``"D"`` is zeros and its mask False until the last step of an episode; with
    ``[failures]`` also ``"alive"`` (E, R) bool, the agents that have not failed. The
    wrapped :class:`RoverWorld` is ``world``; its recorded trajectories serve the fitness
    critics.

    Start states follow the scenario's ``redraw`` (:mod:`physrover.domain.scenarios`): under
    ``"generation"`` one draw is shared by all teams of a reset but the last
    ``fresh_teams``, which draw their own (evaluation envs pass ``fresh_teams=num_envs``:
    every team its own start), or with ``start_groups`` = n the draws of teams 0 to n - 1
    in turn (the CCEA's ``rollouts``); under ``"never"`` all teams start alike.

    Arguments: ``RoverVectorEnv(num_envs, config=None, render_mode=None, fresh_teams=0,
    start_groups=1, **fields)``.
    """

    metadata = {"render_modes": [], "render_fps": 10, "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(
        self,
        num_envs: int = 1,
        config: DomainConfig | Mapping[str, Any] | None = None,
        render_mode: str | None = None,
        fresh_teams: int = 0,
        start_groups: int = 1,
        **fields: Any,
    ):
        if int(num_envs) < 1:
            raise ValueError(f"num_envs must be >= 1, got {num_envs}")
        if render_mode is not None:
            raise ValueError(f"render_mode must be None for the vector env, got {render_mode!r}")
        self.config = resolve_config(config, fields)
        self.num_envs = int(num_envs)
        self.render_mode = render_mode
        self.single_observation_space, self.single_action_space = team_spaces(self.config)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.world = RoverWorld(self.config, n_teams=self.num_envs)
        self.world.fresh_teams = int(fresh_teams)
        self.world.start_groups = int(start_groups)
        self._rngs: list[np.random.Generator] | None = None
        self._last_G = np.zeros(self.num_envs)
        self._autoreset = np.zeros(self.num_envs, dtype=bool)  # NEXT_STEP: reset at next step

    def _infos(self, G: np.ndarray, teams: np.ndarray | None = None) -> dict[str, Any]:
        """The infos of the ``teams`` (an (E,) mask; every team if None)."""
        w = self.world
        every = np.ones(self.num_envs, dtype=bool) if teams is None else teams
        done = w.team_done & every
        D = np.zeros((self.num_envs, w.config.n_rovers))
        if done.any():
            D[done] = w.D[done]
        infos = {"G": G, "_G": every,
                 "rover_positions": w.rover_positions.copy(), "_rover_positions": every,
                 "rover_headings": w.rover_headings.copy(), "_rover_headings": every,
                 # Every step (keys never change): zeros, masked out, until a team's last
                 # step, as gymnasium's vector envs fill a key an env lacks.
                 "D": D, "_D": done}  # fmt: skip
        if w.plan.step.failures is not None:
            infos["alive"], infos["_alive"] = w.alive, every
        return infos

    def play_episode(self, policy, headings: bool = True) -> RoverWorld:
        """One whole episode of every team under ``policy`` (``obs (E, R, n_obs) -> actions
        (E, R, 2)``), from a reset that continues the teams' generators, as ``reset()``
        then ``steps`` calls of ``step`` would play it, without building gymnasium's
        per-step infos (the learners' fast path). A policy with a ``play(world, obs,
        headings)`` method plays the episode itself (a
        :class:`~physrover.learn.rollout.TeamPolicy` compiles it into one call on a
        compiled world; ``headings=False`` lets it skip the heading angles). Returns the world, at
        the episode's end; the next ``step`` autoresets as after any last step."""
        if self._rngs is None:
            raise RuntimeError("call reset(seed=...) first: the generators are made there")
        obs = self._reset_world(None)
        self._autoreset[:] = True  # also if the policy fails mid-episode: the next step resets
        play = getattr(policy, "play", None)
        if play is not None:
            play(self.world, obs, headings)
        else:
            for _ in range(self.config.steps):
                obs = self.world.step(policy(obs))
        self._last_G = self.world.G
        return self.world

    def _reset_world(self, options: dict[str, Any] | None, teams=None) -> np.ndarray:
        """Reset every team, or the ``teams`` of an (E,) bool mask alone."""
        obs = self.world.reset(self._rngs, StartOverrides.from_options(options), teams)
        every = slice(None) if teams is None else teams
        self._last_G[every] = 0.0
        self._autoreset[every] = False
        return obs

    def reset(self, *, seed: int | Sequence[int] | None = None, options: dict | None = None):
        options = dict(options or {})
        mask = _reset_mask(options.pop("reset_mask", None), self.num_envs)
        if seed is not None or self._rngs is None:
            fresh = _team_generators(seed, self.num_envs)
            if self._rngs is None or mask is None:
                self._rngs = fresh
            else:  # the reset teams' generators only, as SyncVectorEnv reseeds its envs
                old = self._rngs
                self._rngs = [f if m else g for f, g, m in zip(fresh, old, mask, strict=True)]
            self._np_random = self._rngs[0]
        return self._reset_world(options, mask), self._infos(self.world.G, mask)

    def rng_states(self) -> list[dict]:
        """The state of each team's generator (JSON-serialisable), for checkpoints."""
        if self._rngs is None:
            raise RuntimeError("call reset() first: the generators are made on the first reset")
        return [g.bit_generator.state for g in self._rngs]

    def set_rng_states(self, states: Sequence[dict]) -> None:
        """Restore the generators saved by :meth:`rng_states`."""
        if len(states) != self.num_envs:
            raise ValueError(f"need {self.num_envs} generator states, got {len(states)}")
        self._rngs = [generator_from_state(state) for state in states]
        self._np_random = self._rngs[0]

    def step(self, actions):
        if self._rngs is None:
            raise RuntimeError("call reset() before step()")
        n, auto = self.num_envs, self._autoreset.copy()  # the reset below clears its rows
        if auto.all():  # NEXT_STEP autoreset of every team: this call only resets
            obs = self._reset_world(None)
            zeros = np.zeros(n, dtype=bool)
            return obs, np.zeros(n), zeros, zeros.copy(), self._infos(self.world.G)
        if auto.any():  # those teams reset, the others step
            self._reset_world(None, auto)
            obs = self.world.step_teams(actions, ~auto)
        else:
            obs = self.world.step(actions)
        G = self.world.G
        rewards, self._last_G = G - self._last_G, G
        rewards[auto], self._last_G[auto] = 0.0, 0.0  # reset this call: as a reset returns
        truncated = self.world.team_done
        self._autoreset = truncated.copy()
        return obs, rewards, np.zeros(n, dtype=bool), truncated, self._infos(G)
