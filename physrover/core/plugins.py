"""A researcher's own parts on the command line: modules imported before a command runs.

A scenario, sensor, motion model, credit signal, fitness method or trainer of one's own is
registered when its module is imported (docs/extending.md). From Python that is
an ``import``; for ``physrover`` it is ``physrover --import SPEC COMMAND ...``, a sweep
file's ``[sweep] imports = [SPEC, ...]``, or the ``PHYSROVER_IMPORT`` environment variable
(SPECs joined by ``os.pathsep``, ``:`` on Linux and macOS). A SPEC is

- the path of a ``.py`` file (relative to the current directory, or for a sweep file to the
  sweep file's directory); the file's directory is added to ``sys.path``, so it imports
  its sibling files as a script would;
- or a module name: an installed module (``pip install -e .`` of one's own package), or a
  ``NAME.py`` file in the sweep file's directory or the current directory, which is then
  taken as that file.

:func:`load` imports each once per process (a file loaded by path and the same file
imported by name are one module) and writes every loaded SPEC into ``PHYSROVER_IMPORT`` (a
file as its absolute path), so the processes a sweep starts, its pool's workers and Ray's
workers on this machine, import the same parts: :func:`load_from_environment` is the first
thing a sweep worker does. A module whose import failed fails again with the same error in
the same process, instead of half-registering twice. :func:`loaded` gives each SPEC's file
and the digest of its source when it was imported, which a run's provenance records.
"""

from __future__ import annotations

import dataclasses
import hashlib
import importlib
import importlib.util
import os
import sys
from pathlib import Path

ENV = "PHYSROVER_IMPORT"


class PluginError(ValueError):
    """A SPEC names no module or file that can be imported."""


@dataclasses.dataclass(frozen=True)
class _Loaded:
    module: str
    """Its name in ``sys.modules``."""
    file: str | None
    """Its source file (absolute), if it has one."""
    sha256: str | None
    """The first 16 hex digits of the sha256 of that file's bytes, read at import."""


_loaded: dict[str, _Loaded] = {}
"""Key (an installed module's name, or a file's absolute path) -> what it loaded."""
_failed: dict[str, Exception] = {}
"""Key -> the error its import raised in this process."""


def _is_file(spec: str) -> bool:
    return spec.endswith(".py") or "/" in spec or os.sep in spec


def _resolve(spec: str, base: Path | None) -> str:
    """The key of ``spec``: a file's absolute path, or an installed module's name."""
    if _is_file(spec):
        path = Path(spec).expanduser()
        return str(((base or Path.cwd()) / path).resolve())  # an absolute path stays itself
    if importlib.util.find_spec(spec.split(".")[0]) is not None:
        return spec
    folders = list(dict.fromkeys(d for d in (base, Path.cwd()) if d is not None))
    for folder in folders:
        if "." not in spec and (folder / f"{spec}.py").is_file():
            return str((folder / f"{spec}.py").resolve())
    where = " or ".join(str(f) for f in folders)
    raise PluginError(f"cannot import {spec!r}: no installed module of that name and no "
                      f"{spec}.py in {where} (a file elsewhere: give its path)")  # fmt: skip


def _source(module) -> str | None:
    file = getattr(module, "__file__", None)
    return str(Path(file).resolve()) if file else None


def _record(module) -> _Loaded:
    file = _source(module)
    digest = hashlib.sha256(Path(file).read_bytes()).hexdigest()[:16] if file else None
    return _Loaded(module.__name__, file, digest)


def _import(key: str) -> _Loaded:
    if not _is_file(key):
        spec = importlib.util.find_spec(key.split(".")[0])
        origin = str(Path(spec.origin).resolve()) if spec and spec.origin else None
        for loaded in _loaded.values():  # the same file, loaded by its path before
            if origin is not None and loaded.file == origin and "." not in key:
                return loaded
        try:
            return _record(importlib.import_module(key))
        except ModuleNotFoundError as exc:
            if exc.name == key:
                raise PluginError(f"cannot import {key!r}: no such module") from None
            raise  # a module the SPEC imports is missing: the user's traceback says where
    path = Path(key)
    if not path.is_file():
        raise PluginError(f"cannot import {key}: no such file")
    for module in list(sys.modules.values()):  # imported by name already (`import my_parts`)
        if _source(module) == key:
            return _record(module)
    if str(path.parent) not in sys.path:
        sys.path.append(str(path.parent))  # its siblings import as from a script
    name = f"physrover_plugin_{path.stem}_{hashlib.sha256(key.encode()).hexdigest()[:8]}"
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # dataclasses and pickling look their module up by name
    try:
        spec.loader.exec_module(module)
    except BaseException:
        del sys.modules[name]
        raise
    return _record(module)


def load(specs=(), base: str | Path | None = None) -> list[str]:
    """Import each SPEC of ``specs`` not imported yet (paths and bare names are looked up in
    ``base`` first, then the current directory) and write the loaded SPECs into
    ``PHYSROVER_IMPORT``; returns the modules' names.

    Raises :class:`PluginError` for a SPEC that names no module or file; an error inside
    the module itself propagates with its own traceback (and again, the same, on a retry).
    """
    base = Path(base).resolve() if base is not None else None
    names = []
    for spec in specs:
        spec = spec.strip()
        if not spec:
            continue
        key = _resolve(spec, base)
        if key in _failed:
            raise _failed[key]
        if key not in _loaded:
            try:
                _loaded[key] = _import(key)
            except PluginError:
                raise
            except Exception as exc:  # the module's own error: registrations may be half done
                _failed[key] = exc
                raise
        names.append(_loaded[key].module)
    _export()
    return names


def load_from_environment() -> list[str]:
    """:func:`load` the SPECs of ``PHYSROVER_IMPORT`` (what a sweep's worker processes do)."""
    return load(os.environ.get(ENV, "").split(os.pathsep))


def loaded() -> dict[str, dict[str, str | None]]:
    """Each loaded SPEC (a file's absolute path or a module's name) -> ``{"file": its source
    file, "sha256": the digest of the file when it was imported}``: what a run's provenance
    records."""
    return {key: {"file": v.file, "sha256": v.sha256} for key, v in _loaded.items()}


def _export() -> None:
    """``PHYSROVER_IMPORT`` := every loaded key, then any entry already there that is not
    (yet) loaded here; a relative entry that was loaded is replaced by its absolute key."""
    entries = list(_loaded)
    for entry in os.environ.get(ENV, "").split(os.pathsep):
        if not entry or entry in entries:
            continue
        try:
            if _resolve(entry, None) in _loaded:
                continue
        except PluginError:
            pass
        entries.append(entry)
    if entries:
        os.environ[ENV] = os.pathsep.join(entries)
