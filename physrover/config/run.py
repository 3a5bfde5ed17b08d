"""A training run's configuration: the domain's tables, [learn] and the method's own table."""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from physrover.config.base import (
    ConfigError,
    check,
    did_you_mean,
    dumps_toml,
    load_toml_file,
    loads_toml,
    naming_file,
)
from physrover.config.domain import COMPONENTS, REGISTRIES, DomainConfig
from physrover.config.hybrid import HybridConfig
from physrover.config.learn import LearnConfig
from physrover.config.roles import ROLE_TABLES, check_not_overridden
from physrover.core.registry import CREDITS, FITNESS_METHODS, TRAINERS

SHARED_WITH_LEARN = ("seed", "hidden", "eval_episodes", "checkpoint_every")
"""Fields a trainer's table shares with [learn], set in [learn] only (one seed per run)."""

RESERVED_SECTIONS = ("domain", *COMPONENTS, *ROLE_TABLES, "learn", "marl", "hybrid")
"""Tables of a run's config.toml that no method's or trainer's own table may take."""


def method_spec(method: str):
    """The registry entry of ``method``: a trainer's (TRAINERS) or a fitness method's
    (FITNESS_METHODS); None for a name neither knows."""
    for registry in (TRAINERS, FITNESS_METHODS):
        if method in registry:
            return registry[method]
    return None


def settings_class(method: str) -> type | None:
    """The class of ``method``'s own settings table (its registry entry's ``config``), or
    None if it has none."""
    return getattr(method_spec(method), "config", None)


def settings_tables() -> dict[str, list[str]]:
    """``{section: [methods]}``: every method's own table and the methods that take it."""
    tables: dict[str, list[str]] = {}
    for registry in (TRAINERS, FITNESS_METHODS):
        for name, spec in registry.items():
            if getattr(spec, "config", None) is not None:
                tables.setdefault(spec.config.section, []).append(name)
    return tables


def _tables_with(field: str) -> dict[str, tuple[type, list[str]]]:
    """``{section: (settings class, [methods])}``: the fitness methods' tables with ``field``."""
    found: dict[str, tuple[type, list[str]]] = {}
    for name, spec in FITNESS_METHODS.items():
        cls = getattr(spec, "config", None)
        if cls is not None and field in cls.field_names():
            found.setdefault(cls.section, (cls, []))[1].append(name)
    return found


def _owners(field: str) -> str:
    """``[critic] (mean-critic, max-critic, ...)``: the fitness methods' tables with ``field``."""
    return "; ".join(f"[{section}] ({', '.join(names)})"
                     for section, (_, names) in _tables_with(field).items())  # fmt: skip


@dataclasses.dataclass(frozen=True)
class RunConfig:
    """Everything a training run needs: the domain and the learner. TOML: the domain's tables
    ([domain], [physics], [scenario], [sensor], [[pois]], [[agents]]), [learn], and the
    method's own table, held in ``settings``: a fitness method's (``[critic]``,
    ``[trajectory_critic]``, ``[sampled]``: :mod:`physrover.learn.configs`) or a
    gradient-based trainer's (``[mappo]``; its fields shared with [learn],
    :data:`SHARED_WITH_LEARN`, are taken from [learn]). A method without settings (``D``,
    ``G``, ``hall-of-fame``) has ``settings = None``; None for one that has them means its
    defaults. ``hybrid``: a ``[hybrid]`` table, a gradient learner whose actors migrate into
    the CCEA's populations (:class:`~physrover.config.hybrid.HybridConfig`), or None."""

    domain: DomainConfig = dataclasses.field(default_factory=DomainConfig)
    learn: LearnConfig = dataclasses.field(default_factory=LearnConfig)
    settings: Any = None
    hybrid: HybridConfig | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.domain, DomainConfig):
            raise ConfigError("domain", "must be a DomainConfig")
        if not isinstance(self.learn, LearnConfig):
            raise ConfigError("learn", "must be a LearnConfig")
        signals = {self.learn.feedback} | {c.feedback for c in self.domain.agents if c.feedback}
        for name in sorted(signals & set(CREDITS)):  # defined for the domain?
            CREDITS[name].check(self.domain)
        self._check_curriculum()
        self._check_hybrid()
        method = self.learn.method
        cls = settings_class(method)
        if cls is None:
            if self.settings is not None:
                raise ConfigError(self.settings.section, f"method {method!r} has no settings "
                                  "of its own")  # fmt: skip
            return
        settings = self.settings if self.settings is not None else cls()
        if not isinstance(settings, cls):
            raise ConfigError(cls.section, f"{method!r} takes a {cls.__name__}, got "
                              f"{type(settings).__name__}")  # fmt: skip
        if method in TRAINERS:
            check(not self.domain.agents, "agents", f"{method} trains teams of the paper's "
                  "rovers only; agent classes train with the CCEA")  # fmt: skip
            try:  # the trainer's credit signal, defined for the domain?
                CREDITS[settings.reward].check(self.domain)
            except ConfigError as exc:
                raise ConfigError(f"{cls.section}.reward", exc.message) from None
            settings = settings.replace(**{n: getattr(self.learn, n) for n in SHARED_WITH_LEARN})
        object.__setattr__(self, "settings", settings)
        getattr(settings, "check_run", lambda run: None)(self)  # rules across the tables

    @property
    def trainer(self):
        """The gradient-based trainer's config (``[mappo]``...), or None for the CCEA."""
        return self.settings if self.learn.method in TRAINERS else None

    def _check_curriculum(self) -> None:
        """A coupling curriculum (``[learn] curriculum_start``) fits the domain: it starts
        below the domain's coupling, and its evaluation at the domain's coupling rescores
        the same episodes (:mod:`physrover.learn.curriculum`), so no POI may vanish once
        captured (its sight would depend on the coupling) or score by a rule."""
        start = self.learn.curriculum_start
        if start == 0:
            return
        top = max(self.domain.n_req_per_poi)
        check(start < top, "curriculum_start",
              f"must be below the domain's coupling (n_req {top}), got {start}")  # fmt: skip
        for k, poi in enumerate(self.domain.pois):
            counted = poi.disappear != "captured" and not poi.scored_by_rule
            check(counted, "curriculum_start", f"pois[{k}] vanishes once captured or scores "
                  "by a rule (after, score_at, require, value_by); the curriculum needs POIs "
                  "captured by a count of agents in range")  # fmt: skip

    def _check_hybrid(self) -> None:
        """A ``[hybrid]`` learner's actor must be a genome of the CCEA's populations: the
        paper's rovers (no agent classes) with ReLU policies, under a fitness method."""
        hybrid = self.hybrid
        if hybrid is None:
            return
        check(isinstance(hybrid, HybridConfig), "hybrid", "must be a HybridConfig")
        check(self.learn.method not in TRAINERS, "hybrid", f"the hybrid runs beside the CCEA; "
              f"method {self.learn.method!r} is a gradient-based trainer")  # fmt: skip
        check(not self.domain.agents, "hybrid", "the hybrid's learner trains teams of the "
              "paper's rovers only, not agent classes ([[agents]])")  # fmt: skip
        check(self.learn.activation == "relu", "hybrid", "the learner's actor is ReLU then "
              'tanh: set [learn] activation = "relu"')  # fmt: skip
        check(not hybrid.together or self.learn.method != "hall-of-fame", "hybrid.together",
              "needs teams drawn at random, not the hall of fame's")  # fmt: skip
        try:
            CREDITS[hybrid.reward].check(self.domain)
        except ConfigError as exc:
            raise ConfigError("hybrid.reward", exc.message) from None

    @property
    def length(self) -> int:
        """What the run's checkpoints count when it is finished: [learn] generations, or a
        gradient-based trainer's iterations (its total_episodes / num_envs, rounded up)."""
        return self.trainer.total_iterations if self.trainer is not None else self.learn.generations

    @property
    def unit(self) -> str:
        """What the run counts: "generation" (the CCEA) or "iteration" (a gradient-based
        trainer: ``num_envs`` training episodes and an update)."""
        return "iteration" if self.trainer is not None else "generation"

    def with_length(self, n: int, unit: str | None = None) -> RunConfig:
        """This config trained for ``n`` of its :attr:`unit` (a trainer's total_episodes
        becomes ``n`` x num_envs). ``unit``, when given (a command-line flag's), must be
        the config's own: a trainer's run is not measured in generations."""
        if unit is not None and unit != self.unit:
            flag = "--iterations" if self.unit == "iteration" else "--generations"
            what = (f"{self.learn.method} trains in iterations ({self.trainer.num_envs} "
                    "episodes each)" if self.trainer is not None
                    else f"{self.learn.method} (the CCEA) trains in generations")  # fmt: skip
            raise ConfigError(f"--{unit}s", f"{what}, not {unit}s: use {flag} N")
        check(n >= 1, f"{self.unit}s", f"must be >= 1, got {n}")
        if self.trainer is None:
            return self.with_overrides({"generations": n})
        return self.with_overrides({"total_episodes": n * self.trainer.num_envs})

    def _tables(self) -> dict[str, dict[str, Any]]:
        tables = {**self.domain.tables(), "learn": self.learn.to_dict()}
        if self.settings is not None:
            own = self.settings.to_dict()
            shared = SHARED_WITH_LEARN if self.trainer is not None else ()
            tables[self.settings.section] = {k: v for k, v in own.items() if k not in shared}
        if self.hybrid is not None:
            tables["hybrid"] = self.hybrid.to_dict()
        return tables

    def to_toml(self) -> str:
        return dumps_toml(self._tables())

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> RunConfig:
        sections = settings_tables()
        known = ["domain", *COMPONENTS, *ROLE_TABLES, "learn", "hybrid", *sections]
        unknown = sorted(set(data) - set(known))
        if unknown:
            raise ConfigError(unknown[0], f"unknown TOML table (known: {', '.join(known)}; a "
                              "method or trainer of your own registers its table when its "
                              "module is imported: physrover --import my_parts.py)")  # fmt: skip
        table = dict(data.get("learn", {}))
        moved = {k: table.pop(k) for k in list(table)
                 if k not in LearnConfig.field_names() and _owners(k)}  # fmt: skip
        learn = LearnConfig.from_dict(table)
        own = settings_class(learn.method)
        for section in sections:
            if section in data and (own is None or section != own.section):
                takes = f" (its table is [{own.section}])" if own is not None else ""
                raise ConfigError(section, f"a [{section}] table, but method is "
                                  f"{learn.method!r}{takes}")  # fmt: skip
        settings = None
        if own is not None:
            table = dict(data.get(own.section, {}))
            if learn.method in TRAINERS:
                for shared in SHARED_WITH_LEARN:
                    if shared in table:
                        raise ConfigError(f"{own.section}.{shared}", f"set {shared} in [learn]")
            _move_from_learn(moved, table, own, learn.method)
            settings = own.from_dict(table)
        else:
            _move_from_learn(moved, {}, None, learn.method)
        hybrid = None
        if "hybrid" in data:
            try:
                hybrid = HybridConfig.from_dict(data["hybrid"])
            except ConfigError as exc:
                raise ConfigError(f"hybrid.{exc.field}", exc.message) from None
        return cls(DomainConfig.from_tables(data), learn, settings, hybrid)

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
        """Apply ``{field: value}`` by bare field name, or ``table.field`` (``critic.critic_lr``,
        ``mappo.lr``); a bare name that two active tables share is an error that says which
        to write. A change of ``method`` starts the new method's table from its defaults
        unless it takes the same table (``mean-critic`` to ``max-critic``). ``hybrid``
        names the ``[hybrid]`` learner ("mappo": the table, from its defaults if absent) or
        "none" (no table); ``hybrid.FIELD`` sets one of its fields."""
        domain, learn, own, hybrid = {}, {}, {}, {}
        # the fields of a scenario or sensor chosen in the same overrides are domain fields
        domain_names = set(self.domain.flat_dict())
        for section, registry in REGISTRIES.items():
            kind = overrides.get(section, overrides.get(f"{section}.kind"))
            if isinstance(kind, str) and kind in registry:
                domain_names |= set(registry[kind].field_names())
        for name, value in overrides.items():
            table, _, field = name.rpartition(".")
            check_not_overridden(self.domain, name)
            if table.split(".")[0] in ("agents", "pois"):  # [[agents]] / [[pois]]: lists
                raise ConfigError(name, f"[[{table.split('.')[0]}]] tables cannot be changed "
                                  "with --set or a sweep's grid: edit the TOML")  # fmt: skip
            if table in ("domain", *COMPONENTS):
                domain[name] = value
            elif table == "learn":
                learn[field] = value
            elif table == "hybrid" or name == "hybrid":
                hybrid["learner" if name == "hybrid" else field] = value
            elif table:
                if field in SHARED_WITH_LEARN:
                    raise ConfigError(name, f"set {field} in [learn] (learn.{field})")
                own[(table, field)] = value
            elif name in domain_names:
                domain[name] = value
            elif name in LearnConfig.field_names():
                learn[name] = value
            else:
                own[(None, name)] = value
        new_learn = self.learn.replace(**learn)
        new_hybrid = self.hybrid
        if hybrid.get("learner") == "none":  # hybrid = "none": no [hybrid] table
            check(len(hybrid) == 1, "hybrid", "is none: no hybrid.FIELD may be set beside it")
            new_hybrid = None
        elif hybrid:  # a hybrid.FIELD override starts the table from its defaults if absent
            try:
                new_hybrid = (self.hybrid or HybridConfig()).replace(**hybrid)
            except ConfigError as exc:
                raise ConfigError(f"hybrid.{exc.field}", exc.message) from None
        cls = settings_class(new_learn.method)
        fields: dict[str, Any] = {}
        for (table, name), value in own.items():
            where = f"{table}." if table else ""
            if cls is None or table not in (None, cls.section) or name not in cls.field_names():
                elsewhere = _owners(name) if table in (None, *settings_tables()) else ""
                if elsewhere:
                    raise ConfigError(f"{where}{name}", f"is a setting of {elsewhere}, not of "
                                      f"method {new_learn.method!r}")  # fmt: skip
                known = [*domain_names, *LearnConfig.field_names(),
                         *(cls.field_names() if cls else ())]  # fmt: skip
                raise ConfigError(
                    f"{where}{name}",
                    f"unknown config field{did_you_mean(name, known)} (not in the domain's "
                    "tables, [learn] or the method's own; `physrover info` lists every field)",
                )
            fields[name] = value
        if cls is None:
            return RunConfig(self.domain.replace(**domain), new_learn, None, new_hybrid)
        for name in learn:
            if name in cls.field_names() and name not in SHARED_WITH_LEARN:
                raise ConfigError(name, f"is in [learn] and [{cls.section}]: write learn.{name} "
                                  f"or {cls.section}.{name}")  # fmt: skip
        base = self.settings if isinstance(self.settings, cls) else cls()
        return RunConfig(self.domain.replace(**domain), new_learn, base.replace(**fields),
                         new_hybrid)  # fmt: skip


def _move_from_learn(moved: dict[str, Any], table: dict[str, Any], own: type | None,
                     method: str) -> None:  # fmt: skip
    """Read a physrover 0.5 [learn] whose fields ``moved`` are now a fitness method's own
    (:mod:`physrover.learn.configs`): each the method takes goes into ``table`` (of class
    ``own``); 0.5's config.toml wrote every field, so the others are dropped, quietly at
    their defaults, with the note otherwise. One note says what moved and what was
    dropped."""
    into = [] if own is None or method in TRAINERS else [k for k in moved if k in own.field_names()]
    for name in into:
        if name in table:
            raise ConfigError(f"learn.{name}", f"is also in [{own.section}]: keep that one")
        table[name] = moved[name]
    changed, ignored = [], []
    for name, value in moved.items():
        owner = next(iter(_tables_with(name).values()))[0]
        if value != getattr(owner(), name):
            (changed if name in into else ignored).append(name)
    notes = []
    if into:
        rest = len(into) - len(changed)
        at_default = f" (and {rest} at their defaults)" if changed and rest else ""
        notes.append(f"{', '.join(changed) or 'its settings'}{at_default} moved to "
                     f"[{own.section}] in physrover 0.6")  # fmt: skip
    if ignored:
        notes.append(f"{', '.join(ignored)} ignored ({method!r} has no such setting)")
    if notes:
        warnings.warn(f"[learn] {'; '.join(notes)} (`physrover info` writes the new layout)",
                      UserWarning, stacklevel=4)  # fmt: skip
