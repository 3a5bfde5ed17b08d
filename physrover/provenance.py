"""What code and machine produced a run: the ``provenance.json`` of a run directory.

A run may be trained in pieces (resumed after an interruption, or on another machine, as
long sweeps are here), and a resumed run is bit-identical to an uninterrupted one only if
the code is the same and the critics' reassociated sums (:mod:`physrover.learn.kernels`)
see the same vector width. So every start and every resume appends a *segment*::

    {"segments": [{"from_generation": 0, "physrover": "0.4.0",
                   "code": "<sha256 of the package's sources>", "git": "<commit>" or null,
                   "python": ..., "numpy": ..., "numba": ..., "torch": ..., "pymunk": ...,
                   "cpu": "<model name>", "llvm_cpu": "znver4", "machine": "x86_64",
                   "started": "<UTC ISO time>"},
                  ...]}

``code`` (:func:`code_fingerprint`) identifies the installed package's source exactly, also
in a non-editable install of a ``git archive``, which has no commit to ask; ``git`` is the
commit of a checkout the package is imported from (with ``+dirty`` for uncommitted changes),
else null. A resume with other code than the last segment's warns (:func:`record_segment`).
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

PROVENANCE = "provenance.json"
PACKAGE_DIR = Path(__file__).resolve().parent


def fingerprint(package_dir: Path) -> str:
    """sha256 (hex) over the ``.py`` files below ``package_dir``: each file's path relative
    to it and its bytes, in sorted order. Equal for equal sources wherever installed."""
    digest = hashlib.sha256()
    for path in sorted(package_dir.rglob("*.py")):
        relative = path.relative_to(package_dir).as_posix()
        data = path.read_bytes()
        digest.update(f"{relative}\0{len(data)}\0".encode())
        digest.update(data)
    return digest.hexdigest()


@functools.cache
def code_fingerprint() -> str:
    """:func:`fingerprint` of this installed physrover package."""
    return fingerprint(PACKAGE_DIR)


def _git_commit() -> str | None:
    """The commit of the checkout this package is imported from (``+dirty`` with changes to
    tracked files), or None outside one (an installed package) or without git."""
    root = PACKAGE_DIR.parent
    if not (root / ".git").exists():
        return None
    try:
        head = subprocess.run(["git", "-C", str(root), "rev-parse", "HEAD"], capture_output=True,
                              text=True, check=True, timeout=10).stdout.strip()  # fmt: skip
        dirty = subprocess.run(["git", "-C", str(root), "status", "--porcelain",
                                "--untracked-files=no"], capture_output=True, text=True,
                               check=True, timeout=10).stdout.strip()  # fmt: skip
    except (OSError, subprocess.SubprocessError):
        return None
    return head + ("+dirty" if dirty else "")


def _cpu() -> str:
    """The CPU's model name (``/proc/cpuinfo`` on Linux, else ``platform.processor()``)."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def _llvm_cpu() -> str | None:
    """The CPU numba compiles the kernels for (LLVM's name, e.g. ``znver4``): what decides
    their vector width, and so the last bits of the critics' reassociated sums."""
    try:
        import llvmlite.binding

        return str(llvmlite.binding.get_host_cpu_name())
    except Exception:  # noqa: BLE001 - provenance must not stop a run
        return None


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
        "cpu": _cpu(),
        "llvm_cpu": _llvm_cpu(),
        "machine": platform.machine(),
        "started": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
    }


def read_provenance(run_dir: Path) -> list[dict]:
    """The segments of a run's ``provenance.json`` ([] if it has none, as runs made before
    it was recorded)."""
    path = Path(run_dir) / PROVENANCE
    if not path.is_file():
        return []
    return list(json.loads(path.read_text())["segments"])


def record_segment(run_dir: Path, from_generation: int) -> dict:
    """Append this process's segment to ``run_dir/provenance.json`` and return it; warn if
    the run was trained so far with other code than this (by the last segment's ``code``).
    Earlier segments from ``from_generation`` on are dropped: they left no checkpoint
    past it (a start or resume that stopped before its first checkpoint)."""
    run_dir = Path(run_dir)
    segments = [s for s in read_provenance(run_dir) if s["from_generation"] < from_generation]
    segment = describe(from_generation)
    if segments and segments[-1]["code"] != segment["code"]:
        before = segments[-1]
        warnings.warn(
            f"{run_dir}: resuming at generation {from_generation} with other code than "
            f"generation {before['from_generation']} on was trained with (physrover "
            f"{before['physrover']}, code {before['code'][:12]}; now {segment['physrover']}, "
            f"code {segment['code'][:12]}): the run is bit-identical to an uninterrupted one "
            "only if the training code is the same",
            RuntimeWarning,
            stacklevel=2,
        )
    segments.append(segment)
    tmp = run_dir / (PROVENANCE + ".tmp")
    tmp.write_text(json.dumps({"segments": segments}, indent=1) + "\n")
    tmp.replace(run_dir / PROVENANCE)
    return segment
