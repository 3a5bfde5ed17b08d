"""PettingZoo parallel env over one team of the multi-rover domain.

Built on :class:`physrover.RoverEnv` (its public API only: ``reset``, ``step``, ``render``
and its infos), so each agent sees exactly what the gymnasium env gives its rover.
PettingZoo is optional (``pip install 'physrover[marl]'``): this module imports without it,
and building an env without it raises ``ImportError``.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from dataclasses import fields
from typing import Any

import numpy as np
from gymnasium import spaces

from physrover.config import DomainConfig
from physrover.core.registry import CREDITS
from physrover.domain.agents.classes import agent_names
from physrover.domain.scoring.credit import step_rewards, team_credit
from physrover.domain.sensing.sensor import agent_obs_sizes
from physrover.domain.world import StartOverrides
from physrover.envs.gymnasium_env import RoverEnv, resolve_config

try:
    from pettingzoo import ParallelEnv
except ImportError:  # optional extra; RoverParallelEnv() raises with the install command
    ParallelEnv = object

MISSING_PETTINGZOO = "pettingzoo is not installed: pip install 'physrover[marl]'"


def _require_pettingzoo() -> None:
    """Raise ImportError with the install command if pettingzoo cannot be imported."""
    try:
        import pettingzoo  # noqa: F401
    except ImportError as error:
        raise ImportError(MISSING_PETTINGZOO) from error
    if ParallelEnv is object:  # pettingzoo was installed after this module was imported
        raise ImportError(f"{MISSING_PETTINGZOO} (then restart Python)")


class RoverParallelEnv(ParallelEnv):
    """One team of the tightly coupled multi-rover domain as a PettingZoo ``ParallelEnv``.

    ## Description
    The world of :class:`physrover.RoverEnv` (paper Section 4.1) with one agent per rover:
    every agent acts at every step, and the step of the team is one ``RoverEnv.step``. A POI
    is captured when at least ``n_req`` rovers are within ``d_cap`` of it at the same step;
    the team score G sums the values of the POIs captured at any step (Eqs. 11-14).

    ## Agents
    ``possible_agents = ["rover_0", ..., "rover_{R-1}"]``; agent i is row i of the wrapped
    env's arrays. ``agents`` is every rover from ``reset`` until the step limit, then empty.
    With agent classes (``[[agents]]``) the names are ``CLASS_j``, j counted within the
    class (``rover_0 .. rover_3, uav_0, uav_1``), in team order.

    ## Observation Space
    Per agent the rover's row of ``RoverEnv``'s (R, n_obs) observation, with the sensor's
    bounds: with the paper's sensor ``Box(0, inf, (8,), float32)``, rover density in its
    quadrants 0-3 (Eq. 15) then POI value density in quadrants 0-3 (Eq. 16). ``state()`` is
    the R rows concatenated, ``state_space`` ``Box(0, inf, (R * 8,), float32)``.
    With agent classes an agent's observation is its class's sensor's (the wrapped env's
    row without its padding), so classes differ in size; ``state()`` keeps the padded rows.

    ## Action Space
    Per agent ``Box(-1, 1, (2,), float32)``: a command in the rover's own frame (forward,
    left), as in ``RoverEnv``: the displacement of this step in world units under
    ``motion="ideal"``, the commanded velocity (world units per step) under
    ``motion="physics"``. ``step`` takes a dict with an action for every live agent.

    ## Rewards
    ``reward="G"``: every agent gets the team's increase of G at each step (the first
    step's reward also includes a capture at reset), so each agent's rewards of an episode
    sum to its G. ``reward="D"``: each agent gets its rover's difference evaluation
    D_i = G - G(without rover i) (Eq. 1) at the last step and 0 before, so its rewards sum
    to D_i; any other credit signal the CCEA takes (``"D++"``, ``"ID"``, a registered one:
    :mod:`physrover.domain.scoring.credit`) likewise.

    ## Starting State
    As ``RoverEnv``: ``reset(seed=s)`` seeds it like a gymnasium env (same seed, same
    episode), and ``reset(options=...)`` passes ``rover_positions`` (R, 2),
    ``rover_headings`` (R,), ``poi_positions`` (K, 2), ``poi_values`` (K,) through; unknown
    option names are a ``ValueError``.

    ## Episode End
    Truncated after ``steps`` steps (every agent at once). After the truncating step
    ``agents`` is empty; ``reset()`` starts a new episode. With ``[failures]`` (agents
    that fail mid-episode, :mod:`physrover.config.failures`) an agent that fails is
    terminated by the step into the state it fails at and leaves ``agents`` (one out from
    the start, step 0, by the first step: every agent begins in ``agents``, its observation
    0, so every one ends terminated or truncated). Its reward on that step is the
    team's increase of G (``reward="G"``), or 0 under an episode-end credit (its credit,
    what it did alive, is the episode's, known at the end).

    ## Info
    Per agent ``"G"`` (the team's score so far), ``"position"`` (2,) in world units and
    ``"heading"`` (radians) of its rover, and its ``"D"`` (0 until the last step: the keys are
    the same at every step, as TorchRL's PettingZoo wrapper needs).

    ## Rendering
    ``render_mode="rgb_array"``: ``render()`` returns the wrapped ``RoverEnv``'s (H, W, 3)
    uint8 RGB frame of the whole team.

    ## Arguments
    ``RoverParallelEnv(config=None, reward="G", render_mode=None, render_config=None,
    **fields)``: any :class:`~physrover.config.DomainConfig` field by name (e.g.
    ``n_rovers=4, n_req=2``) over an optional base ``config`` (a ``DomainConfig`` or a
    mapping), as ``RoverEnv`` takes them; ``render_config`` is passed to ``RoverEnv``.
    The wrapped env is ``env``.
    """

    metadata = {
        "render_modes": ["rgb_array"],
        "name": "physrover_rover_v0",
        "is_parallelizable": True,
        "render_fps": RoverEnv.metadata["render_fps"],
    }

    def __init__(
        self,
        config: DomainConfig | Mapping[str, Any] | None = None,
        reward: str = "G",
        render_mode: str | None = None,
        render_config=None,
        **fields: Any,
    ):
        _require_pettingzoo()
        if reward not in CREDITS:
            raise ValueError(f"reward: {CREDITS.unknown_message(reward)}")
        self.reward = reward
        self.env = RoverEnv(
            resolve_config(config, fields), render_mode=render_mode, render_config=render_config
        )
        self.config = self.env.config
        team_credit(reward, self.config).check(self.config)  # defined for this domain?
        self.render_mode = render_mode
        team_obs = self.env.observation_space  # (R, n_obs), bounds from the sensor
        self.possible_agents = agent_names(self.config)  # CLASS_j with [[agents]]
        self._sizes = agent_obs_sizes(self.config)  # each agent's class's observations
        self.agents: list[str] = []
        # One space object per agent, so seeding one agent's space leaves the others alone.
        self.observation_spaces = {
            agent: spaces.Box(team_obs.low[i, :n], team_obs.high[i, :n], dtype=np.float32)
            for i, (agent, n) in enumerate(zip(self.possible_agents, self._sizes, strict=True))
        }
        self.action_spaces = {
            agent: spaces.Box(-1.0, 1.0, shape=(self.env.action_space.shape[1],), dtype=np.float32)
            for agent in self.possible_agents
        }
        self.state_space = spaces.Box(team_obs.low.ravel(), team_obs.high.ravel(), dtype=np.float32)
        self._obs: np.ndarray | None = None  # (R, obs_dim) float32, the latest observations

    def observation_space(self, agent: str) -> spaces.Box:
        """The (obs_dim,) float32 observation space of ``agent`` (the same object each call)."""
        return self.observation_spaces[agent]

    def action_space(self, agent: str) -> spaces.Box:
        """The (2,) float32 action space of ``agent`` (the same object each call)."""
        return self.action_spaces[agent]

    def _split(self, obs: np.ndarray, info: dict[str, Any]) -> tuple[dict, dict]:
        """Per-agent observations and infos from the team's (R, obs_dim) obs and its info."""
        self._obs = np.array(obs, dtype=np.float32)  # a copy: agents' rows never change later
        rows = zip(self.possible_agents, self._obs, self._sizes, strict=True)
        observations = {agent: row[:n] for agent, row, n in rows}
        infos = {}
        for i, agent in enumerate(self.possible_agents):
            infos[agent] = {
                "G": info["G"],
                "position": info["rover_positions"][i].copy(),
                "heading": float(info["rover_headings"][i]),
                "D": float(info["D"][i]),  # 0 until the last step: the keys never change
            }
        return observations, infos

    def reset(self, seed: int | None = None, options: dict[str, Any] | None = None):
        """Start an episode; returns ({agent: (obs_dim,) obs}, {agent: info}).

        ``options`` are RoverEnv's start-state options (``rover_positions`` ...). Other keys
        are ignored with a warning: PettingZoo's conformance tests pass options an env does
        not know (``{"options": 1}``), where RoverEnv itself raises.
        """
        if options:
            known = {f.name for f in fields(StartOverrides)}
            unknown = sorted(set(options) - known)
            if unknown:
                warnings.warn(
                    f"ignoring unknown reset options {', '.join(map(repr, unknown))} "
                    f"(known: {', '.join(sorted(known))})",
                    stacklevel=2,
                )
                options = {k: v for k, v in options.items() if k in known}
        obs, info = self.env.reset(seed=seed, options=options)
        self.agents = list(self.possible_agents)
        return self._split(obs, info)

    def _live(self) -> list[str]:
        """The agents that have not failed (every agent without ``[failures]``)."""
        alive = self.env.world.alive[0]
        return [agent for agent, ok in zip(self.possible_agents, alive, strict=True) if ok]

    @staticmethod
    def _of(values: dict, agents: list[str]) -> dict:
        return {agent: values[agent] for agent in agents}

    def _team_action(self, actions: Mapping[str, Any]) -> np.ndarray:
        """The (R, 2) action of ``RoverEnv.step`` from a dict with one (2,) action per agent."""
        missing = [agent for agent in self.agents if agent not in actions]
        if missing:
            raise ValueError(
                f"no action for {', '.join(missing)}: step() needs an action for every live "
                f"agent ({', '.join(self.agents)})"
            )
        unknown = sorted(set(actions) - set(self.agents), key=str)
        if unknown:
            raise ValueError(
                f"actions for unknown agents {', '.join(map(repr, unknown))}; "
                f"the live agents are {', '.join(self.agents)}"
            )
        team = np.zeros((len(self.possible_agents), self.env.action_space.shape[1]))
        for i, agent in enumerate(self.possible_agents):
            if agent not in self.agents:  # failed: its command is ignored anyway
                continue
            row = np.asarray(actions[agent])
            if row.shape != self.action_spaces[agent].shape:
                raise ValueError(
                    f"the action of {agent} must have shape {self.action_spaces[agent].shape}, "
                    f"got {row.shape}"
                )
            team[i] = row
        return team

    def step(self, actions: Mapping[str, Any]):
        """Advance every rover one step; returns (observations, rewards, terminations,
        truncations, infos), each a dict over the agents live before the step."""
        if not self.agents:
            raise RuntimeError("no live agents (the episode is over or never began): reset()")
        obs, reward, _, truncated, info = self.env.step(self._team_action(actions))
        observations, infos = self._split(obs, info)
        credit = step_rewards(self.reward, self.env.world, bool(truncated), np.array([reward]))
        before, live = self.agents, set(self._live())
        index = {agent: i for i, agent in enumerate(self.possible_agents)}
        rewards = {agent: float(credit[0, index[agent]]) for agent in before}
        terminations = {agent: agent not in live for agent in before}
        truncations = dict.fromkeys(before, bool(truncated))
        self.agents = [] if truncated else [agent for agent in before if agent in live]
        return (self._of(observations, before), rewards, terminations, truncations,
                self._of(infos, before))  # fmt: skip

    def state(self) -> np.ndarray:
        """The (R * obs_dim,) float32 observations of all rovers, concatenated in agent order."""
        if self._obs is None:
            raise RuntimeError("call reset() before state()")
        return self._obs.reshape(-1).copy()

    def render(self):
        """The wrapped ``RoverEnv``'s (H, W, 3) uint8 RGB frame (``render_mode="rgb_array"``)."""
        return self.env.render()

    def close(self) -> None:
        self.env.close()


def parallel_env(
    config: DomainConfig | Mapping[str, Any] | None = None,
    reward: str = "G",
    render_mode: str | None = None,
    **fields: Any,
) -> RoverParallelEnv:
    """A PettingZoo ``ParallelEnv`` over one team (see :class:`RoverParallelEnv`).

    ``parallel_env(n_rovers=4, n_req=2, reward="D")``; raises ImportError if pettingzoo is
    not installed.
    """
    return RoverParallelEnv(config, reward=reward, render_mode=render_mode, **fields)
