"""MADDPG: decentralised deterministic actors, one centralised critic per rover.

Lowe et al. 2017, "Multi-Agent Actor-Critic for Mixed Cooperative-Competitive
Environments" (NeurIPS): DDPG (Lillicrap et al. 2016) per agent, where agent i's critic
Q_i(x, a_1, ..., a_R) sees every agent's observation and action while its actor
mu_i(o_i) sees only its own observation; a replay buffer, target networks with soft
updates, and Gaussian exploration noise on the actions (the paper's continuous-action form),
with two details of Lowe et al.'s code: a penalty on the actors' squared pre-tanh outputs
(``action_penalty``, 1e-3) and each variable's gradient clipped to norm 0.5 per agent
(``grad_clip``; since physrover 0.2.0: an older run resumed by this release gains both).
Without them our actors drifted into tanh's saturation on the paper's task (a flat critic,
Adam turning its tiny gradients into full steps) and stopped learning.

**Actors**: one per rover, the CCEA's policy shape n_obs -> ``hidden`` -> 2 (ReLU, then
tanh), so each exports as a CCEA genome (:meth:`MADDPG.policy_genomes`). **Critics**: one
per rover, (R x n_obs + R x 2 [+ 1 time input]) -> ``critic_hidden`` -> ``critic_hidden``
-> 1 (ReLU). The R actors (and the R critics) are one module of stacked weights
(:func:`stacked_mlp`), so a step of every team, and every update, is a few batched matrix
products with no Python loop over rovers; Adam is element-wise, so one Adam over the
stacked weights is R independent Adams. Actions in training are
``clip(mu_i(o_i) + noise_std x N(0, 1), -1, 1)``, with fixed ``noise_std``; evaluation
plays ``mu_i(o_i)``.

Updates (Lowe et al.'s Algorithm 1): from a uniformly sampled mini-batch of team
transitions, each critic regresses ``y_i = r_i + gamma (1 - done) Q'_i(x', mu'_1(o'_1),
..., mu'_R(o'_R))`` with the target networks; each actor ascends ``Q_i(x, a_1, ...,
mu_i(o_i), ..., a_R)`` (its own action from its current actor, the others' from the
buffer); then every target moves by ``tau`` (:func:`~physrover.marl.common.soft_update`).
The step limit ends an episode (``done``), so nothing is bootstrapped past it.

**One iteration** plays ``num_envs`` whole episodes (``num_envs x steps`` team steps, one
transition each) with the noisy actors, adds them to the replay buffer, then makes one
update of every critic and actor per ``update_every`` transitions collected once the buffer
holds ``warmup_steps`` transitions (the remainder carries over to the next iteration). A
run of ``total_episodes`` episodes has ceil(total_episodes / num_envs) iterations.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Mapping

import numpy as np
import torch
from torch import nn

from physrover.config import DomainConfig
from physrover.marl.common import (
    Trainer,
    ccea_genome,
    run_episodes,
    soft_update,
    to_tensor,
)
from physrover.marl.configs import MADDPGConfig

# ----------------------------------------------------------------------------------------------
# Networks: R independent MLPs as stacked weights
# ----------------------------------------------------------------------------------------------


class StackedLinear(nn.Module):
    """R independent linear layers: (..., R, n_in) -> (..., R, n_out).

    ``weight`` is (R, n_in, n_out) (input-major, as the CCEA genome stores it), ``bias``
    (R, n_out); both start uniform in +-``bound``, by default +-1/sqrt(n_in) (PyTorch's
    default for a linear layer, and the CCEA's initialisation), drawn from ``generator``.
    """

    def __init__(
        self,
        n: int,
        n_in: int,
        n_out: int,
        generator: torch.Generator,
        bound: float | None = None,
    ):
        super().__init__()
        bound = 1.0 / math.sqrt(n_in) if bound is None else bound

        def uniform(*shape: int) -> nn.Parameter:
            return nn.Parameter((torch.rand(shape, generator=generator) * 2 - 1) * bound)

        self.weight = uniform(n, n_in, n_out)
        self.bias = uniform(n, n_out)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return torch.einsum("...ri,rio->...ro", x, self.weight) + self.bias


def clip_per_rover(params, max_norm: float) -> None:
    """Clip the gradient of each of stacked ``params`` (leading axis R) rover by rover to
    norm ``max_norm`` at most, each tensor on its own: rover r's slice of a weight or bias
    is scaled by ``min(1, max_norm / norm)``, as Lowe et al.'s code clips each variable of
    an agent's network (``tf.clip_by_norm``)."""
    if max_norm <= 0:
        return
    for p in params:
        if p.grad is None:
            continue
        norm = p.grad.flatten(1).norm(dim=1)  # (R,)
        scale = torch.where(norm > max_norm, max_norm / norm.clamp(min=1e-30), 1.0)
        p.grad.mul_(scale.view(-1, *([1] * (p.grad.dim() - 1))))


def stacked_mlp(
    n: int,
    sizes: list[int],
    activation: type[nn.Module],
    generator: torch.Generator,
    out_bound: float = 3e-3,
) -> nn.Sequential:
    """``n`` independent MLPs ``sizes[0] -> ... -> sizes[-1]`` with ``activation`` between
    layers: (..., n, sizes[0]) -> (..., n, sizes[-1]). The last layer starts uniform in
    +-``out_bound`` (DDPG's 3e-3, Lillicrap et al. 2016: initial actions and values near 0)."""
    layers: list[nn.Module] = []
    for i, (n_in, n_out) in enumerate(zip(sizes[:-1], sizes[1:], strict=True)):
        last = i == len(sizes) - 2
        layers.append(StackedLinear(n, n_in, n_out, generator, out_bound if last else None))
        if not last:
            layers.append(activation())
    return nn.Sequential(*layers)


# ----------------------------------------------------------------------------------------------
# Replay buffer
# ----------------------------------------------------------------------------------------------


class ReplayBuffer:
    """A fixed-capacity ring buffer of transitions, stored field by field.

    Order: ``add`` writes the rows of its batch in order, row i to slot
    ``(pointer + i) % capacity``, then advances ``pointer`` by the batch length; once the
    buffer is full each new row overwrites the oldest, so it always holds the newest
    ``size = min(rows added, capacity)`` rows (a batch longer than the capacity keeps its
    last ``capacity`` rows). ``sample`` draws rows uniformly with replacement.

    Args:
        capacity: rows held.
        fields: name -> (shape of one row, dtype), e.g. ``{"obs": ((R, 8), torch.float32)}``.
    """

    def __init__(self, capacity: int, fields: Mapping[str, tuple[tuple[int, ...], torch.dtype]]):
        self.capacity = capacity
        self.data = {
            name: torch.zeros((capacity, *shape), dtype=dtype)
            for name, (shape, dtype) in fields.items()
        }
        self.pointer = 0
        self.size = 0

    def add(self, **rows: np.ndarray | torch.Tensor) -> None:
        """Append a batch: every field of the buffer, each with the same leading length N."""
        if set(rows) != set(self.data):
            raise ValueError(f"add() needs the fields {sorted(self.data)}, got {sorted(rows)}")
        n = len(next(iter(rows.values())))
        kept = min(n, self.capacity)
        slots = (self.pointer + (n - kept) + torch.arange(kept)) % self.capacity
        for name, value in rows.items():
            value = torch.as_tensor(value)
            if len(value) != n:
                raise ValueError(f"every field needs {n} rows; {name} has {len(value)}")
            self.data[name][slots] = value[n - kept :].to(self.data[name].dtype)
        self.pointer = (self.pointer + n) % self.capacity
        self.size = min(self.size + n, self.capacity)

    def sample(self, batch_size: int, generator: torch.Generator) -> dict[str, torch.Tensor]:
        """``batch_size`` rows drawn uniformly with replacement from the ``size`` held."""
        if self.size == 0:
            raise ValueError("cannot sample from an empty replay buffer")
        index = torch.randint(self.size, (batch_size,), generator=generator)
        return {name: value[index] for name, value in self.data.items()}

    def state(self) -> tuple[dict[str, np.ndarray], dict]:
        """(arrays of the ``size`` filled slots, {"pointer", "size"})."""
        arrays = {name: value[: self.size].numpy().copy() for name, value in self.data.items()}
        return arrays, {"pointer": self.pointer, "size": self.size}

    def load_state(self, arrays: Mapping[str, np.ndarray], meta: Mapping) -> None:
        self.size, self.pointer = int(meta["size"]), int(meta["pointer"])
        for name, value in self.data.items():
            value.zero_()
            value[: self.size] = torch.as_tensor(arrays[name])


# ----------------------------------------------------------------------------------------------
# The trainer
# ----------------------------------------------------------------------------------------------


class MADDPG(Trainer):
    """MADDPG on a :class:`physrover.RoverVectorEnv`; see the module docstring.

    ``MADDPG(config, domain)``; ``iteration()`` advances one iteration and returns its
    stats (:meth:`physrover.marl.common.Trainer.iteration`; ``critic_loss`` (mean over the
    rovers' critics of their squared TD error), ``actor_loss`` (mean over rovers of
    -Q_i plus the pre-tanh penalty), ``q_mean``, averaged over this iteration's updates,
    NaN without any, and ``updates``, the updates made so far); ``evaluate()``,
    ``state()`` / ``load_state()`` as there (the state includes the replay buffer).
    """

    STATS = ("critic_loss", "actor_loss", "q_mean", "updates")
    """The losses and diagnostics :meth:`iteration` returns beside the shared keys."""

    def __init__(self, config: MADDPGConfig, domain: DomainConfig | None = None):
        super().__init__(config, domain)
        R, n_obs, n_act = self.n_rovers, self.n_obs, self.n_act
        g = self.init_gen
        self.actors = stacked_mlp(R, [n_obs, config.hidden, n_act], nn.ReLU, g)
        critic_in = R * (n_obs + n_act) + 1
        h = config.critic_hidden
        self.critics = stacked_mlp(R, [critic_in, h, h, 1], nn.ReLU, g)
        self.target_actors = copy.deepcopy(self.actors)
        self.target_critics = copy.deepcopy(self.critics)
        for target in (self.target_actors, self.target_critics):
            target.requires_grad_(False)
        self.actor_optimizer = torch.optim.Adam(self.actors.parameters(), lr=config.actor_lr)
        self.critic_optimizer = torch.optim.Adam(self.critics.parameters(), lr=config.critic_lr)
        self.modules = {
            "actors": self.actors,
            "critics": self.critics,
            "target_actors": self.target_actors,
            "target_critics": self.target_critics,
        }
        self.optimizers = {"actors": self.actor_optimizer, "critics": self.critic_optimizer}
        self.buffer = ReplayBuffer(
            config.buffer_capacity,
            {
                "obs": ((R, n_obs), torch.float32),
                "actions": ((R, n_act), torch.float32),
                "rewards": ((R,), torch.float32),
                "next_obs": ((R, n_obs), torch.float32),
                "step": ((), torch.int64),  # t of the transition; done = (t == steps - 1)
            },
        )
        self.updates = 0
        """Updates (of every critic and actor) made so far."""
        self.update_credit = 0
        """Transitions collected since warm-up that no update has been made for yet."""
        self._eye = torch.eye(R, dtype=torch.bool)[..., None]  # (R, R, 1)

    # -- policies ----------------------------------------------------------------------------

    def _mu(self, actors: nn.Module, obs: torch.Tensor) -> torch.Tensor:
        """(..., R, 2) each rover's actor on its own observation (..., R, n_obs)."""
        return torch.tanh(actors(obs))

    def act(self, obs: np.ndarray) -> np.ndarray:
        """(E, R, 2) deterministic actions mu_i(o_i) for (E, R, n_obs) observations."""
        with torch.no_grad():
            return self._mu(self.actors, to_tensor(obs)).numpy()

    def policy_genomes(self) -> np.ndarray:
        """(R, P) each rover's actor as a CCEA genome."""
        first, _, last = self.actors
        return ccea_genome(first.weight, first.bias, last.weight, last.bias)

    # -- critics -----------------------------------------------------------------------------

    def _q(
        self, critics: nn.Module, obs: torch.Tensor, joint: torch.Tensor, step: torch.Tensor
    ) -> torch.Tensor:
        """(B, R) Q_i of each rover's critic.

        Args:
            obs: (B, R, n_obs) every rover's observation.
            joint: (B, R, R, 2): row i is the team's actions as critic i sees them.
            step: (B,) the step t of the transition.
        """
        B, R = joint.shape[:2]
        x = torch.cat(
            [
                obs.flatten(-2)[:, None].expand(B, R, -1),
                joint.flatten(-2),
                self.time_input(step)[:, None, None].expand(B, R, 1),
            ],
            dim=-1,
        )
        return critics(x).squeeze(-1)

    def _own_actions_from_actors(
        self, obs: torch.Tensor, actions: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """(B, R, R, 2) joint actions for the actor update: row i (critic i's input) has
        rover i's action from its current actor mu_i(o_i) (differentiable), the other
        rovers' from ``actions`` (B, R, 2), the buffer (Lowe et al. 2017, Eq. 6); and the
        actors' pre-tanh outputs (B, R, 2)."""
        pre = self.actors(obs)
        return torch.where(self._eye, torch.tanh(pre)[:, None], actions[:, None]), pre

    def actor_loss(
        self, obs: torch.Tensor, actions: torch.Tensor, step: torch.Tensor
    ) -> torch.Tensor:
        """Each actor's loss, summed over rovers: ``-Q_i(x, ..., mu_i(o_i), ...)`` (mean over
        the batch) plus ``action_penalty`` times the mean squared pre-tanh output."""
        joint, pre = self._own_actions_from_actors(obs, actions)
        loss = -self._q(self.critics, obs, joint, step).mean(0).sum()
        return loss + self.config.action_penalty * pre.square().mean((0, 2)).sum()

    def _update(self) -> tuple[float, float, float]:
        """One update of every critic, then every actor, then the targets; returns
        (critic_loss, actor_loss, q_mean)."""
        cfg, R = self.config, self.n_rovers
        batch = self.buffer.sample(cfg.batch_size, self.gen)
        obs, actions, step = batch["obs"], batch["actions"], batch["step"]
        B = len(step)
        with torch.no_grad():
            next_actions = self._mu(self.target_actors, batch["next_obs"])
            next_q = self._q(
                self.target_critics,
                batch["next_obs"],
                next_actions[:, None].expand(B, R, R, -1),
                step + 1,
            )
            alive = (step < self.steps - 1).float()[:, None]
            target = batch["rewards"] + cfg.gamma * alive * next_q
        q = self._q(self.critics, obs, actions[:, None].expand(B, R, R, -1), step)
        # Each critic's own mean squared error, summed: R independent regressions.
        critic_loss = (q - target).square().mean(0).sum()
        self.critic_optimizer.zero_grad()
        critic_loss.backward()
        clip_per_rover(list(self.critics.parameters()), cfg.grad_clip)
        self.critic_optimizer.step()

        actor_loss = self.actor_loss(obs, actions, step)
        self.actor_optimizer.zero_grad()
        actor_loss.backward()  # also fills the critics' grads; zeroed before their next step
        clip_per_rover(list(self.actors.parameters()), cfg.grad_clip)
        self.actor_optimizer.step()

        soft_update(self.target_actors, self.actors, cfg.tau)
        soft_update(self.target_critics, self.critics, cfg.tau)
        self.updates += 1
        return (
            float(critic_loss.detach()) / R,
            float(actor_loss.detach()) / R,
            float(q.detach().mean()),
        )

    # -- one iteration -----------------------------------------------------------------------

    def _train(self, stats: dict[str, float]) -> np.ndarray:
        cfg, T, E = self.config, self.steps, self.config.num_envs
        actions = torch.empty(T, E, self.n_rovers, self.n_act)

        uniform = cfg.warmup_actions == "uniform" and self.buffer.size < cfg.warmup_steps

        def act(obs: np.ndarray, t: int) -> np.ndarray:
            with torch.no_grad():
                if uniform:  # before the first update: uniform in [-1, 1]
                    shape = (*obs.shape[:-1], self.n_act)
                    actions[t] = torch.rand(shape, generator=self.gen) * 2.0 - 1.0
                    return actions[t].numpy()
                a = self._mu(self.actors, to_tensor(obs))
                noise = torch.randn(a.shape, generator=self.gen)
                actions[t] = (a + cfg.noise_std * noise).clamp(-1.0, 1.0)
            return actions[t].numpy()

        episodes = run_episodes(self.env, act, cfg.reward)
        # Transitions in time-major order: row t * E + e is step t of team e.
        obs = torch.from_numpy(episodes.obs)
        self.buffer.add(
            obs=obs[:-1].flatten(0, 1),
            actions=actions.flatten(0, 1),
            rewards=torch.from_numpy(episodes.rewards).flatten(0, 1),
            next_obs=obs[1:].flatten(0, 1),
            step=torch.arange(T).repeat_interleave(E),
        )
        if self.buffer.size >= cfg.warmup_steps:
            self.update_credit += T * E
        n_updates, self.update_credit = divmod(self.update_credit, cfg.update_every)
        losses = np.array([self._update() for _ in range(n_updates)]).reshape(-1, 3)
        means = losses.mean(0) if n_updates else np.full(3, math.nan)
        stats.update(
            critic_loss=float(means[0]),
            actor_loss=float(means[1]),
            q_mean=float(means[2]),
            updates=self.updates,
        )
        return episodes.G

    # -- checkpoints -------------------------------------------------------------------------

    def _extra_state(self) -> tuple[dict[str, np.ndarray], dict]:
        arrays, meta = self.buffer.state()
        arrays = {f"buffer/{k}": v for k, v in arrays.items()}
        return arrays, {"buffer": meta, "updates": self.updates, "credit": self.update_credit}

    def _load_extra_state(self, arrays: dict[str, np.ndarray], meta: dict) -> None:
        prefix = "buffer/"
        self.buffer.load_state(
            {k[len(prefix) :]: v for k, v in arrays.items() if k.startswith(prefix)},
            meta["buffer"],
        )
        self.updates = int(meta["updates"])
        self.update_credit = int(meta["credit"])
