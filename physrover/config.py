"""Typed, frozen configuration with field-named validation and TOML in/out.

Field names are the public vocabulary of physrover: the same names are used in TOML files
(``[domain]`` table), on the command line (``--set n_req=5``) and as keyword arguments of the
gymnasium environments (``RoverVectorEnv(50, n_req=5)``).

Every config is validated on construction: a bad value raises :class:`ConfigError`, whose
message names the field and the allowed range. Unknown names are errors, never ignored.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import sys
import typing
from collections.abc import Mapping
from pathlib import Path
from typing import Any, ClassVar

from physrover.registry import CREDITS, FITNESS_METHODS, TRAINERS, did_you_mean

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - exercised on Python 3.10 only
    import tomli as tomllib

MOTION_MODELS = ("ideal", "physics")


class ConfigError(ValueError):
    """A configuration value is invalid; the message names the field."""

    def __init__(self, field: str, message: str):
        self.field, self.message = field, message
        super().__init__(f"{field}: {message}")


@contextlib.contextmanager
def naming_file(path: str | Path):
    """Prefix the message of a :class:`ConfigError` raised inside with the file's path."""
    try:
        yield
    except ConfigError as exc:
        if str(exc).startswith(str(path)):
            raise
        raise ConfigError(f"{path}: {exc.field}", exc.message) from None


# ----------------------------------------------------------------------------------------------
# Type coercion shared by every config dataclass
# ----------------------------------------------------------------------------------------------


def _coerce(field: str, annotation: Any, value: Any) -> Any:
    """Return ``value`` converted to the field's declared type, or raise ConfigError.

    Accepted conversions are the loss-free ones: int -> float, list -> tuple. A bool is never
    accepted for a number (TOML and Python both allow ``True == 1``; a config should not).
    """
    if annotation is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(field, f"expected a number, got {value!r}")
        value = float(value)
        if math.isnan(value):
            raise ConfigError(field, "must not be NaN")
        return value
    if annotation is int:
        if isinstance(value, bool) or not isinstance(value, int):
            if isinstance(value, float) and value.is_integer():
                return int(value)
            raise ConfigError(field, f"expected an integer, got {value!r}")
        return int(value)
    if annotation is bool:
        if not isinstance(value, bool):
            raise ConfigError(field, f"expected true or false, got {value!r}")
        return value
    if annotation is str:
        if not isinstance(value, str):
            raise ConfigError(field, f"expected a string, got {value!r}")
        return value
    origin = typing.get_origin(annotation)
    if origin is tuple:
        (item_type, _ellipsis) = typing.get_args(annotation)
        if isinstance(value, (str, bytes)) or not isinstance(value, (list, tuple)):
            raise ConfigError(field, f"expected a list, got {value!r}")
        return tuple(_coerce(field, item_type, v) for v in value)
    raise TypeError(f"unsupported config field type {annotation!r} for {field}")


class ConfigBase:
    """Mixin of every config dataclass: type coercion on construction, dict/TOML
    conversion, unknown-key errors. Subclasses (frozen dataclasses) call
    ``_coerce_fields()`` then validate with :func:`check` in ``__post_init__``."""

    #: Name of the TOML table that holds this config.
    section: ClassVar[str] = ""

    def _coerce_fields(self) -> None:
        hints = typing.get_type_hints(type(self))
        for f in dataclasses.fields(self):  # type: ignore[arg-type]
            value = _coerce(f.name, hints[f.name], getattr(self, f.name))
            object.__setattr__(self, f.name, value)

    def check_at_least(self, minimum: float, *names: str) -> None:
        """ConfigError naming the first of ``names`` below ``minimum``."""
        for name in names:
            value = getattr(self, name)
            check(value >= minimum, name, f"must be >= {minimum}, got {value}")

    def check_positive(self, *names: str) -> None:
        """ConfigError naming the first of ``names`` that is not a finite number > 0."""
        for name in names:
            value = getattr(self, name)
            check(value > 0 and math.isfinite(value), name, f"must be > 0, got {value}")

    def check_unit(self, *names: str, closed: bool = True) -> None:
        """ConfigError naming the first of ``names`` outside [0, 1] (``closed=False``: (0, 1])."""
        for name in names:
            value = getattr(self, name)
            ok = 0.0 <= value <= 1.0 if closed else 0.0 < value <= 1.0
            interval = "[0, 1]" if closed else "(0, 1]"
            check(ok, name, f"must be in {interval}, got {value}")

    @classmethod
    def field_names(cls) -> tuple[str, ...]:
        return tuple(f.name for f in dataclasses.fields(cls))  # type: ignore[arg-type]

    @classmethod
    def from_dict(cls, values: Mapping[str, Any]):
        unknown = sorted(set(values) - set(cls.field_names()))
        if unknown:
            allowed = ", ".join(cls.field_names())
            hint = did_you_mean(unknown[0], cls.field_names())
            raise ConfigError(unknown[0], f"unknown {cls.__name__} field{hint} (known: {allowed})")
        return cls(**values)

    def to_dict(self) -> dict[str, Any]:
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}  # type: ignore[arg-type]

    def replace(self, **changes: Any):
        """A copy with ``changes`` applied and validated (unknown names are errors)."""
        merged = self.to_dict()
        unknown = sorted(set(changes) - set(merged))
        if unknown:
            hint = did_you_mean(unknown[0], merged)
            raise ConfigError(unknown[0], f"unknown {type(self).__name__} field{hint}")
        merged.update(changes)
        return type(self)(**merged)

    def to_toml(self) -> str:
        return dumps_toml({self.section: self.to_dict()})

    @classmethod
    def from_toml(cls, text: str):
        data = loads_toml(text)
        unknown = sorted(set(data) - {cls.section})
        if unknown:
            raise ConfigError(unknown[0], f"unknown TOML table (expected [{cls.section}])")
        return cls.from_dict(data.get(cls.section, {}))


def check(ok: bool, field: str, message: str) -> None:
    """Raise :class:`ConfigError` naming ``field`` with ``message`` unless ``ok``."""
    if not ok:
        raise ConfigError(field, message)


def check_choice(value: str, choices: tuple[str, ...], field: str) -> None:
    """Raise :class:`ConfigError` unless ``value`` is one of ``choices``."""
    hint = did_you_mean(value, choices) if isinstance(value, str) else ""
    check(value in choices, field, f"must be one of {', '.join(choices)}; got {value!r}{hint}")


# ----------------------------------------------------------------------------------------------
# The domain
# ----------------------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class DomainConfig(ConfigBase):
    """The tightly coupled multi-rover domain (paper Sections 4.1-4.2).

    Distances are in world units (the paper's: capture radius 4, POI ring radius 15); one
    environment step is one time step ``t`` of Eqs. 11-16. Defaults are the paper's values.
    """

    section: ClassVar[str] = "domain"

    n_rovers: int = 15
    """Rovers per team (the paper varies 6-15)."""
    poi_values: tuple[float, ...] = (1.0, 2.0, 3.0, 4.0)
    """Value V_k of each POI; distinct and positive (the paper: 1..4, max score 10)."""
    n_req: int = 3
    """Coupling: rovers needed within d_cap of a POI at one step to capture it (Eq. 12)."""
    d_cap: float = 4.0
    """Capture radius, world units (Eq. 13)."""
    d_min: float = 1.0
    """Lower bound of the distance metric, world units (Eq. 14)."""
    steps: int = 50
    """Time steps per episode."""
    poi_ring_radius: float = 15.0
    """POIs start evenly on a circle of this radius around the origin, world units."""
    spawn_radius: float = 1.5
    """Rovers start uniformly at random in a disc of this radius at the origin, world units."""
    motion: str = "ideal"
    """Motion model: "ideal" (the paper's kinematics) or "physics" (pymunk bodies)."""

    # -- physical motion only (motion = "physics"); time unit: one environment step --------
    collisions: bool = True
    """Rovers of a team collide with each other (physics only)."""
    rover_radius: float = 0.2
    """Radius of a rover's circular body, world units (physics only)."""
    rover_mass: float = 1.0
    """Mass of a rover, mass units (physics only); moment of inertia is that of a disc."""
    max_force: float = 0.5
    """Largest drive force, mass x world units / step^2: from rest to speed 1 takes
    rover_mass / max_force steps (physics only)."""
    max_torque: float = 0.05
    """Largest steering torque, mass x world units^2 / step^2 (physics only)."""
    substeps: int = 4
    """Physics steps per environment step (physics only)."""
    solver_iterations: int = 10
    """Iterations of pymunk's contact solver per physics step (physics only)."""
    walls: bool = False
    """Square walls around each team's world (physics only)."""
    wall_half_size: float = 30.0
    """Half the side of the walled square centred on the origin, world units."""

    def __post_init__(self) -> None:
        self._coerce_fields()
        check(self.n_rovers >= 1, "n_rovers", f"must be >= 1, got {self.n_rovers}")
        check(len(self.poi_values) >= 1, "poi_values", "must list at least one POI value")
        for v in self.poi_values:
            check(
                v > 0 and math.isfinite(v),
                "poi_values",
                f"every value must be positive and finite, got {v}",
            )
        check(
            len(set(self.poi_values)) == len(self.poi_values),
            "poi_values",
            f"values must be distinct, got {list(self.poi_values)}",
        )
        check(
            1 <= self.n_req <= self.n_rovers,
            "n_req",
            f"must be in [1, n_rovers={self.n_rovers}], got {self.n_req}",
        )
        self.check_positive("d_cap", "d_min", "poi_ring_radius", "spawn_radius")
        check(
            self.d_min <= self.d_cap,
            "d_min",
            f"must be in (0, d_cap={self.d_cap}], got {self.d_min}",
        )
        check(self.steps >= 1, "steps", f"must be >= 1, got {self.steps}")
        check_choice(self.motion, MOTION_MODELS, "motion")
        self.check_positive("rover_radius", "rover_mass", "max_force", "max_torque")
        check(self.substeps >= 1, "substeps", f"must be >= 1, got {self.substeps}")
        check(
            self.solver_iterations >= 1,
            "solver_iterations",
            f"must be >= 1, got {self.solver_iterations}",
        )
        inner = self.spawn_radius + 2 * self.rover_radius
        check(
            math.isfinite(self.wall_half_size) and self.wall_half_size > inner,
            "wall_half_size",
            f"must exceed spawn_radius + 2 rover_radius = {inner}, got {self.wall_half_size}",
        )

    @property
    def n_pois(self) -> int:
        return len(self.poi_values)


# ----------------------------------------------------------------------------------------------
# TOML
# ----------------------------------------------------------------------------------------------


def loads_toml(text: str, source: str = "<string>") -> dict[str, Any]:
    """Parse TOML; a syntax error names ``source`` (a file's path) and the line and column
    the parser gives."""
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(source, f"cannot parse TOML: {exc}") from None


def load_toml_file(path: str | Path) -> dict[str, Any]:
    """Parse a TOML file; errors name the file."""
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise ConfigError(str(path), f"cannot read: {exc.strerror}") from None
    return loads_toml(text, str(path))


def _toml_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return repr(value)
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    raise TypeError(f"cannot write {value!r} as TOML")


def dumps_toml(tables: Mapping[str, Mapping[str, Any]]) -> str:
    """Write tables of scalars and flat lists as TOML (enough for every physrover config)."""
    lines: list[str] = []
    for name, table in tables.items():
        if lines:
            lines.append("")
        lines.append(f"[{name}]")
        lines.extend(f"{key} = {_toml_value(value)}" for key, value in table.items())
    return "\n".join(lines) + "\n"


def parse_override(text: str) -> tuple[str, Any]:
    """Parse ``FIELD=VALUE`` from the command line; VALUE is read as TOML, else as a string.

    ``n_req=5`` -> ("n_req", 5); ``poi_values=[1, 2]`` -> ("poi_values", [1, 2]);
    ``motion=physics`` -> ("motion", "physics").
    """
    name, sep, raw = text.partition("=")
    name = name.strip()
    if not sep or not name:
        raise ConfigError("--set", f"expected FIELD=VALUE, got {text!r}")
    raw = raw.strip()
    try:
        value = tomllib.loads(f"v = {raw}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw
    return name, value


# ----------------------------------------------------------------------------------------------
# Learning and runs
# ----------------------------------------------------------------------------------------------

OPTIMIZERS = ("sgd", "adam")


@dataclasses.dataclass(frozen=True)
class LearnConfig(ConfigBase):
    """The CCEA and the fitness methods (paper Sections 2.1, 3, 4.2; defaults are the paper's).

    Methods: ``D`` and ``G`` use one episode's feedback as fitness; ``average`` the mean and
    ``leniency`` the max of the feedback over ``n_samples`` episodes with fresh random
    teammates; ``hall-of-fame`` the feedback with the best team found so far as teammates;
    ``mean-critic`` (Eq. 4, regular updates Eqs. 6-8), ``max-critic`` (Eq. 3, inexact
    updates Eqs. 9-10) and the two other combinations ``max-critic-regular`` and
    ``mean-critic-inexact`` use a fitness critic.
    """

    section: ClassVar[str] = "learn"

    method: str = "max-critic"
    """Fitness method (see the class docstring)."""
    feedback: str = "D"
    """The credit signal, each rover's immediate feedback: "D" (difference evaluation, Eq. 1),
    "G", or any registered in :data:`physrover.registry.CREDITS` (physrover.domain.credit)."""
    generations: int = 5000
    """Generations to run."""
    seed: int = 0
    """Seeds every random draw of the run (world, initial policies, evolution, critics)."""
    population: int = 50
    """Policies per rover, k."""
    hidden: int = 32
    """Hidden units of each policy (8 -> hidden -> 2, ReLU then tanh)."""
    mutation_rate: float = 0.01
    """Probability that an offspring's weight is mutated."""
    mutation_scale: float = 1.0
    """Scale of the Cauchy distribution added to a mutated weight."""
    n_samples: int = 10
    """Episodes per generation for the average and leniency methods."""
    eval_episodes: int = 10
    """Fresh episodes of the champion team per generation (the learning curve)."""
    critic_hidden: int = 80
    """Hidden units of the intermediate critic (10 -> hidden -> 1, leaky ReLU)."""
    leaky_slope: float = 0.01
    """Slope of the critic's leaky ReLU for negative inputs."""
    critic_lr: float = 5e-6
    """Critic learning rate alpha_w (Eqs. 7, 9); 0 freezes the critic at its random
    initialisation (an ablation: is it the training or the random shape that helps?)."""
    critic_optimizer: str = "sgd"
    """"sgd": plain mini-batch gradient steps of Eq. 7/9; "adam": Adam on the same gradient."""
    replay_trajectories: int = 500
    """Replay capacity, trajectories, for regular updates."""
    trajectory_batch: int = 7
    """Trajectories per mini-batch, regular updates."""
    trajectory_batches: int = 7
    """Mini-batches per generation, regular updates."""
    replay_pairs: int = 25000
    """Replay capacity, state-action pairs, for inexact updates."""
    pair_batch: int = 50
    """State-action pairs per mini-batch, inexact updates."""
    pair_batches: int = 50
    """Mini-batches per generation, inexact updates."""
    checkpoint_every: int = 100
    """Write a checkpoint every this many generations (and at the end)."""

    def __post_init__(self) -> None:
        self._coerce_fields()
        if self.method not in TRAINERS:
            check(
                self.method in FITNESS_METHODS,
                "method",
                FITNESS_METHODS.unknown_message(self.method) + f", or a trainer: "
                f"{', '.join(TRAINERS)}",
            )
        check(self.feedback in CREDITS, "feedback", CREDITS.unknown_message(self.feedback))
        check_choice(self.critic_optimizer, OPTIMIZERS, "critic_optimizer")
        check(self.generations >= 0, "generations", f"must be >= 0, got {self.generations}")
        check(self.seed >= 0, "seed", f"must be >= 0, got {self.seed}")
        check(self.population >= 2, "population", f"must be >= 2, got {self.population}")
        self.check_at_least(
            1, "hidden", "n_samples", "eval_episodes", "critic_hidden", "replay_trajectories",
            "trajectory_batch", "trajectory_batches", "replay_pairs", "pair_batch",
            "pair_batches", "checkpoint_every",
        )  # fmt: skip
        check(
            0.0 <= self.mutation_rate <= 1.0,
            "mutation_rate",
            f"must be in [0, 1], got {self.mutation_rate}",
        )
        check(
            self.mutation_scale > 0 and math.isfinite(self.mutation_scale),
            "mutation_scale",
            f"must be > 0, got {self.mutation_scale}",
        )
        check(
            self.critic_lr >= 0 and math.isfinite(self.critic_lr),
            "critic_lr",
            f"must be >= 0 (0 freezes the critic at its random start), got {self.critic_lr}",
        )
        check(
            0.0 <= self.leaky_slope < 1.0,
            "leaky_slope",
            f"must be in [0, 1), got {self.leaky_slope}",
        )


SHARED_WITH_LEARN = ("seed", "hidden", "eval_episodes", "checkpoint_every")
"""Fields a trainer's table shares with [learn], set in [learn] only (one seed per run)."""


@dataclasses.dataclass(frozen=True)
class RunConfig:
    """Everything a training run needs: the domain and the learner. TOML: [domain], [learn],
    and, when ``[learn] method`` names a gradient-based trainer (``physrover methods``), that
    trainer's table (e.g. ``[mappo]``), held in ``trainer``; its fields shared with [learn]
    (:data:`SHARED_WITH_LEARN`) are taken from [learn]."""

    domain: DomainConfig = dataclasses.field(default_factory=DomainConfig)
    learn: LearnConfig = dataclasses.field(default_factory=LearnConfig)
    trainer: Any = None

    def __post_init__(self) -> None:
        if not isinstance(self.domain, DomainConfig):
            raise ConfigError("domain", "must be a DomainConfig")
        if not isinstance(self.learn, LearnConfig):
            raise ConfigError("learn", "must be a LearnConfig")
        spec = TRAINERS[self.learn.method] if self.learn.method in TRAINERS else None
        if spec is None:
            if self.trainer is not None:
                raise ConfigError("trainer", f"method {self.learn.method!r} takes no trainer")
            return
        trainer = self.trainer if self.trainer is not None else spec.config()
        if not isinstance(trainer, spec.config):
            raise ConfigError("trainer", f"must be a {spec.config.__name__}")
        shared = {name: getattr(self.learn, name) for name in SHARED_WITH_LEARN}
        object.__setattr__(self, "trainer", trainer.replace(**shared))

    @property
    def length(self) -> int:
        """What the run's checkpoints count when it is finished: [learn] generations, or a
        gradient-based trainer's iterations (its total_episodes / num_envs, rounded up)."""
        return self.trainer.total_iterations if self.trainer is not None else self.learn.generations

    def _tables(self) -> dict[str, dict[str, Any]]:
        tables = {"domain": self.domain.to_dict(), "learn": self.learn.to_dict()}
        if self.trainer is not None:
            own = self.trainer.to_dict()
            tables[self.trainer.section] = {
                k: v for k, v in own.items() if k not in SHARED_WITH_LEARN
            }
        return tables

    def to_toml(self) -> str:
        return dumps_toml(self._tables())

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> RunConfig:
        sections = {spec.config.section: name for name, spec in TRAINERS.items()}
        unknown = sorted(set(data) - {"domain", "learn", *sections})
        if unknown:
            known = ", ".join(["domain", "learn", *sections])
            raise ConfigError(unknown[0], f"unknown TOML table (known: {known})")
        learn = LearnConfig.from_dict(data.get("learn", {}))
        trainer = None
        for section, name in sections.items():
            if section not in data:
                continue
            if name != learn.method:
                raise ConfigError(section, f"a [{section}] table, but method is {learn.method!r}")
            table = dict(data[section])
            for shared in SHARED_WITH_LEARN:
                if shared in table:
                    raise ConfigError(f"{section}.{shared}", f"set {shared} in [learn]")
            trainer = TRAINERS[name].config.from_dict(table)
        return cls(DomainConfig.from_dict(data.get("domain", {})), learn, trainer)

    @classmethod
    def from_toml(cls, text: str) -> RunConfig:
        return cls.from_dict(loads_toml(text))

    @classmethod
    def load(cls, path: str | Path) -> RunConfig:
        """The config in a TOML file; every error names the file."""
        data = load_toml_file(path)
        with naming_file(path):
            return cls.from_dict(data)

    def with_overrides(self, overrides: Mapping[str, Any]) -> RunConfig:
        """Apply ``{field: value}`` by bare field name, or ``table.field`` (``mappo.lr``);
        a bare name that two active tables share is an error that says which to write."""
        domain, learn, trainer = {}, {}, {}
        for name, value in overrides.items():
            table, _, field = name.rpartition(".")
            if table == "domain":
                domain[field] = value
            elif table == "learn":
                learn[field] = value
            elif table:
                trainer[(table, field)] = value
            elif name in DomainConfig.field_names():
                domain[name] = value
            elif name in LearnConfig.field_names():
                learn[name] = value
            else:
                trainer[(None, name)] = value
        new_learn = self.learn.replace(**learn)
        spec = TRAINERS[new_learn.method] if new_learn.method in TRAINERS else None
        fields: dict[str, Any] = {}
        for (table, name), value in trainer.items():
            if spec is None or table not in (None, spec.config.section):
                known = DomainConfig.field_names() + LearnConfig.field_names()
                where = f"{table}." if table else ""
                raise ConfigError(
                    f"{where}{name}",
                    f"unknown config field{did_you_mean(name, known)} (not in [domain] or "
                    "[learn]; `physrover info` lists every field)",
                )
            fields[name] = value
        if spec is not None:
            section = spec.config.section
            for name in learn:
                if name in spec.config.field_names() and name not in SHARED_WITH_LEARN:
                    raise ConfigError(
                        name, f"is in [learn] and [{section}]: write learn.{name} or "
                        f"{section}.{name}"
                    )  # fmt: skip
            base = self.trainer if isinstance(self.trainer, spec.config) else spec.config()
            return RunConfig(self.domain.replace(**domain), new_learn, base.replace(**fields))
        return RunConfig(self.domain.replace(**domain), new_learn)


def __getattr__(name: str):
    # ``METHODS`` was a tuple here before the registry; kept readable for existing code.
    if name == "METHODS":
        return FITNESS_METHODS.names()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
