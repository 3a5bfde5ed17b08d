"""The gradient-based baselines' configs, importable without torch.

Each algorithm's hyper-parameters are a typed, validated table (``[mappo]``, ``[maddpg]`` in a
run's config.toml), and each algorithm is registered by name in
:data:`physrover.core.registry.TRAINERS`, so ``physrover train --method mappo`` and config
validation know it without importing torch; :mod:`physrover.marl.mappo` and
:mod:`physrover.marl.maddpg` (which do import torch) hold the trainers themselves.
"""

from __future__ import annotations

import dataclasses
import math
from typing import ClassVar

from physrover.config import RESERVED_SECTIONS, ConfigBase, check, check_choice, settings_tables
from physrover.core.registry import CREDITS, FITNESS_METHODS, TRAINERS

# ----------------------------------------------------------------------------------------------
# Config
# ----------------------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class MARLConfig(ConfigBase):
    """Fields every gradient-based baseline has; subclasses add the algorithm's own."""

    section: ClassVar[str] = "marl"

    num_envs: int = 32
    """Teams run in parallel on the vector env; one iteration plays one episode per team."""
    total_episodes: int = 250_000
    """Training episodes of the whole run (the CCEA's budget at the paper's settings: 5000
    generations x 50 teams); the run has ceil(total_episodes / num_envs) iterations
    (:attr:`Trainer.total_iterations`). Read by the run loop, not the trainer."""
    hidden: int = 32
    """Hidden units of each rover's policy, n_obs -> hidden -> 2 (ReLU, then tanh), the
    CCEA's policy shape, so a trained actor exports as a CCEA genome."""
    reward: str = "G"
    """Credit signal, by the CCEA's names (``[learn] feedback``, the
    :data:`~physrover.core.registry.CREDITS` registry): "G" every rover gets the team's
    increase of G at each step (its rewards sum to G); any other ("D", "D++", "ID",
    "ID-step", a registered one) each rover gets its signal for the episode at the last
    step and 0 before (its rewards sum to it;
    :func:`~physrover.domain.scoring.credit.step_rewards`)."""
    time_feature: bool = True
    """Give the critics the elapsed fraction of the episode, t / steps, as an extra input:
    episodes end at a fixed step, so without it values are not a function of their input
    (Pardo et al. 2018, "Time Limits in Reinforcement Learning"). The actors never see it."""
    eval_episodes: int = 10
    """Fresh episodes of the current (deterministic) policies at each logging point."""
    log_every: int = 1
    """Evaluate (and report ``eval_G``) every this many iterations."""
    seed: int = 0
    """Seeds every random stream: network initialisation, sampling, env start states."""
    checkpoint_every: int = 50
    """Iterations between checkpoints (read by the run loop, not the trainer)."""

    def __post_init__(self) -> None:
        self._coerce_fields()
        self.check_at_least(
            1, "num_envs", "total_episodes", "hidden", "eval_episodes", "log_every",
            "checkpoint_every",
        )  # fmt: skip
        check(self.seed >= 0, "seed", f"must be >= 0, got {self.seed}")
        check(self.reward in CREDITS, "reward", CREDITS.unknown_message(self.reward))

    @property
    def total_iterations(self) -> int:
        """Iterations of the whole run: ceil(total_episodes / num_envs)."""
        return -(-self.total_episodes // self.num_envs)


@dataclasses.dataclass(frozen=True)
class MAPPOConfig(MARLConfig):
    """MAPPO / IPPO hyper-parameters (defaults after Yu et al. 2022 and CleanRL)."""

    section: ClassVar[str] = "mappo"

    value_hidden: int = 64
    """Hidden units of the value network's two hidden layers (tanh)."""
    lr: float = 3e-4
    """Adam learning rate of the policy and the value network."""
    gamma: float = 0.99
    """Discount factor."""
    gae_lambda: float = 0.95
    """GAE's lambda."""
    clip: float = 0.2
    """PPO's clipping range of the probability ratio (and of the value update)."""
    epochs: int = 5
    """Passes over an iteration's data."""
    minibatches: int = 4
    """Mini-batches per pass; each holds steps x num_envs / minibatches team steps."""
    entropy_coef: float = 0.0
    """Weight of the entropy bonus."""
    value_coef: float = 0.5
    """Weight of the value loss."""
    max_grad_norm: float = 0.5
    """Global gradient norm clip."""
    init_log_std: float = -0.5
    """Initial log standard deviation of the Gaussian (learnt, state-independent)."""
    norm_advantages: bool = True
    """Standardise advantages within each mini-batch."""
    clip_value_loss: bool = True
    """PPO's clipped value loss (the value moves at most ``clip`` from its rollout value)."""
    centralised_critic: bool = True
    """True: MAPPO, values from the whole team's observations; False: IPPO, each rover's
    value from its own observation."""

    def __post_init__(self) -> None:
        super().__post_init__()
        self.check_at_least(1, "value_hidden", "epochs", "minibatches")
        self.check_positive("lr", "clip", "max_grad_norm")
        self.check_unit("gamma", "gae_lambda")
        for name in ("entropy_coef", "value_coef"):
            value = getattr(self, name)
            check(value >= 0 and math.isfinite(value), name, f"must be >= 0, got {value}")
        check(
            math.isfinite(self.init_log_std),
            "init_log_std",
            f"must be finite, got {self.init_log_std}",
        )


@dataclasses.dataclass(frozen=True)
class MADDPGConfig(MARLConfig):
    """MADDPG hyper-parameters (defaults after Lowe et al. 2017 where the domain allows)."""

    section: ClassVar[str] = "maddpg"

    critic_hidden: int = 64
    """Hidden units of each critic's two hidden layers (ReLU)."""
    actor_lr: float = 1e-3
    """Adam learning rate of the actors."""
    critic_lr: float = 1e-3
    """Adam learning rate of the critics."""
    gamma: float = 0.95
    """Discount factor (Lowe et al.: 0.95)."""
    tau: float = 0.01
    """Soft update rate of the target networks (Lowe et al.: 0.01)."""
    batch_size: int = 1024
    """Team transitions per mini-batch (Lowe et al.: 1024)."""
    buffer_capacity: int = 100_000
    """Replay capacity, team transitions; the oldest are overwritten when full."""
    noise_std: float = 0.1
    """Standard deviation of the Gaussian exploration noise added to every action component
    (fixed over the run); the noisy action is clipped to [-1, 1]."""
    update_every: int = 100
    """Team transitions collected per update of every critic and actor (Lowe et al. train
    every 100 steps)."""
    warmup_steps: int = 25_600
    """Team transitions in the buffer before the first update (Lowe et al.: batch x 25);
    before it the actors act (with noise) but do not learn."""
    warmup_actions: str = "policy"
    """What acts before the first update: "policy" (the noisy actors, Lowe et al.) or
    "uniform" (actions uniform in [-1, 1], as TD3-style implementations start)."""
    action_penalty: float = 1e-3
    """Weight of the mean squared pre-tanh actor output in the actor loss (Lowe et al.'s
    code: 1e-3); keeps the actors out of tanh's saturation, where they stop learning."""
    grad_clip: float = 0.5
    """The gradient of each weight and bias of each rover's actor and critic is scaled to
    this norm at most (Lowe et al.'s code clips each variable so, at 0.5); 0: no clipping."""

    def __post_init__(self) -> None:
        super().__post_init__()
        self.check_at_least(1, "critic_hidden", "batch_size", "buffer_capacity", "update_every")
        check(self.warmup_steps >= 0, "warmup_steps", f"must be >= 0, got {self.warmup_steps}")
        check_choice(self.warmup_actions, ("policy", "uniform"), "warmup_actions")
        for name in ("action_penalty", "grad_clip"):
            value = getattr(self, name)
            check(value >= 0 and math.isfinite(value), name, f"must be >= 0, got {value}")
        check(
            self.buffer_capacity >= self.batch_size,
            "buffer_capacity",
            f"must be >= batch_size = {self.batch_size}, got {self.buffer_capacity}",
        )
        self.check_positive("actor_lr", "critic_lr")
        self.check_unit("gamma")
        self.check_unit("tau", closed=False)
        check(
            self.noise_std >= 0 and math.isfinite(self.noise_std),
            "noise_std",
            f"must be >= 0, got {self.noise_std}",
        )


@dataclasses.dataclass(frozen=True)
class TrainerSpec:
    """A registered gradient-based trainer: its config table and its class."""

    config: type
    """The config class (a :class:`MARLConfig`); its ``section`` names the TOML table."""
    trainer: str | type
    """The trainer class (a :class:`physrover.marl.common.Trainer`), or ``"module:Class"``,
    imported only when a run uses it (the built-in trainers import torch)."""
    summary: str
    reference: str

    def load(self) -> type:
        if isinstance(self.trainer, type):
            return self.trainer
        import importlib

        module, name = self.trainer.split(":")
        return getattr(importlib.import_module(module), name)


def register_trainer(
    name: str, config: type, trainer: str | type, summary: str, reference: str = ""
) -> TrainerSpec:
    """Add a learning algorithm under ``name`` (``[learn] method = "NAME"``, ``--method``).

    ``config``: a :class:`MARLConfig` subclass whose ``section`` (its TOML table, e.g.
    ``[mappo]``) no other table of a run uses; ``trainer``: a
    :class:`physrover.marl.common.Trainer` subclass or ``"module:Class"``. The run directory,
    checkpoints, bit-identical resume, ``curves --x episodes``, ``render`` and ``evaluate``
    come with it (:mod:`physrover.experiment.trainer_runs`).
    """
    if not (isinstance(config, type) and issubclass(config, MARLConfig)):
        raise TypeError(f"a trainer's config must be a MARLConfig subclass, got {config!r}")
    if not isinstance(trainer, (str, type)) or (isinstance(trainer, str) and ":" not in trainer):
        raise TypeError(f"a trainer must be a class or 'module:Class', got {trainer!r}")
    if name in FITNESS_METHODS:
        raise ValueError(f"{name!r} is a fitness method of the CCEA; give the trainer its own name")
    taken = {*RESERVED_SECTIONS, *(s for s, names in settings_tables().items() if names != [name])}
    if config.section in taken:
        raise ValueError(f"trainer {name!r}: its config's section [{config.section}] is taken; "
                         "give its MARLConfig subclass its own `section`")  # fmt: skip
    return TRAINERS.register(name, TrainerSpec(config, trainer, summary, reference))


register_trainer(
    "mappo", MAPPOConfig, "physrover.marl.mappo:MAPPO",
    "MAPPO: shared Gaussian actor, centralised value, GAE, clipped surrogate (IPPO: "
    "centralised_critic = false)", "Yu et al. 2022")  # fmt: skip
register_trainer(
    "maddpg", MADDPGConfig, "physrover.marl.maddpg:MADDPG",
    "MADDPG: deterministic actors, a centralised critic per rover, replay, soft targets",
    "Lowe et al. 2017")  # fmt: skip
