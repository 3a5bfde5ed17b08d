"""physrover: a physics-simulated multi-rover testbed for multiagent learning research.

Reproduces the tightly coupled multi-rover domain and the fitness critics of "Multi-level
Fitness Critics for Cooperative Coevolution" (Rockefeller, Khadka and Tumer, AAMAS 2020),
with an idealised and a physical motion model.

The public surface is :data:`__all__`: the envs, the configs, :func:`train`, the
``register_*`` functions of every seam, and the video writer. The package's wings, lowest
first (a wing imports only from the wings before it; ``tests/test_layers.py`` checks it)::

    core        registries, compiled-kernel cache, threads, progress, plugins, statistics
    config      typed frozen tables: [domain] [physics] [scenario] [sensor] [learn] [...]
    domain      the rover domain, batched over teams: state, plan and step, agents, motion,
                sensing, scoring and credit
    viz         frames of a world state and H.264 video
    envs        gymnasium single and vector envs, PettingZoo
    learn       policies, evolution, critics, fitness methods, the CCEA (Algorithm 1)
    marl        gradient-based trainers (MAPPO, MADDPG)
    experiment  run directories, training and resume, sweeps, evaluation, playback, bench
    analysis    curve data, tables, figures
    cli         ``physrover ...``
"""

from __future__ import annotations

import gymnasium

from physrover.config import ConfigError, DomainConfig, RunConfig
from physrover.core import deprecation as _deprecation
from physrover.domain.motion import physics as _physics  # noqa: F401  (motion models)

# Importing these registers the built-in parts under their names (physrover.core.registry).
from physrover.domain.motion.dynamics import register_dynamics
from physrover.domain.scenarios import register_scenario
from physrover.domain.scoring.credit import register_credit
from physrover.domain.sensing import density as _density  # noqa: F401  (the sensors)
from physrover.domain.sensing import lidar as _lidar  # noqa: F401
from physrover.domain.sensing.sensor import register_sensor
from physrover.envs import ENV_ID, RoverEnv, RoverVectorEnv
from physrover.learn.fitness import register_method
from physrover.marl.configs import register_trainer  # trainers; no torch import

__version__ = "0.6.0.dev0"
__all__ = [
    "ConfigError",
    "DomainConfig",
    "ENV_ID",
    "RenderConfig",
    "RoverEnv",
    "RoverVectorEnv",
    "RunConfig",
    "VideoWriter",
    "__version__",
    "parallel_env",
    "register_credit",
    "register_dynamics",
    "register_method",
    "register_scenario",
    "register_sensor",
    "register_trainer",
    "train",
]

_LAZY = {  # what needs an optional or heavy package is imported when first asked for
    "parallel_env": "physrover.envs.pettingzoo_env",  # pettingzoo (physrover[marl])
    "train": "physrover.experiment.training",
    "RenderConfig": "physrover.viz.render",  # OpenCV
    "VideoWriter": "physrover.viz.video",  # PyAV
}


def __getattr__(name: str):
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'physrover' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(__all__))


_deprecation.install()

if ENV_ID not in gymnasium.registry:
    gymnasium.register(
        id=ENV_ID,
        entry_point="physrover.envs:RoverEnv",
        vector_entry_point="physrover.envs:RoverVectorEnv",
    )
