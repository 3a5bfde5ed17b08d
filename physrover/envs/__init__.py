"""Adapters of the one batched world to the ecosystem's interfaces.

- :mod:`~physrover.envs.gymnasium_env`: :class:`RoverEnv` (one team, gymnasium's ``Env``,
  registered as ``physrover/Rover-v0``) and :class:`RoverVectorEnv` (many teams natively
  batched, gymnasium's ``VectorEnv``);
- :mod:`~physrover.envs.pettingzoo_env`: :func:`parallel_env`, PettingZoo's parallel API
  (``pip install 'physrover[marl]'``; importing this package never needs pettingzoo);
- :mod:`~physrover.envs.torchrl_env`: :class:`RoverTorchEnv`, a natively batched TorchRL
  env over the vector env (``pip install 'physrover[torchrl]'``, needed only for it);
- :mod:`~physrover.envs.benchmarl_task`: physrover's BenchMARL tasks over that env
  (``pip install 'physrover[benchmarl]'``; importing it registers them with BenchMARL).

May import: :mod:`physrover.core`, :mod:`physrover.config`, :mod:`physrover.domain`,
:mod:`physrover.viz`.
"""

from __future__ import annotations

from physrover.envs.gymnasium_env import ENV_ID, RoverEnv, RoverVectorEnv

__all__ = ["ENV_ID", "RoverEnv", "RoverVectorEnv", "RoverParallelEnv", "RoverTorchEnv",
           "parallel_env"]  # fmt: skip


def __getattr__(name: str):
    if name in ("parallel_env", "RoverParallelEnv"):
        from physrover.envs import pettingzoo_env

        return getattr(pettingzoo_env, name)
    if name == "RoverTorchEnv":  # torchrl is optional (physrover[torchrl])
        from physrover.envs.torchrl_env import RoverTorchEnv

        return RoverTorchEnv
    raise AttributeError(f"module 'physrover.envs' has no attribute {name!r}")
