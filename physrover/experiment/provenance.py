"""What code and machine produced a run: the ``provenance.json`` of a run directory.

A run may be trained in pieces (resumed after an interruption, or on another machine, as
long sweeps are here), and a resumed run is bit-identical to an uninterrupted one only if
the code is the same and the critics' reassociated sums (:mod:`physrover.learn.kernels`)
see the same vector width. So every start and every resume appends a *segment*::

    {"segments": [{"from_generation": 0, "physrover": "0.4.0",
                   "code": "<sha256 of the package's sources>", "git": "<commit>" or null,
                   "python": ..., "numpy": ..., "numba": ..., "torch": ..., "pymunk": ...,
                   "cpu": "<model name>", "llvm_cpu": "znver4", "cpu_features": "<digest>",
                   "machine": "x86_64",
                   "imports": {"<SPEC>": {"file": "<path>", "sha256": "<digest>"}},
                   "started": "<UTC ISO time>"},
                  ...]}

``code`` (:func:`code_fingerprint`) identifies the installed package's sources exactly
(every ``.py`` file, docstrings and help texts included), also in a non-editable install of
a ``git archive``, which has no commit to ask; ``git`` is the commit of a checkout the
package is imported from (with ``+dirty`` for uncommitted changes to tracked files), else
null. Both are taken once per process, when its first run starts. ``llvm_cpu`` and
``cpu_features`` (a digest of the features numba compiles for) say what the kernels were
compiled for. ``imports`` (only when there are any) lists the researcher's own modules
loaded by ``--import``, ``PHYSROVER_IMPORT`` or a sweep's ``imports``
(:mod:`physrover.core.plugins`), each with its file and the digest of its source. A resume
with other code, or for another ``llvm_cpu`` or ``cpu_features``,
than the last segment's warns (:func:`with_segment`;
:func:`physrover.experiment.store.record_provenance` writes the file).
"""

from __future__ import annotations

import datetime
import functools
import hashlib
import json
import platform
import subprocess
import warnings
from importlib import metadata
from pathlib import Path

from physrover.core import plugins
from physrover.core.compiled import source_digest

PROVENANCE = "provenance.json"
PACKAGE_DIR = Path(__file__).resolve().parent.parent  # physrover/, above this wing


@functools.cache
def code_fingerprint() -> str | None:
    """:func:`physrover.core.compiled.source_digest` of this installed physrover package (None
    if it has no ``.py`` sources to read), taken once per process."""
    return source_digest(PACKAGE_DIR) or None


@functools.cache
def _git_commit() -> str | None:
    """The commit of the checkout this package is imported from (``+dirty`` with changes to
    tracked files), or None outside one (an installed package) or without git."""
    root = PACKAGE_DIR.parent
    if not (root / ".git").exists():
        return None
    try:
        head = subprocess.run(["git", "-C", str(root), "rev-parse", "HEAD"], capture_output=True,
                              text=True, check=True, timeout=10).stdout.strip()  # fmt: skip
        dirty = subprocess.run(["git", "--no-optional-locks", "-C", str(root), "status",
                                "--porcelain", "--untracked-files=no"], capture_output=True,
                               text=True, check=True, timeout=10).stdout.strip()  # fmt: skip
    except (OSError, subprocess.SubprocessError):
        return None
    return head + ("+dirty" if dirty else "")


def cpu_model() -> str:
    """The CPU's model name (``/proc/cpuinfo`` on Linux, else ``platform.processor()``)."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


@functools.cache
def _compile_target() -> tuple[str | None, str | None]:
    """(CPU name, digest of the CPU features) numba compiles the kernels for: its
    ``NUMBA_CPU_NAME`` / ``NUMBA_CPU_FEATURES`` if set, else the host's as LLVM sees them
    (e.g. ``znver4``; a VM may hide features). They decide the kernels' vector width, and so
    the last bits of the critics' reassociated sums. (None, None) if they cannot be read."""
    try:
        import llvmlite.binding
        import numba

        name = numba.config.CPU_NAME or llvmlite.binding.get_host_cpu_name()
        features = numba.config.CPU_FEATURES or llvmlite.binding.get_host_cpu_features().flatten()
    except Exception:  # provenance must not stop a run
        return None, None
    return str(name), hashlib.sha256(str(features).encode()).hexdigest()[:12]


def _version(package: str) -> str | None:
    try:
        return metadata.version(package)
    except metadata.PackageNotFoundError:
        return None


def describe(from_generation: int) -> dict:
    """This process's segment: the code and machine that train from ``from_generation``."""
    from physrover import __version__

    return {
        "from_generation": int(from_generation),
        "physrover": __version__,
        "code": code_fingerprint(),
        "git": _git_commit(),
        "python": platform.python_version(),
        **{name: _version(name) for name in ("numpy", "numba", "torch", "pymunk")},
        "cpu": cpu_model(),
        "llvm_cpu": _compile_target()[0],
        "cpu_features": _compile_target()[1],
        "machine": platform.machine(),
        **({"imports": imports} if (imports := plugins.loaded()) else {}),
        "started": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
    }


def _warn(message: str) -> None:
    warnings.warn(message, RuntimeWarning, stacklevel=4)  # the train call behind the resume


def read_provenance(run_dir: Path) -> list[dict]:
    """The segments of a run's ``provenance.json`` ([] if it has none, as runs made before
    it was recorded)."""
    path = Path(run_dir) / PROVENANCE
    if not path.is_file():
        return []
    return list(json.loads(path.read_text())["segments"])


def with_segment(run_dir: Path, from_generation: int) -> list[dict]:
    """The segments ``provenance.json`` should hold once this process trains ``run_dir``
    from ``from_generation``: the recorded ones before it, then this process's; warns if
    the run was trained so far with other code than this, or with kernels compiled for
    another CPU (by the last segment's ``code``, ``llvm_cpu`` and ``cpu_features``; an
    unknown code, None, is not compared). Earlier segments from ``from_generation`` on are
    dropped: they left no checkpoint past it (a start or resume that stopped before its
    first checkpoint)."""
    segments = [s for s in read_provenance(run_dir) if s["from_generation"] < from_generation]
    segment = describe(from_generation)
    if segments:
        before = segments[-1]
        since = f"generation {before['from_generation']} on"
        old, new = before["code"], segment["code"]
        if None not in (old, new) and old != new:
            _warn(
                f"{run_dir}: resuming at generation {from_generation} with other code than "
                f"{since} was trained with (physrover {before['physrover']}, code {old[:12]}; "
                f"now {segment['physrover']}, code {new[:12]}): the run is bit-identical to "
                "an uninterrupted one only if the training code is the same"
            )
        target = ("llvm_cpu", "cpu_features")
        if any(before.get(k) != segment[k] for k in target):
            _warn(
                f"{run_dir}: resuming at generation {from_generation} with kernels compiled "
                f"for another CPU than {since} was ({before.get('llvm_cpu')}, now "
                f"{segment['llvm_cpu']}): the critics' sums may round differently, so the "
                "run may not be bit-identical to an uninterrupted one"
            )
        for key, now in segment.get("imports", {}).items():
            then = before.get("imports", {}).get(key)
            if then is not None and then["sha256"] != now["sha256"]:
                _warn(
                    f"{run_dir}: resuming at generation {from_generation} with {key} changed "
                    f"since {since} (sha256 {then['sha256']}, now {now['sha256']}): the run is "
                    "bit-identical to an uninterrupted one only if its parts are the same"
                )
    return [*segments, segment]
