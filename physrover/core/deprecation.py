"""Old module paths that keep importing, with a DeprecationWarning naming the new ones.

physrover 0.5 moved its top-level modules into wings (``physrover.runs`` became
:mod:`physrover.experiment.store`, :mod:`~physrover.experiment.training` and their
neighbours, ``physrover.render`` became :mod:`physrover.viz.render`, ...). So that a
researcher's script written for 0.4 still runs for one release, ``import physrover.runs``
(or ``from physrover.runs import train``) gives a stand-in module whose attributes are
those of the new modules, and warns once per old path. The stand-in is a module of its own
(the new modules keep their names and specs); setting an attribute on it does not reach the
new module. Installed by ``physrover/__init__.py``; each old path is removed in the release
after the one that moved it (0.5's wings, 0.6's domain folders).
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.util
import sys
import types
import warnings

OLD_PATHS: dict[str, tuple[str, ...]] = {
    "physrover.runs": (
        "physrover.experiment.training",
        "physrover.experiment.store",
        "physrover.experiment.stops",
        "physrover.experiment.loop",
    ),
    "physrover.trainer_runs": ("physrover.experiment.trainer_runs",),
    "physrover.sweep": ("physrover.experiment.sweep", "physrover.experiment.execute"),
    "physrover.provenance": ("physrover.experiment.provenance",),
    "physrover.evaluate": ("physrover.experiment.evaluate",),
    "physrover.playback": ("physrover.experiment.playback",),
    "physrover.bench": ("physrover.experiment.bench",),
    "physrover.curve_data": ("physrover.analysis.curve_data",),
    "physrover.compare": ("physrover.analysis.tables",),
    "physrover.plots": ("physrover.analysis.plots",),
    "physrover.render": ("physrover.viz.render", "physrover.viz.video"),
    "physrover.video": ("physrover.viz.video",),
    "physrover.registry": ("physrover.core.registry",),
    "physrover.compiled": ("physrover.core.compiled",),
    "physrover.threads": ("physrover.core.threads",),
    "physrover.progress": ("physrover.core.progress",),
    "physrover.plugins": ("physrover.core.plugins",),
    "physrover.stats": ("physrover.core.stats",),
    "physrover.commands": ("physrover.cli.commands",),
    "physrover.marl.parallel_env": ("physrover.envs.pettingzoo_env",),
    # physrover 0.6 organised the domain by concept (agents, motion, sensing, scoring)
    "physrover.domain.kernels": (
        "physrover.domain.motion.ideal",
        "physrover.domain.scoring.captures",
        "physrover.domain.sensing.density",
        "physrover.domain.sensing.sectors",
    ),
    "physrover.domain.sense_kernels": (
        "physrover.domain.sensing.density",
        "physrover.domain.sensing.sectors",
    ),
    "physrover.domain.sensors": (
        "physrover.domain.sensing.sensor",
        "physrover.domain.sensing.density",
    ),
    "physrover.domain.lidar": ("physrover.domain.sensing.lidar",),
    "physrover.domain.roles": (
        "physrover.domain.agents.classes",
        "physrover.domain.agents.roles",
        "physrover.domain.sensing.sensor",
    ),
    "physrover.domain.dynamics": ("physrover.domain.motion.dynamics",),
    "physrover.domain.physics": ("physrover.domain.motion.physics",),
    "physrover.domain.physics_kernels": ("physrover.domain.motion.integrator",),
    "physrover.domain.contacts": ("physrover.domain.motion.contacts",),
    "physrover.domain.separation": ("physrover.domain.motion.separation",),
    "physrover.domain.poi_rules": ("physrover.domain.scoring.rules",),
    "physrover.domain.influence": ("physrover.domain.scoring.influence",),
    "physrover.domain.credit": ("physrover.domain.scoring.credit",),
}
"""{old module path: the modules that now hold what it held, searched in order}."""


class _StandIn(types.ModuleType):
    """An old module path: its attributes are found in the new modules."""

    def __init__(self, name: str, targets: tuple[str, ...]):
        super().__init__(name, f"Deprecated: see {', '.join(targets)}.")
        self.__targets = targets

    def __getattr__(self, attribute: str):
        for target in self.__targets:
            module = importlib.import_module(target)
            if hasattr(module, attribute):
                return getattr(module, attribute)
        raise AttributeError(f"module {self.__name__!r} (now {', '.join(self.__targets)}) "
                             f"has no attribute {attribute!r}")  # fmt: skip

    def __dir__(self):
        names = set()
        for target in self.__targets:
            names.update(dir(importlib.import_module(target)))
        return sorted(names)


class OldPathFinder(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """A meta-path finder that answers for :data:`OLD_PATHS` only (appended after Python's
    own finders, which no longer find those files)."""

    def find_spec(self, fullname, path=None, target=None):
        if fullname not in OLD_PATHS:
            return None
        return importlib.util.spec_from_loader(fullname, self)

    def create_module(self, spec):
        targets = OLD_PATHS[spec.name]
        warnings.warn(f"{spec.name} is now {' and '.join(targets)}; the old path goes in the "
                      "next release", DeprecationWarning, stacklevel=2)  # fmt: skip
        return _StandIn(spec.name, targets)

    def exec_module(self, module) -> None:
        pass


def install() -> None:
    """Add the finder to ``sys.meta_path`` (once)."""
    if not any(isinstance(f, OldPathFinder) for f in sys.meta_path):
        sys.meta_path.append(OldPathFinder())
