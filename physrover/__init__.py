"""physrover: a physics-simulated multi-rover testbed for multiagent learning research.

Reproduces the tightly coupled multi-rover domain and the fitness critics of "Multi-level
Fitness Critics for Cooperative Coevolution", with an idealised and a physical motion model.
"""

from __future__ import annotations

import gymnasium

from physrover.config import ConfigError, DomainConfig

# Importing these registers the built-in parts under their names (physrover.registry).
from physrover.domain import credit as _credit  # noqa: F401  (credit signals)
from physrover.domain import physics as _physics  # noqa: F401  (motion models)
from physrover.domain import scenarios as _scenarios  # noqa: F401  (scenarios)
from physrover.domain import sensors as _sensors  # noqa: F401  (sensors)
from physrover.envs import ENV_ID, RoverEnv, RoverVectorEnv
from physrover.learn import fitness as _fitness  # noqa: F401  (fitness methods)
from physrover.marl import configs as _trainers  # noqa: F401  (trainers; no torch import)

__version__ = "0.4.0"
__all__ = [
    "ConfigError",
    "DomainConfig",
    "ENV_ID",
    "RoverEnv",
    "RoverVectorEnv",
    "__version__",
    "parallel_env",
]


def __getattr__(name: str):
    if name == "parallel_env":  # the PettingZoo env; pettingzoo is optional (physrover[marl])
        from physrover.marl import parallel_env

        return parallel_env
    raise AttributeError(f"module 'physrover' has no attribute {name!r}")


if ENV_ID not in gymnasium.registry:
    gymnasium.register(
        id=ENV_ID,
        entry_point="physrover.envs:RoverEnv",
        vector_entry_point="physrover.envs:RoverVectorEnv",
    )
