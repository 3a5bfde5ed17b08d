"""Gradient-based baselines on the natively batched vector env: :mod:`physrover.marl.mappo`
(MAPPO, and IPPO behind a flag) and :mod:`physrover.marl.maddpg` (MADDPG), written on torch
(imported only by those two modules), with their shared machinery
(:mod:`physrover.marl.common`) and config tables and registry
(:mod:`physrover.marl.configs`, which imports no torch).

``physrover.marl.parallel_env`` (the PettingZoo env, now :mod:`physrover.envs.pettingzoo_env`)
is still found here, with a DeprecationWarning, until the next release.

May import: :mod:`physrover.core`, :mod:`physrover.config`, :mod:`physrover.domain`,
:mod:`physrover.envs`, :mod:`physrover.learn` (policy layouts).
"""

from __future__ import annotations

import warnings


def __getattr__(name: str):
    if name in ("parallel_env", "RoverParallelEnv"):
        warnings.warn(f"physrover.marl.{name} is now physrover.envs.{name} (and physrover."
                      f"{name}); the old path goes in the next release", DeprecationWarning,
                      stacklevel=2)  # fmt: skip
        from physrover.envs import pettingzoo_env

        return getattr(pettingzoo_env, name)
    raise AttributeError(f"module 'physrover.marl' has no attribute {name!r}")
