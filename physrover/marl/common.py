"""Pieces shared by the gradient-based MARL baselines (:mod:`.mappo`, :mod:`.maddpg`).

What both trainers need word for word: seeding (one ``torch.Generator`` per random
stream, never torch's global RNG), network builders, ``soft_update``, ``gae``, whole
episodes on the vector env, and :class:`Trainer`: the bookkeeping of an iteration (counters,
evaluation at logging points, a coupling curriculum, wall time) and of checkpoints (every
network, optimiser, generator and env RNG as ``(arrays, meta)``, as ``CCEA.state``).

Conventions: arrays are time-major inside an iteration, ``(T, E, R, ...)`` for T steps of E
teams of R rovers; observations are ``(..., R, n_obs)`` float32 and actions ``(..., R, 2)``
float32 in [-1, 1], as :class:`physrover.RoverVectorEnv` takes them.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable, Sequence

import numpy as np
import torch
from torch import nn

from physrover.config import DomainConfig
from physrover.domain.scoring.credit import step_rewards
from physrover.envs.gymnasium_env import RoverVectorEnv, team_spaces
from physrover.learn.curriculum import replay_rules
from physrover.marl.configs import MARLConfig  # noqa: F401  (re-exported)

# ----------------------------------------------------------------------------------------------
# Seeding and networks
# ----------------------------------------------------------------------------------------------


def seed_streams(seed: int, n: int) -> list[int]:
    """``n`` independent 31-bit seeds derived from ``seed`` (numpy's SeedSequence)."""
    rng = np.random.default_rng(np.random.SeedSequence(seed))
    return [int(s) for s in rng.integers(2**31, size=n)]


def torch_generator(seed: int) -> torch.Generator:
    """A CPU ``torch.Generator`` seeded with ``seed``; pass it to every draw explicitly."""
    gen = torch.Generator()
    gen.manual_seed(seed)
    return gen


def mlp(
    sizes: Sequence[int],
    activation: type[nn.Module],
    generator: torch.Generator,
    out_gain: float = 1.0,
) -> nn.Sequential:
    """``sizes[0] -> ... -> sizes[-1]`` linear layers with ``activation`` between them.

    Orthogonal weights (gain sqrt(2) inside, ``out_gain`` on the last layer) and zero biases,
    the PPO initialisation of CleanRL (Huang et al. 2022, "The 37 Implementation Details of
    PPO"), drawn from ``generator``.
    """
    layers: list[nn.Module] = []
    for i, (n_in, n_out) in enumerate(zip(sizes[:-1], sizes[1:], strict=True)):
        # skip_init: nn.Linear's own initialisation would draw from torch's global RNG.
        layer = nn.utils.skip_init(nn.Linear, n_in, n_out)
        last = i == len(sizes) - 2
        with torch.no_grad():
            nn.init.orthogonal_(layer.weight, out_gain if last else math.sqrt(2), generator)
            layer.bias.zero_()
        layers.append(layer)
        if not last:
            layers.append(activation())
    return nn.Sequential(*layers)


def soft_update(target: nn.Module, source: nn.Module, tau: float) -> None:
    """Polyak averaging of parameters: ``target <- (1 - tau) target + tau source``."""
    with torch.no_grad():
        for t, s in zip(target.parameters(), source.parameters(), strict=True):
            t.mul_(1.0 - tau).add_(s, alpha=tau)


def gae(
    rewards: torch.Tensor,
    values: torch.Tensor,
    dones: torch.Tensor,
    last_value: torch.Tensor,
    gamma: float,
    lam: float,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Generalised advantage estimation (Schulman et al. 2016, Eqs. 11-16).

    One backward pass over time, vectorised over every other axis::

        delta_t = r_t + gamma (1 - done_t) V(s_{t+1}) - V(s_t)
        A_t     = delta_t + gamma lam (1 - done_t) A_{t+1}

    Args:
        rewards: (T, ...) reward of transition t.
        values: (T, ...) V(s_t).
        dones: (T, ...) 1 where transition t ended its episode (no bootstrap from t + 1;
            the next row starts a new episode), else 0.
        last_value: (...) V of the state after transition T - 1 (used unless it ended).
        gamma: discount factor.
        lam: GAE's lambda.

    Returns:
        advantages (T, ...) and returns = advantages + values (the value targets).
    """
    advantages = torch.zeros_like(values)
    next_advantage = torch.zeros_like(last_value)
    next_value = last_value
    for t in reversed(range(rewards.shape[0])):
        alive = 1.0 - dones[t].to(values.dtype)
        delta = rewards[t] + gamma * alive * next_value - values[t]
        next_advantage = delta + gamma * lam * alive * next_advantage
        advantages[t] = next_advantage
        next_value = values[t]
    return advantages, advantages + values


def ccea_genome(
    w1: torch.Tensor, b1: torch.Tensor, w2: torch.Tensor, b2: torch.Tensor
) -> np.ndarray:
    """A CCEA genome ``W1 (n_in x H) | b1 (H) | W2 (H x 2) | b2 (2)`` (float32, the layout of
    :class:`physrover.learn.policies.PolicyLayout`) from (in, out) weights and biases;
    leading axes (e.g. rovers) are kept: (..., P)."""
    lead = w1.shape[:-2]
    parts = [p.detach().reshape(*lead, -1) for p in (w1, b1, w2, b2)]
    return torch.cat(parts, dim=-1).numpy().astype(np.float32)


# ----------------------------------------------------------------------------------------------
# Episodes
# ----------------------------------------------------------------------------------------------


@dataclasses.dataclass
class Episodes:
    """One batch of whole episodes played on a vector env (T steps, E teams, R rovers)."""

    obs: np.ndarray
    """(T + 1, E, R, n_obs) float32: observation before each step, then the final one."""
    rewards: np.ndarray
    """(T, E, R) float32: each rover's reward of each step
    (:func:`~physrover.domain.scoring.credit.step_rewards`)."""
    G: np.ndarray
    """(E,) the team score G at the end of each episode."""


def run_episodes(
    env: RoverVectorEnv,
    act: Callable[[np.ndarray, int], np.ndarray],
    reward: str = "G",
) -> Episodes:
    """Reset ``env`` and play one whole episode per team.

    Args:
        env: the vector env; its generators continue from their state (fresh episodes).
        act: ``act(obs (E, R, n_obs), t) -> actions (E, R, 2)`` at step t = 0..T-1.
        reward: the credit signal of the rewards returned, "G" or a registered one
            (:func:`~physrover.domain.scoring.credit.step_rewards`).
    """
    steps = env.config.steps
    obs, _ = env.reset()
    all_obs = np.empty((steps + 1, *obs.shape), dtype=np.float32)
    rewards = np.zeros((steps, *obs.shape[:2]), dtype=np.float32)
    all_obs[0] = obs
    for t in range(steps):
        obs, team_reward, _, _, infos = env.step(act(obs, t))
        all_obs[t + 1] = obs
        rewards[t] = step_rewards(reward, env.world, t == steps - 1, team_reward)
    return Episodes(all_obs, rewards, np.asarray(infos["G"], dtype=np.float64).copy())


# ----------------------------------------------------------------------------------------------
# The trainer's bookkeeping
# ----------------------------------------------------------------------------------------------


class Trainer:
    """What a gradient-based baseline shares: envs, random streams, counters, evaluation,
    checkpoints. Subclasses build their networks in ``__init__`` (from ``self.init_gen``),
    register them in ``modules`` / ``optimizers``, and implement:

    - ``_train(stats)``: collect ``num_envs`` whole episodes with the training env, update
      the networks, return the iteration's final G per episode (E,) and add loss values to
      ``stats``;
    - ``act(obs)``: deterministic actions (E, R, 2) of the current policies;
    - ``policy_genomes()``: the (R, P) genomes of the current policies in the CCEA layout.

    Random streams (from ``config.seed``): network initialisation (``init_gen``), every draw
    of training (``gen``: action noise, mini-batch order, replay samples), the training env's
    start states and the evaluation env's start states.
    """

    modules: dict[str, nn.Module]
    optimizers: dict[str, torch.optim.Optimizer]
    STATS: tuple[str, ...] = ()
    """The keys ``_train`` adds to an iteration's stats (its losses), in the order a run's
    metrics.csv gives them columns (:mod:`physrover.experiment.trainer_runs`)."""

    def __init__(self, config: MARLConfig, domain: DomainConfig | None = None):
        self.config = config
        self.domain = domain if domain is not None else DomainConfig()
        obs_space, action_space = team_spaces(self.domain)
        self.n_rovers, self.n_obs = obs_space.shape
        self.n_act = action_space.shape[-1]
        self.steps = self.domain.steps
        init_seed, draw_seed, env_seed, eval_seed = seed_streams(config.seed, 4)
        self.init_gen = torch_generator(init_seed)
        self.gen = torch_generator(draw_seed)
        self.env = RoverVectorEnv(config.num_envs, config=self.domain)
        self.env.reset(seed=env_seed)
        self.eval_env = RoverVectorEnv(config.eval_episodes, config=self.domain,
                                       fresh_teams=config.eval_episodes)  # fmt: skip
        self.eval_env.reset(seed=eval_seed)
        self.curriculum = None  # a coupling curriculum: follow_curriculum()
        self.iterations = 0
        """Iterations completed."""
        self.wall_seconds = 0.0
        """Seconds spent in training iterations, summed across resumes (excludes checkpoints)."""
        self.modules, self.optimizers = {}, {}

    # -- hooks -------------------------------------------------------------------------------

    def _train(self, stats: dict[str, float]) -> np.ndarray:
        raise NotImplementedError

    def act(self, obs: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def policy_genomes(self) -> np.ndarray:
        raise NotImplementedError

    def _extra_state(self) -> tuple[dict[str, np.ndarray], dict]:
        """Algorithm state beyond networks and optimisers (e.g. a replay buffer)."""
        return {}, {}

    def _load_extra_state(self, arrays: dict[str, np.ndarray], meta: dict) -> None:
        pass

    def follow_curriculum(self, curriculum) -> None:
        """Before the first iteration: train at the coupling of ``curriculum`` (a
        :class:`~physrover.learn.curriculum.CouplingCurriculum`), which tightens on the
        evaluations (at the domain's coupling) rescored at it, ``patience`` logging points
        in a row; ``iteration()`` then reports ``train_n_req``."""
        self.curriculum = curriculum
        self._rules = replay_rules(self.eval_env.world)
        self.env.world.set_coupling(curriculum.n_req)

    # -- one iteration -----------------------------------------------------------------------

    @property
    def total_iterations(self) -> int:
        """Iterations of the whole run: ceil(total_episodes / num_envs)."""
        return self.config.total_iterations

    @property
    def episodes(self) -> int:
        """Training episodes played so far (evaluation episodes are not counted)."""
        return self.iterations * self.config.num_envs

    @property
    def env_steps(self) -> int:
        """Team steps of training so far: episodes x steps."""
        return self.episodes * self.steps

    def time_input(self, t: torch.Tensor | float) -> torch.Tensor:
        """The critics' time input t / steps (zero with ``time_feature=False``)."""
        t = torch.as_tensor(t, dtype=torch.float32)
        return t / self.steps if self.config.time_feature else torch.zeros_like(t)

    def iteration(self, evaluate: bool = True) -> dict[str, float]:
        """Play ``num_envs`` episodes, update, evaluate at logging points (never with
        ``evaluate=False``: a learner inside another loop, :mod:`physrover.learn.hybrid`);
        returns the stats.

        Keys: ``iteration`` (from 1), ``episodes`` and ``env_steps`` (cumulative, training
        only), ``eval_G`` (mean G of the deterministic policies on ``eval_episodes`` fresh
        episodes after this iteration's update; NaN when this is not a logging point),
        ``train_G_mean`` (mean G of this iteration's training episodes, at ``train_n_req``
        under a curriculum: :meth:`follow_curriculum`), the algorithm's
        losses, ``wall_seconds`` (cumulative, includes evaluation) and
        ``env_steps_per_second`` (this iteration's training team steps over its training
        time: collection and update, without evaluation).
        """
        start = time.perf_counter()
        stats: dict[str, float] = {}
        if self.curriculum is not None:  # the coupling this iteration trains at
            stats["train_n_req"] = self.curriculum.train_n_req
        G = self._train(stats)
        trained = time.perf_counter()
        self.iterations += 1
        eval_G = math.nan
        if evaluate and self.iterations % self.config.log_every == 0:
            eval_G = self.evaluate()
            if self.curriculum is not None:
                self.curriculum.follow(self.eval_env.world, self.env.world, self._rules)
        self.wall_seconds += time.perf_counter() - start
        return {
            "iteration": self.iterations,
            "episodes": self.episodes,
            "env_steps": self.env_steps,
            "eval_G": eval_G,
            "train_G_mean": float(G.mean()),
            **stats,
            "wall_seconds": self.wall_seconds,
            "env_steps_per_second": self.config.num_envs * self.steps / (trained - start),
        }

    def evaluate(self, episodes: int | None = None, seed: int | None = None) -> float:
        """Mean G of the current deterministic policies on fresh episodes.

        Without ``seed``: on ``eval_episodes`` episodes of the dedicated evaluation stream,
        which advances (each call sees new start states; part of the checkpoint). With
        ``seed``: on ``episodes`` (default ``eval_episodes``) episodes of a new env, episode i
        starting like ``RoverEnv.reset(seed=seed + i)``; the trainer's streams are untouched."""
        if seed is None:
            if episodes not in (None, self.config.eval_episodes):
                raise ValueError("evaluate(episodes=N) needs a seed for the N fresh episodes")
            env = self.eval_env
        else:
            n = episodes or self.config.eval_episodes
            env = RoverVectorEnv(n, config=self.domain, fresh_teams=n)
            env.reset(seed=seed)
        return float(run_episodes(env, lambda obs, t: self.act(obs)).G.mean())

    # -- checkpoints -------------------------------------------------------------------------

    def state(self) -> tuple[dict[str, np.ndarray], dict]:
        """Everything needed to continue bit-identically, as (arrays, JSON-serialisable meta):
        network parameters (``module/NAME/PARAM``), optimiser moments
        (``optimizer/NAME/INDEX/KEY``), torch generator states (``rng/NAME``) and the
        algorithm's extra arrays; meta holds counters, env generator states and extras."""
        arrays: dict[str, np.ndarray] = {}
        for name, module in self.modules.items():
            for key, value in module.state_dict().items():
                arrays[f"module/{name}/{key}"] = value.detach().numpy().copy()
        for name, optimizer in self.optimizers.items():
            for index, slots in optimizer.state_dict()["state"].items():
                for key, value in slots.items():
                    arrays[f"optimizer/{name}/{index}/{key}"] = value.detach().numpy().copy()
        for name in ("init_gen", "gen"):
            arrays[f"rng/{name}"] = getattr(self, name).get_state().numpy().copy()
        extra_arrays, extra_meta = self._extra_state()
        arrays.update({f"extra/{k}": v for k, v in extra_arrays.items()})
        meta = {
            "iterations": self.iterations,
            "wall_seconds": self.wall_seconds,
            "env_rng": self.env.rng_states(),
            "eval_env_rng": self.eval_env.rng_states(),
            "extra": extra_meta,
        }
        if self.curriculum is not None:
            meta["curriculum"] = self.curriculum.state()
        return arrays, meta

    def load_state(self, arrays: dict[str, np.ndarray], meta: dict) -> None:
        """Restore a :meth:`state` into a trainer built with the same configs."""
        for name, module in self.modules.items():
            prefix = f"module/{name}/"
            saved = {k[len(prefix) :]: torch.tensor(v) for k, v in arrays.items()
                     if k.startswith(prefix)}  # fmt: skip
            module.load_state_dict(saved)
        for name, optimizer in self.optimizers.items():
            prefix = f"optimizer/{name}/"
            slots: dict[int, dict[str, torch.Tensor]] = {}
            for key, value in arrays.items():
                if key.startswith(prefix):
                    index, slot = key[len(prefix) :].split("/")
                    slots.setdefault(int(index), {})[slot] = torch.tensor(value)
            # Hyper-parameters come from the config; only the moments are state.
            groups = optimizer.state_dict()["param_groups"]
            optimizer.load_state_dict({"state": slots, "param_groups": groups})
        for name in ("init_gen", "gen"):
            getattr(self, name).set_state(torch.tensor(arrays[f"rng/{name}"]))
        self.iterations = int(meta["iterations"])
        self.wall_seconds = float(meta["wall_seconds"])
        self.env.set_rng_states(meta["env_rng"])
        self.eval_env.set_rng_states(meta["eval_env_rng"])
        if self.curriculum is not None:
            self.curriculum.load(meta["curriculum"])
            self.env.world.set_coupling(self.curriculum.n_req)
        extra = {k[len("extra/") :]: v for k, v in arrays.items() if k.startswith("extra/")}
        self._load_extra_state(extra, meta["extra"])

    @property
    def generation(self) -> int:
        """Iterations completed, under the CCEA's name for what run directories count."""
        return self.iterations

    def champion_genomes(self) -> np.ndarray:
        """(R, P) float32: :meth:`policy_genomes`, under the CCEA's name for the team that
        run directories checkpoint and ``render`` / ``evaluate`` play."""
        return self.policy_genomes()


def to_tensor(array: np.ndarray) -> torch.Tensor:
    """A float32 tensor sharing memory with ``array`` where possible."""
    return torch.from_numpy(np.ascontiguousarray(array, dtype=np.float32))
