"""A researcher's own parts on the command line: modules imported before a command runs.

A scenario, sensor, motion model, credit signal, fitness method or trainer of one's own is
registered when its module is imported (README: Extending physrover). From Python that is
an ``import``; for ``physrover`` it is ``physrover --import SPEC COMMAND ...``, a sweep
file's ``[sweep] imports = [SPEC, ...]``, or the ``PHYSROVER_IMPORT`` environment variable
(SPECs joined by ``os.pathsep``). A SPEC is a module name (``my_parts``, found on
``sys.path`` or in the current directory, as ``python -m`` finds it; a module found in the
current directory adds it to ``PYTHONPATH`` for child processes) or the path of a ``.py``
file.

:func:`load` imports each SPEC once per process and adds it to ``PHYSROVER_IMPORT`` (a file
as its absolute path), so the processes a sweep starts (its pool's workers, Ray's) import
the same parts: :func:`load_from_environment` is the first thing a sweep worker does.
:func:`loaded` says what was imported, for a run's provenance.
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.util
import os
import sys
from pathlib import Path

ENV = "PHYSROVER_IMPORT"

_loaded: dict[str, str] = {}
"""SPEC as recorded (a module name, or a file's absolute path) -> the module's name."""


class PluginError(ValueError):
    """A SPEC names no module or file that can be imported."""


def _is_file(spec: str) -> bool:
    return spec.endswith(".py") or "/" in spec or os.sep in spec


def _key(spec: str, base: Path | None) -> str:
    if not _is_file(spec):
        return spec
    path = Path(spec).expanduser()
    if not path.is_absolute():
        path = (base or Path.cwd()) / path
    return str(path.resolve())


def _import(key: str) -> str:
    if not _is_file(key):
        cwd = os.getcwd()
        if cwd not in sys.path and "" not in sys.path:
            sys.path.append(cwd)  # after the installed packages: a local file shadows none
            if importlib.util.find_spec(key.split(".")[0]) is not None:  # found there:
                _export_path(cwd)  # child processes look there too, whatever their cwd
        try:
            return importlib.import_module(key).__name__
        except ModuleNotFoundError as exc:
            if exc.name == key or key.startswith(f"{exc.name}."):  # the SPEC itself
                hint = f"a file: give its path, e.g. ./{key}.py"
                raise PluginError(
                    f"cannot import {key!r}: no such module on sys.path or in {cwd} ({hint})"
                ) from None
            raise  # a module the SPEC imports is missing: the user's traceback says where
    path = Path(key)
    if not path.is_file():
        raise PluginError(f"cannot import {key}: no such file")
    name = f"physrover_plugin_{path.stem}_{hashlib.sha256(key.encode()).hexdigest()[:8]}"
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # dataclasses and pickling look their module up by name
    try:
        spec.loader.exec_module(module)
    except BaseException:
        del sys.modules[name]
        raise
    return name


def load(specs=(), base: str | Path | None = None) -> list[str]:
    """Import each SPEC of ``specs`` not imported yet (a file relative to ``base``, default
    the current directory) and add it to ``PHYSROVER_IMPORT``; returns the modules' names.

    Raises :class:`PluginError` for a SPEC that names no module or file; an error inside
    the module itself propagates with its own traceback.
    """
    names = []
    base = Path(base) if base is not None else None
    for spec in specs:
        spec = spec.strip()
        if not spec:
            continue
        key = _key(spec, base)
        if key not in _loaded:
            _loaded[key] = _import(key)
        names.append(_loaded[key])
    _export()
    return names


def load_from_environment() -> list[str]:
    """:func:`load` the SPECs of ``PHYSROVER_IMPORT`` (what a sweep's worker processes do)."""
    return load(os.environ.get(ENV, "").split(os.pathsep))


def loaded() -> dict[str, str | None]:
    """Each imported SPEC -> the sha256 (first 16 hex digits) of its source file (None when
    it has no file of its own); what a run's provenance records."""
    out = {}
    for key, name in _loaded.items():
        file = getattr(sys.modules.get(name), "__file__", None)
        out[key] = hashlib.sha256(Path(file).read_bytes()).hexdigest()[:16] if file else None
    return out


def _export_path(directory: str) -> None:
    known = [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p]
    if directory not in known:
        os.environ["PYTHONPATH"] = os.pathsep.join([*known, directory])


def _export() -> None:
    known = [s for s in os.environ.get(ENV, "").split(os.pathsep) if s]
    new = [key for key in _loaded if key not in known]
    if new:
        os.environ[ENV] = os.pathsep.join(known + new)
