"""Named registries: the one list of the fitness methods, credit signals, scenarios, sensors,
motion models and trainers that config validation, the CLI, plots and docs all read.

A registry maps a name (as written in TOML and on the command line) to an entry; a
researcher's own entry is one ``register`` call, from any module, without editing the package.
This module sits at the bottom of the package (it imports nothing of physrover), so the
config layer can validate names against it; the learners fill it when they are imported
(``physrover/__init__.py`` imports them, so the built-in names are always there).
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable, Iterator
from typing import Generic, TypeVar

T = TypeVar("T")


def did_you_mean(name: str, known: Iterable[str]) -> str:
    """`` (did you mean 'a' or 'b'?)`` for the known names closest to ``name``, or ``""``."""
    if not isinstance(name, str):  # a number or a list where a name belongs
        return ""
    known = list(known)
    close = difflib.get_close_matches(name, known, n=3, cutoff=0.6)
    if not close:  # a case slip (``d`` for ``D``) or a missing separator (``nreq``)
        squash = {k.lower().replace("_", "").replace("-", ""): k for k in known}
        close = [squash[k] for k in difflib.get_close_matches(
            name.lower().replace("_", "").replace("-", ""), list(squash), n=3, cutoff=0.6
        )]  # fmt: skip
    if not close:
        return ""
    return " (did you mean " + " or ".join(repr(c) for c in close) + "?)"


class Registry(Generic[T]):
    """An ordered ``name -> entry`` map with helpful errors.

    ``register(name, entry)`` adds (a second entry under one name is an error unless
    ``replace=True``); ``registry[name]`` looks up, raising :class:`KeyError` whose message
    lists the known names and suggests the nearest.
    """

    def __init__(self, kind: str):
        self.kind = kind
        self._entries: dict[str, T] = {}
        self._aliases: set[str] = set()

    def register(self, name: str, entry: T, *, replace: bool = False, alias: bool = False) -> T:
        """Add ``entry`` under ``name``; an ``alias`` (an old name kept so old files load)
        is found by lookups but not listed by :meth:`names`."""
        if not isinstance(name, str) or not name:
            raise ValueError(f"a {self.kind} name must be a non-empty string, got {name!r}")
        if name in self._entries and not replace:
            raise ValueError(f"{self.kind} {name!r} is already registered")
        self._entries[name] = entry
        if alias:
            self._aliases.add(name)
        return entry

    def register_class(self, cls: type, base: type, name_attr: str, *, replace: bool = False):
        """Register the subclass ``cls`` of ``base`` under its ``name_attr`` attribute; returns
        ``cls`` (so a ``register_*`` function built on this works as a class decorator)."""
        name = getattr(cls, name_attr, "")
        if not (isinstance(cls, type) and issubclass(cls, base)) or not name:
            raise TypeError(f"a {self.kind} must be a {base.__name__} subclass with a {name_attr}")
        self.register(name, cls, replace=replace)
        return cls

    def unknown_message(self, name: str, more: str = "") -> str:
        """``unknown KIND 'NAME' (did you mean ...); known: a, b`` + ``more``, and where a
        researcher's own part comes from (its module must be imported to register it)."""
        shown = repr(name) if isinstance(name, str) else f"{name!r} (not a name)"
        return (
            f"unknown {self.kind} {shown}{did_you_mean(name, self.names())}; "
            f"known: {', '.join(self.names())}{more} (one of your own: its module registers "
            "it when imported, e.g. physrover --import my_parts.py)"
        )

    def __getitem__(self, name: str) -> T:
        try:
            return self._entries[name]
        except KeyError:
            raise KeyError(self.unknown_message(name)) from None

    def __contains__(self, name: object) -> bool:
        return isinstance(name, str) and name in self._entries  # a list from TOML: not a name

    def __iter__(self) -> Iterator[str]:
        return iter(self._entries)

    def __len__(self) -> int:
        return len(self._entries)

    def names(self) -> tuple[str, ...]:
        """The registered names, aliases left out."""
        return tuple(n for n in self._entries if n not in self._aliases)

    def items(self):
        return self._entries.items()


#: Fitness methods of the CCEA: name -> :class:`physrover.learn.fitness.MethodSpec`.
FITNESS_METHODS: Registry = Registry("fitness method")

#: Credit signals, the immediate feedback of each rover: name -> a
#: :class:`physrover.domain.scoring.credit.Credit`.
CREDITS: Registry = Registry("credit signal")

#: Gradient-based trainers (the MARL baselines): name -> a
#: :class:`physrover.marl.configs.TrainerSpec`.
TRAINERS: Registry = Registry("trainer")

#: Scenarios, the start states of episodes: name -> a
#: :class:`physrover.domain.scenarios.Scenario` subclass (``[scenario] kind``).
SCENARIOS: Registry = Registry("scenario")

#: Sensors, what a rover observes: name -> a :class:`physrover.domain.sensing.sensor.Sensor`
#: subclass (``[sensor] kind``).
SENSORS: Registry = Registry("sensor")

#: Motion models: name -> a :class:`physrover.domain.motion.dynamics.Dynamics` subclass
#: (``[domain] motion``).
DYNAMICS: Registry = Registry("motion model")
