"""Typed, frozen configuration with field-named validation and TOML in/out.

- :mod:`physrover.config.base`: the shared machinery (coercion, errors, TOML, components);
- :mod:`physrover.config.domain`: [domain], [physics], [scenario], [sensor];
- :mod:`physrover.config.learn`: [learn];
- :mod:`physrover.config.run`: a run's whole config (the tables above and the method's own).

Every config is validated on construction: a bad value raises :class:`ConfigError`, whose
message names the field and the allowed range. Unknown names are errors, never ignored.

May import: :mod:`physrover.core` (its registries, to validate names).
"""

from physrover.config.base import (
    Component,
    ConfigBase,
    ConfigError,
    check,
    check_choice,
    dumps_toml,
    load_toml_file,
    loads_toml,
    naming_file,
    parse_override,
)
from physrover.config.domain import COMPONENTS, DomainConfig, PhysicsConfig
from physrover.config.learn import OPTIMIZERS, LearnConfig
from physrover.config.run import (
    RESERVED_SECTIONS,
    SHARED_WITH_LEARN,
    RunConfig,
    method_spec,
    settings_class,
    settings_tables,
)

__all__ = [
    "COMPONENTS",
    "Component",
    "ConfigBase",
    "ConfigError",
    "DomainConfig",
    "LearnConfig",
    "OPTIMIZERS",
    "PhysicsConfig",
    "RESERVED_SECTIONS",
    "RunConfig",
    "SHARED_WITH_LEARN",
    "check",
    "check_choice",
    "dumps_toml",
    "load_toml_file",
    "loads_toml",
    "method_spec",
    "naming_file",
    "parse_override",
    "settings_class",
    "settings_tables",
]
