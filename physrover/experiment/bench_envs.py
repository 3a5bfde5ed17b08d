"""Env throughput (a benchmark, not a test): team steps per second of the rover domain through
each interface a learner uses, and of VMAS ``discovery`` through its own TorchRL env.

``physrover bench envs`` prints the table; each row is the median of ``repeats`` timed
episodes (``steps`` steps, random actions, after one untimed episode), one thread:

- ``RoverVectorEnv``: the native batched gymnasium env, actions drawn beforehand;
- ``RoverTorchEnv``: the native TorchRL env over it (``env.rollout`` with auto-reset);
- PettingZoo under ``torchrl.envs.PettingZooWrapper``: one team per env, as that wrapper
  runs it (it is not batched);
- VMAS ``discovery`` in ``torchrl.envs.VmasEnv`` on the CPU, the same team size, targets
  and agents per target as the rover domain's rovers, POIs and n_req (VMAS's own
  dynamics: 2 substeps, collisions, LIDAR sensors).

Every TorchRL env is driven by ``env.rollout`` with the same cheap policy: it writes actions
its spec drew before the timing (:func:`_replay_policy`), so the rows time the envs and
TorchRL's stepping, not the drawing of random actions (TorchRL's ``rand_action`` alone
costs about as much as one of physrover's batched steps). A row whose package is not
installed says so instead of a number.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from physrover.config import DomainConfig
from physrover.envs.gymnasium_env import RoverVectorEnv
from physrover.experiment.bench import median_seconds


@dataclass(frozen=True)
class Throughput:
    """One row: team steps per second (median), the teams stepped together, and a note."""

    name: str
    team_steps_per_s: float | None
    teams: int
    note: str = ""

    def line(self) -> str:
        rate = "-" if self.team_steps_per_s is None else f"{self.team_steps_per_s:,.0f}"
        return f"| {self.name} | {self.teams} | {rate} | {self.note} |"


def _median_rate(episode: Callable[[], None], team_steps: int, repeats: int) -> float:
    """Team steps per second: ``team_steps`` over the median time of one ``episode()``
    (after one untimed: compilation, caches)."""
    return team_steps / median_seconds(episode, 1, repeats)


def _replay_policy(env, steps: int):
    """A policy writing ``steps`` actions drawn from ``env``'s action spec beforehand, in turn."""
    bank = [env.full_action_spec.rand() for _ in range(steps)]
    turn = iter(range(1 << 62))

    def policy(tensordict):
        return tensordict.update(bank[next(turn) % steps])

    return policy


def _rollout_rate(env, teams: int, steps: int, repeats: int) -> float:
    policy = _replay_policy(env, steps)
    return _median_rate(lambda: env.rollout(steps, policy, break_when_any_done=False),
                        teams * steps, repeats)  # fmt: skip


def native(domain: DomainConfig, teams: int, repeats: int) -> Throughput:
    env = RoverVectorEnv(teams, domain)
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1, 1, (domain.steps, *env.action_space.shape)).astype(np.float32)
    env.reset(seed=0)

    def episode():
        env.reset()
        for a in actions:
            env.step(a)

    rate = _median_rate(episode, teams * domain.steps, repeats)
    return Throughput("physrover RoverVectorEnv (gymnasium, numpy)", rate, teams)


def torchrl_native(domain: DomainConfig, teams: int, repeats: int) -> Throughput:
    name = "physrover RoverTorchEnv (TorchRL, batched)"
    try:
        from physrover.envs.torchrl_env import RoverTorchEnv
    except ImportError:
        return Throughput(name, None, teams, "torchrl not installed")
    env = RoverTorchEnv(teams, domain)
    env.set_seed(0)
    return Throughput(name, _rollout_rate(env, teams, domain.steps, repeats), teams)


def pettingzoo_wrapped(domain: DomainConfig, repeats: int) -> Throughput:
    name = "physrover parallel_env under TorchRL's PettingZooWrapper"
    try:
        from torchrl.envs import PettingZooWrapper

        from physrover.envs.pettingzoo_env import parallel_env
    except ImportError:
        return Throughput(name, None, 1, "torchrl or pettingzoo not installed")
    env = PettingZooWrapper(parallel_env(config=domain), use_mask=True, seed=0)
    rate = _rollout_rate(env, 1, domain.steps, repeats)
    return Throughput(name, rate, 1, "one team per env: the wrapper is not batched")


def vmas_discovery(domain: DomainConfig, teams: int, repeats: int) -> Throughput:
    name = "VMAS discovery, torchrl.envs.VmasEnv (CPU)"
    try:
        import vmas
        from torchrl.envs import VmasEnv
    except ImportError:
        return Throughput(name, None, teams, "vmas or torchrl not installed")
    env = VmasEnv("discovery", num_envs=teams, device="cpu", continuous_actions=True,
                  max_steps=domain.steps, seed=0, n_agents=domain.n_rovers,
                  n_targets=domain.n_pois,
                  agents_per_target=max(domain.n_req_per_poi))  # fmt: skip
    rate = _rollout_rate(env, teams, domain.steps, repeats)
    return Throughput(name, rate, teams, f"vmas {vmas.__version__}")


def bench_envs(domain: DomainConfig, teams: int = 50, repeats: int = 5) -> list[Throughput]:
    """Every row of the table for ``domain`` (its rovers, POIs, n_req, steps, motion)."""
    return [
        native(domain, teams, repeats),
        torchrl_native(domain, teams, repeats),
        pettingzoo_wrapped(domain, repeats),
        vmas_discovery(domain, teams, repeats),
    ]
