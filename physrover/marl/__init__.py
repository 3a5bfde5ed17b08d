"""Interfaces to the multi-agent reinforcement learning (MARL) ecosystem.

This package holds the MARL-ecosystem interfaces (the PettingZoo parallel env,
:func:`parallel_env`) and the gradient-based baselines on the natively batched vector env:
:mod:`physrover.marl.mappo` (MAPPO, and IPPO behind a flag) and :mod:`physrover.marl.maddpg`
(MADDPG), written on torch (imported only by those two modules). pettingzoo is optional
(``pip install 'physrover[marl]'``): importing this package never needs it, building a
PettingZoo env does.
"""

from __future__ import annotations

# Binds the name ``parallel_env`` to the factory, not to the submodule of the same name:
# ``from physrover.marl.parallel_env import RoverParallelEnv`` still reaches the module.
from physrover.marl.parallel_env import RoverParallelEnv, parallel_env

__all__ = ["RoverParallelEnv", "parallel_env"]
