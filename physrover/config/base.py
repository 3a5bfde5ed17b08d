"""The machinery every config table shares: type coercion, field-named errors, TOML in/out.

A config table is a frozen dataclass deriving from :class:`ConfigBase`; it coerces its
fields to their declared types on construction and validates them with :func:`check`, so a
bad value raises :class:`ConfigError` naming the field and the allowed range. Unknown names
are errors, never ignored.
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

import tomlkit

from physrover.core.registry import did_you_mean

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - exercised on Python 3.10 only
    import tomli as tomllib


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


def coerce(field: str, annotation: Any, value: Any) -> Any:
    """Return ``value`` converted to the field's declared type, or raise ConfigError.

    Accepted conversions are the loss-free ones: int -> float, list -> tuple. A bool is never
    accepted for a number (TOML and Python both allow ``True == 1``; a config should not).
    A field annotated ``Any`` is left as given (its table validates it).
    """
    if annotation is Any:
        return value
    if annotation is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(field, f"expected a number, got {value!r}")
        value = float(value)
        if math.isnan(value):
            raise ConfigError(field, "must not be NaN")
        return value
    if annotation is int:
        if isinstance(value, bool) or not isinstance(value, int):
            if isinstance(value, float) and value.is_integer() and abs(value) < 2**53:
                return int(value)  # 3.0 is 3; 1e300 is no count
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
        return tuple(coerce(field, item_type, v) for v in value)
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
            value = coerce(f.name, hints[f.name], getattr(self, f.name))
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

    def is_default(self, name: str) -> bool:
        """Whether field ``name`` holds its declared default (a rule "this field configures
        X" checks this, so the default is written once, where the field is declared)."""
        field = next(f for f in dataclasses.fields(self) if f.name == name)  # type: ignore[arg-type]
        default = field.default
        if default is dataclasses.MISSING:
            default = field.default_factory()  # type: ignore[misc]
        return getattr(self, name) == default

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


def coerce_table(value: Any, cls: type):
    """A ``[section]`` table as ``cls``: from None (its defaults), a mapping or an instance."""
    table = cls() if value is None else value
    if isinstance(table, Mapping):
        table = cls.from_dict(table)
    check(isinstance(table, cls), cls.section, f"must be a {cls.__name__}")
    return table


def coerce_tables(value: Any, cls: type, section: str, finish=None) -> tuple:
    """A list of ``[[section]]`` tables (mappings or ``cls`` instances) as a tuple of
    ``cls`` (each passed through ``finish`` if given); errors name ``section[i].field``."""
    if isinstance(value, (str, bytes, Mapping)) or not isinstance(value, (list, tuple)):
        raise ConfigError(section, f"expected a list of [[{section}]] tables, got {value!r}")
    items = []
    for i, item in enumerate(value):
        try:
            if isinstance(item, Mapping):
                item = cls.from_dict(item)
            check(isinstance(item, cls), "", f"expected a table, got {item!r}")
            items.append(finish(item) if finish is not None else item)
        except ConfigError as exc:
            raise ConfigError(f"{section}[{i}].{exc.field}".rstrip("."), exc.message) from None
    return tuple(items)


def check(ok: bool, field: str, message: str) -> None:
    """Raise :class:`ConfigError` naming ``field`` with ``message`` unless ``ok``."""
    if not ok:
        raise ConfigError(field, message)


def check_choice(value: str, choices: tuple[str, ...], field: str) -> None:
    """Raise :class:`ConfigError` unless ``value`` is one of ``choices``."""
    hint = did_you_mean(value, choices) if isinstance(value, str) else ""
    check(value in choices, field, f"must be one of {', '.join(choices)}; got {value!r}{hint}")


# ----------------------------------------------------------------------------------------------
# TOML
# ----------------------------------------------------------------------------------------------


def loads_toml(text: str, source: str = "<string>") -> dict[str, Any]:
    """Parse TOML; a syntax error names ``source`` (a file's path) and the line and column
    the parser gives."""
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        message = str(exc)
        if "end of document" in message:  # tomllib gives no line here: find the opener
            message += _unclosed(text)
        raise ConfigError(source, f"cannot parse TOML: {message}") from None


def _unclosed(text: str) -> str:
    """Where a document that ended too soon left a bracket or brace open (for the error of
    :func:`loads_toml`), e.g. ``; the [ of line 4 is never closed`` (brackets inside a
    one-line string or after a comment do not count)."""
    stack: list[tuple[str, int]] = []
    for number, line in enumerate(text.splitlines(), start=1):
        quote = None
        for char in line:
            if quote:
                quote = None if char == quote else quote
            elif char in "\"'":
                quote = char
            elif char == "#":
                break
            elif char in "[{":
                stack.append((char, number))
            elif char in "]}" and stack:
                stack.pop()
    if stack:
        char, number = stack[-1]
        return f"; the {char} of line {number} is never closed"
    return f" (line {len(text.splitlines())})"


def load_toml_file(path: str | Path) -> dict[str, Any]:
    """Parse a TOML file; errors name the file."""
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise ConfigError(str(path), f"cannot read: {exc.strerror}") from None
    return loads_toml(text, str(path))


def dumps_toml(tables: Mapping[str, Any]) -> str:
    """Write ``{table: {key: value}}`` as TOML, one ``[table]`` after another (a list of
    tables as ``[[table]]``s).

    Written by tomlkit: strings escaped (quotes, backslashes, newlines, control characters),
    keys quoted where TOML needs it, ``inf``/``nan`` for non-finite floats, lists inline
    (``poi_values = [1.0, 2.0]``). For every config physrover ships the text is byte for byte
    what physrover 0.4's own writer gave, so run directories' config.toml read the same.
    """
    return tomlkit.dumps({name: dict(table) if isinstance(table, Mapping) else
                          [dict(t) for t in table] for name, table in tables.items()})  # fmt: skip


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
# Components: parts of the domain chosen by name (a scenario, a sensor)
# ----------------------------------------------------------------------------------------------


class Component(ConfigBase):
    """A part of the domain chosen by name, whose parameters are its own config table.

    A component class is a frozen dataclass (its fields are its parameters, coerced and
    validated like any table) with a ``kind``, the name it is registered under. In TOML its
    table is ``[section]`` with ``kind = "NAME"`` and the parameters of that kind; in code an
    instance is passed as it is (``DomainConfig(scenario=MyScenario(...))``).
    """

    kind: ClassVar[str] = ""

    def table(self) -> dict[str, Any]:
        """The TOML table: ``kind`` then the parameters."""
        return {"kind": self.kind, **self.to_dict()}


def component(value: Any, registry, section: str, default: str) -> Component:
    """The component of ``section`` that ``value`` describes: None (the default kind), a
    registered kind's name, a table ``{"kind": NAME, **parameters}``, or an instance."""
    if value is None:
        value = default
    if isinstance(value, str):
        value = {"kind": value}
    if isinstance(value, Mapping):
        table = dict(value)
        kind = table.pop("kind", default)
        check(kind in registry, f"{section}.kind", registry.unknown_message(kind))
        return registry[kind].from_dict(table)
    ok = isinstance(value, Component) and value.section == section
    check(ok, section, f"must be a {section} (a registered kind's name, a table or an "
          f"instance), got {type(value).__name__}")  # fmt: skip
    return value
