"""A training run's configuration: the domain's tables, [learn] and a trainer's table."""

from __future__ import annotations

import dataclasses
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
from physrover.config.learn import LearnConfig
from physrover.config.roles import ROLE_TABLES, check_not_overridden
from physrover.core.registry import CREDITS, TRAINERS

SHARED_WITH_LEARN = ("seed", "hidden", "eval_episodes", "checkpoint_every")
"""Fields a trainer's table shares with [learn], set in [learn] only (one seed per run)."""


@dataclasses.dataclass(frozen=True)
class RunConfig:
    """Everything a training run needs: the domain and the learner. TOML: the domain's tables
    ([domain], [physics], [scenario], [sensor]), [learn], and, when ``[learn] method`` names
    a gradient-based trainer (``physrover methods``), that trainer's table (e.g. ``[mappo]``),
    held in ``trainer``; its fields shared with [learn] (:data:`SHARED_WITH_LEARN`) are taken
    from [learn]."""

    domain: DomainConfig = dataclasses.field(default_factory=DomainConfig)
    learn: LearnConfig = dataclasses.field(default_factory=LearnConfig)
    trainer: Any = None

    def __post_init__(self) -> None:
        if not isinstance(self.domain, DomainConfig):
            raise ConfigError("domain", "must be a DomainConfig")
        if not isinstance(self.learn, LearnConfig):
            raise ConfigError("learn", "must be a LearnConfig")
        credit = CREDITS[self.learn.feedback] if self.learn.feedback in CREDITS else None
        getattr(credit, "check", lambda domain: None)(self.domain)  # defined for the domain?
        if self.learn.critic_target == "step":
            check(getattr(credit, "per_step_defined", False), "critic_target",
                  f'per-step targets are defined for feedback "D", "G" and "D++", not '
                  f'{self.learn.feedback!r}')  # fmt: skip
            check(
                not any(p.scored_by_rule for p in self.domain.pois),
                "critic_target",
                'per-step targets need POIs without after, require or score_at = "final"',
            )
        self._check_curriculum()
        spec = TRAINERS[self.learn.method] if self.learn.method in TRAINERS else None
        check(spec is None or not self.domain.agents, "agents", f"{self.learn.method} trains "
              "teams of the paper's rovers only; agent classes train with the CCEA")  # fmt: skip
        if spec is None:
            if self.trainer is not None:
                raise ConfigError("trainer", f"method {self.learn.method!r} takes no trainer")
            return
        trainer = self.trainer if self.trainer is not None else spec.config()
        if not isinstance(trainer, spec.config):
            raise ConfigError("trainer", f"must be a {spec.config.__name__}")
        try:  # the trainer's credit signal, defined for the domain?
            CREDITS[trainer.reward].check(self.domain)
        except ConfigError as exc:
            raise ConfigError(f"{spec.config.section}.reward", exc.message) from None
        shared = {name: getattr(self.learn, name) for name in SHARED_WITH_LEARN}
        object.__setattr__(self, "trainer", trainer.replace(**shared))

    def _check_curriculum(self) -> None:
        """A coupling curriculum (``[learn] curriculum_start``) fits the domain: it starts
        below the domain's coupling, and its evaluation at the domain's coupling rescores
        the same episodes (:mod:`physrover.learn.curriculum`), so no POI may vanish once
        captured or score by a rule."""
        start = self.learn.curriculum_start
        if start == 0:
            return
        top = max(self.domain.n_req_per_poi)
        check(start < top, "curriculum_start",
              f"must be below the domain's coupling (n_req {top}), got {start}")  # fmt: skip
        for k, poi in enumerate(self.domain.pois):
            counted = poi.disappear == "never" and not poi.scored_by_rule
            check(counted, "curriculum_start", f"pois[{k}] vanishes once captured or scores "
                  "by a rule (after, score_at, require); the curriculum needs POIs captured "
                  "by a count of agents in range")  # fmt: skip

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
        unknown = sorted(set(data) - {"domain", *COMPONENTS, *ROLE_TABLES, "learn", *sections})
        if unknown:
            known = ", ".join(["domain", *COMPONENTS, *ROLE_TABLES, "learn", *sections])
            raise ConfigError(unknown[0], f"unknown TOML table (known: {known}; a trainer of "
                              "your own registers its table when its module is imported, e.g. "
                              "physrover --import my_parts.py)")  # fmt: skip
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
        return cls(DomainConfig.from_tables(data), learn, trainer)

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
            elif table:
                if field in SHARED_WITH_LEARN:
                    raise ConfigError(name, f"set {field} in [learn] (learn.{field})")
                trainer[(table, field)] = value
            elif name in domain_names:
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
                known = [*domain_names, *LearnConfig.field_names()]
                where = f"{table}." if table else ""
                raise ConfigError(
                    f"{where}{name}",
                    f"unknown config field{did_you_mean(name, known)} (not in the domain's "
                    "tables or [learn]; `physrover info` lists every field)",
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
