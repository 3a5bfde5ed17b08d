"""How physrover compiles its kernels: numba, nopython, cached on disk.

The compiled kernels are the one implementation of the hot equations (the world step, the
policies' forward pass, the critics' values and updates). They compile on first use (5-10 s)
and numba caches them on disk, so later processes load them. ``NUMBA_DISABLE_JIT=1`` runs
them as plain Python, for debugging with a debugger or prints (slow, but the same results).

The on-disk cache lives in ``~/.cache/physrover/numba-KEY`` (under ``$XDG_CACHE_HOME`` or
``$NUMBA_CACHE_DIR`` if set), KEY a hash of every source file of the package. numba checks
only a kernel's own file when it loads it from its cache, not the files of the kernels it
calls: a kernel calling one from another module whose signature or body changed would load
stale machine code (this happened: a test suite passed on a cache that a clean clone
failed). Any change to the package's sources now compiles everything afresh once; the
directories of earlier versions are left in place (a few tens of MB each; delete them at
will). Setting numba's cache directory is process-wide: another library's cached numba
functions decorated in the same process after physrover's kernels land there too.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

_PACKAGE = Path(__file__).parent.parent  # physrover/, above this wing
_cache_dir: str | None = None


def source_digest(root: Path = _PACKAGE) -> str:
    """sha256 (hex) of the ``*.py`` files under ``root`` (the package's sources): each
    one's path relative to ``root`` (POSIX form) and bytes, in the sorted order of those
    paths; ``""`` if there are none (a package imported from a zip). Equal sources give
    equal digests wherever installed (``__pycache__`` holds no ``*.py``; dangling links,
    e.g. an editor's lock files, are skipped)."""
    files = sorted((p.relative_to(root).as_posix(), p) for p in root.rglob("*.py") if p.is_file())
    if not files:
        return ""
    digest = hashlib.sha256()
    for relative, path in files:
        data = path.read_bytes()
        digest.update(f"{relative}\0{len(data)}\0".encode())
        digest.update(data)
    return digest.hexdigest()


def sources_key(root: Path = _PACKAGE) -> str:
    """The kernels' cache key: the first 16 hex digits of :func:`source_digest`."""
    return source_digest(root)[:16]


def cache_dir() -> str:
    """Where this version of the package's kernels are cached (module docstring)."""
    base = os.environ.get("NUMBA_CACHE_DIR") or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache"), "physrover"
    )
    return os.path.join(base, f"numba-{sources_key()}")


def _numba():
    """numba, its cache directory set to :func:`cache_dir` for the kernel about to be
    decorated (set again every time: numba re-reads its configuration from the environment
    when a ``NUMBA_*`` variable changes, which would drop it)."""
    global _cache_dir
    import numba

    if _cache_dir is None:
        _cache_dir = cache_dir()
    numba.config.CACHE_DIR = _cache_dir
    return numba


def jit(fn):
    """Compile ``fn`` with numba (nopython, cached on disk); compilation happens on first call.

    No ``fastmath``: the kernel keeps IEEE semantics (no reassociation, no fused
    multiply-adds), so its results do not depend on the CPU's vector width.

    ``error_model="numpy"``: a float division by zero gives inf or NaN as in numpy, instead
    of Python's ZeroDivisionError. The kernels never divide by zero (their divisors are
    bounded away from it, e.g. by ``d_min``), and the check Python's model adds to every
    division is a branch that stops the compiler vectorising the loop around it.
    """
    return _numba().njit(cache=True, nogil=True, error_model="numpy")(fn)


def jit_inline(fn):
    """As :func:`jit`, but inlined into each compiled caller (numba's ``inline="always"``):
    for small helpers called once per object of a hot loop, where a call that passes
    arrays costs more than the helper's work (their reference counts change at every
    call)."""
    return _numba().njit(cache=True, nogil=True, error_model="numpy", inline="always")(fn)


def jit_reassoc(fn):
    """As :func:`jit`, but the compiler may reassociate floating-point sums (``fastmath``
    flag ``reassoc`` only), which lets it vectorise reductions. Results stay deterministic
    on a machine; their last bits depend on its vector width."""
    return _numba().njit(cache=True, nogil=True, error_model="numpy", fastmath={"reassoc"})(fn)


def dims(n: int) -> tuple[int, ...]:
    """``n`` zeros: kernels read ``len(dims)`` as a size the compiler knows, so each size
    (a sensor's observations, its sectors) gets its own compiled version with its loops over
    that size unrolled (what hand-unrolled loops did for the paper's 8 observations and 10
    critic inputs)."""
    return (0,) * n


def bind(kernel, *args, packed: bool = False):
    """``kernel``'s compiled version for the types of ``args``, callable without numba's
    dispatch (which types every argument at every call: a tuple of arrays, as a world's
    plan, costs microseconds in Python). Compiles it, or loads it from the cache, first.
    The caller must pass arguments of the same types. With ``packed``, the last of
    ``args`` is the tuple of ``kernel``'s ``*args`` parameter, and the returned function
    takes it as one tuple too (unpacking it at every call cost a microsecond). Under
    ``NUMBA_DISABLE_JIT=1`` this calls ``kernel`` itself."""
    if not hasattr(kernel, "overloads"):
        return (lambda *given: kernel(*given[:-1], *given[-1])) if packed else kernel
    flat = (*args[:-1], *args[-1]) if packed else args
    _, folded = kernel.fold_argument_types(tuple(kernel.typeof_pyval(a) for a in flat), {})
    signature = tuple(folded)  # a ``*args`` parameter folded into one tuple, as numba does
    kernel.compile(signature)
    return kernel.overloads[signature].entry_point
