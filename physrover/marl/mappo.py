"""MAPPO and IPPO: PPO with one policy shared by every rover.

Yu et al. 2022, "The Surprising Effectiveness of PPO in Cooperative Multi-Agent Games"
(NeurIPS Datasets and Benchmarks): PPO (Schulman et al. 2017) with parameters shared by
the agents, a centralised value function, GAE (Schulman et al. 2016) and a clipped
surrogate. ``centralised_critic=False`` gives IPPO (de Witt et al. 2020, "Is Independent
Learning All You Need in the StarCraft Multi-Agent Challenge?"): each rover's value from
its own observation. Written in the manner of CleanRL's ``ppo_continuous_action.py``.

**The policy** is the CCEA's shape, n_obs -> ``hidden`` -> 2 (ReLU, then tanh), shared by
the R rovers; its output is the mean of a Gaussian with a learnt, state-independent
log-std. **Actions are clipped, not squashed**: a sample ``u ~ N(mean, std)`` goes to the
env as ``clip(u, -1, 1)`` and PPO's ratios use the log-density of ``u`` itself, so the
clipping is part of the environment and the log-probabilities are exact for the
distribution sampled (as CleanRL's ``ppo_continuous_action.py`` does). Evaluation plays
the mean, which tanh keeps inside (-1, 1): the evaluated policy is a CCEA genome
(:meth:`MAPPO.policy_genomes`).

**The value function** maps the team's concatenated observations (R x n_obs), plus the
elapsed fraction of the episode (``time_feature``), to one value per rover (R outputs: the
rovers' returns differ under ``reward="D"``); IPPO's maps a rover's own observation (plus
time) to its value. Episodes end at the step limit, which is treated as the true end of
the episode (no bootstrap past it).

**One iteration** plays ``num_envs`` whole episodes (one per team, ``num_envs x steps``
team steps) with the current stochastic policy, computes GAE over them, then runs
``epochs`` passes of ``minibatches`` mini-batches over the ``steps x num_envs`` team steps
(every rover of a team step in the same mini-batch). A run of ``total_episodes`` episodes
has ceil(total_episodes / num_envs) iterations.
"""

from __future__ import annotations

import math

import numpy as np
import torch
from torch import nn

from physrover.config import ConfigError, DomainConfig
from physrover.marl.common import (
    Trainer,
    ccea_genome,
    gae,
    mlp,
    run_episodes,
    to_tensor,
)
from physrover.marl.configs import MAPPOConfig

LOG_SQRT_2PI = 0.5 * math.log(2 * math.pi)


class Agent(nn.Module):
    """The shared Gaussian policy and the value network.

    Shapes: observations (..., R, n_obs), time (...) (t / steps), actions (..., R, 2),
    log-probabilities and values (..., R).
    """

    def __init__(self, n_rovers: int, n_obs: int, config: MAPPOConfig, generator):
        super().__init__()
        self.centralised = config.centralised_critic
        self.policy = mlp([n_obs, config.hidden, 2], nn.ReLU, generator, out_gain=0.01)
        self.log_std = nn.Parameter(torch.full((2,), config.init_log_std))
        value_in = (n_rovers * n_obs if self.centralised else n_obs) + 1
        value_out = n_rovers if self.centralised else 1
        h = config.value_hidden
        self.value_net = mlp([value_in, h, h, value_out], nn.Tanh, generator, out_gain=1.0)

    def mean(self, obs: torch.Tensor) -> torch.Tensor:
        """(..., R, 2) the policy's mean action, in (-1, 1): the deterministic policy."""
        return torch.tanh(self.policy(obs))

    def log_prob(self, mean: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
        """(..., R) log-density of the unclipped samples ``u`` under N(mean, exp(log_std))."""
        z = (u - mean) * torch.exp(-self.log_std)
        return (-0.5 * z.square() - self.log_std - LOG_SQRT_2PI).sum(-1)

    def entropy(self) -> torch.Tensor:
        """Entropy of the (state-independent) Gaussian, a scalar."""
        return (0.5 + LOG_SQRT_2PI + self.log_std).sum()

    def value(self, obs: torch.Tensor, time: torch.Tensor) -> torch.Tensor:
        """(..., R) value of each rover."""
        if self.centralised:
            x = torch.cat([obs.flatten(-2), time[..., None]], dim=-1)
            return self.value_net(x)
        time = time[..., None, None].expand(*obs.shape[:-1], 1)
        return self.value_net(torch.cat([obs, time], dim=-1)).squeeze(-1)


class MAPPO(Trainer):
    """MAPPO (or IPPO) on a :class:`physrover.RoverVectorEnv`; see the module docstring.

    ``MAPPO(config, domain)``; ``iteration()`` advances one iteration and returns its stats
    (:meth:`physrover.marl.common.Trainer.iteration`; losses ``policy_loss``,
    ``value_loss``, ``entropy``, ``approx_kl``, ``clip_fraction``, ``std``, averaged over
    the iteration's mini-batches); ``evaluate()``, ``state()`` / ``load_state()`` as there.
    """

    STATS = ("policy_loss", "value_loss", "entropy", "approx_kl", "clip_fraction", "std")
    """The losses and diagnostics :meth:`iteration` returns beside the shared keys."""

    def __init__(self, config: MAPPOConfig, domain: DomainConfig | None = None):
        super().__init__(config, domain)
        n_team_steps = config.num_envs * self.steps
        if config.minibatches > n_team_steps:
            raise ConfigError(
                "minibatches",
                f"must be <= num_envs x steps = {n_team_steps} team steps, "
                f"got {config.minibatches}",
            )
        self.agent = Agent(self.n_rovers, self.n_obs, config, self.init_gen)
        self.optimizer = torch.optim.Adam(self.agent.parameters(), lr=config.lr, eps=1e-5)
        self.modules = {"agent": self.agent}
        self.optimizers = {"agent": self.optimizer}

    def act(self, obs: np.ndarray) -> np.ndarray:
        """(E, R, 2) deterministic actions (the policy's mean) for (E, R, n_obs) obs."""
        with torch.no_grad():
            return self.agent.mean(to_tensor(obs)).numpy()

    def policy_genomes(self) -> np.ndarray:
        """(R, P) the shared policy as one CCEA genome per rover (all rows equal)."""
        first, _, last = self.agent.policy
        genome = ccea_genome(first.weight.T, first.bias, last.weight.T, last.bias)
        return np.repeat(genome[None], self.n_rovers, axis=0)

    def _collect(self):
        """Play one episode per team with the stochastic policy; returns the episodes and
        the (T, E, R, ...) unclipped actions, their log-probs and the values."""
        T, E, R = self.steps, self.config.num_envs, self.n_rovers
        samples = torch.empty(T, E, R, 2)
        log_probs = torch.empty(T, E, R)
        values = torch.empty(T, E, R)

        def act(obs: np.ndarray, t: int) -> np.ndarray:
            with torch.no_grad():
                o = to_tensor(obs)
                mean = self.agent.mean(o)
                noise = torch.randn(mean.shape, generator=self.gen)
                u = mean + torch.exp(self.agent.log_std) * noise
                samples[t] = u
                log_probs[t] = self.agent.log_prob(mean, u)
                values[t] = self.agent.value(o, self.time_input(torch.full((E,), t)))
            return u.clamp(-1.0, 1.0).numpy()

        episodes = run_episodes(self.env, act, self.config.reward)
        return episodes, samples, log_probs, values

    def _train(self, stats: dict[str, float]) -> np.ndarray:
        cfg, T, E = self.config, self.steps, self.config.num_envs
        episodes, samples, old_log_probs, old_values = self._collect()
        rewards = torch.from_numpy(episodes.rewards)
        dones = torch.zeros(T, E, self.n_rovers)
        dones[-1] = 1.0  # the step limit ends the episode
        advantages, returns = gae(
            rewards, old_values, dones, torch.zeros(E, self.n_rovers), cfg.gamma, cfg.gae_lambda
        )
        # Flatten (T, E) into N team steps; each keeps its R rovers together.
        n = T * E
        obs = torch.from_numpy(episodes.obs[:-1]).reshape(n, self.n_rovers, self.n_obs)
        times = self.time_input(torch.arange(T).repeat_interleave(E))
        samples, old_log_probs, old_values, advantages, returns = (
            x.reshape(n, *x.shape[2:])
            for x in (samples, old_log_probs, old_values, advantages, returns)
        )

        totals = dict.fromkeys(
            ("policy_loss", "value_loss", "entropy", "approx_kl", "clip_fraction"), 0.0
        )
        n_batches = 0
        for _ in range(cfg.epochs):
            order = torch.randperm(n, generator=self.gen)
            for batch in order.tensor_split(cfg.minibatches):
                mean = self.agent.mean(obs[batch])
                log_ratio = self.agent.log_prob(mean, samples[batch]) - old_log_probs[batch]
                ratio = log_ratio.exp()
                adv = advantages[batch]
                if cfg.norm_advantages:
                    adv = (adv - adv.mean()) / (adv.std() + 1e-8)
                policy_loss = torch.max(
                    -adv * ratio, -adv * ratio.clamp(1 - cfg.clip, 1 + cfg.clip)
                ).mean()

                value = self.agent.value(obs[batch], times[batch])
                value_error = (value - returns[batch]).square()
                if cfg.clip_value_loss:
                    clipped = old_values[batch] + (value - old_values[batch]).clamp(
                        -cfg.clip, cfg.clip
                    )
                    value_error = torch.max(value_error, (clipped - returns[batch]).square())
                value_loss = 0.5 * value_error.mean()

                entropy = self.agent.entropy()
                loss = policy_loss - cfg.entropy_coef * entropy + cfg.value_coef * value_loss
                self.optimizer.zero_grad()
                loss.backward()
                nn.utils.clip_grad_norm_(self.agent.parameters(), cfg.max_grad_norm)
                self.optimizer.step()

                with torch.no_grad():  # Schulman's k3 estimator of KL(old || new)
                    approx_kl = ((ratio - 1) - log_ratio).mean()
                    clipped_share = ((ratio - 1).abs() > cfg.clip).float().mean()
                for key, x in zip(
                    totals,
                    (policy_loss, value_loss, entropy, approx_kl, clipped_share),
                    strict=True,
                ):
                    totals[key] += float(x.detach())
                n_batches += 1
        stats.update({key: total / n_batches for key, total in totals.items()})
        stats["std"] = float(torch.exp(self.agent.log_std.detach()).mean())
        return episodes.G
