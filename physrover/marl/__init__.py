"""Interfaces to the multi-agent reinforcement learning (MARL) ecosystem.

This package holds the MARL-ecosystem interfaces (today the PettingZoo parallel env,
:func:`parallel_env`) and, later, the gradient-based baselines trained through them. Its
dependencies are optional (``pip install 'physrover[marl]'``): importing it never needs
them, building an env does.
"""

from __future__ import annotations

# Binds the name ``parallel_env`` to the factory, not to the submodule of the same name:
# ``from physrover.marl.parallel_env import RoverParallelEnv`` still reaches the module.
from physrover.marl.parallel_env import RoverParallelEnv, parallel_env

__all__ = ["RoverParallelEnv", "parallel_env"]
