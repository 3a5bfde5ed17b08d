"""Run a Python program and, as it exits, name its numba-compiled code for ``perf``.

``perf record`` samples numba's machine code as anonymous addresses (``[JIT]``); perf
names them from ``/tmp/perf-PID.map`` if the process writes one. This runs a console
script (``physrover``) or a ``.py`` file in this process and, at its exit, writes that map:
each compiled kernel's entry (and its CPython wrapper) by module and name. Functions numba
inlined are inside their caller's range; the code after a kernel's entry up to the next
named one is its library's other functions (the non-inlined callees), so read a range's
hottest addresses against a disassembly rather than trusting its name blindly.

    perf record -F 2000 -e cpu-clock -o perf.data \\
        python tools/numba_perf_map.py physrover bench train --methods D --repeats 100
    perf report -i perf.data --no-children --sort sym

How the causes in docs/performance.md (2026-12-06) were found with it: samples in
``NRT_incref``/``NRT_decref`` (numba's reference counts: their ``lock inc``/``lock dec``)
traced to their callers by the return address that ``perf record --call-graph dwarf,64``
copies from the stack, and hot addresses disassembled from a copy of the process's
executable anonymous memory.
"""

from __future__ import annotations

import atexit
import gc
import os
import runpy
import shutil
import sys


def write_perf_map(path: str | None = None) -> int:
    """Write ``/tmp/perf-PID.map`` (or ``path``) for every compiled overload of every numba
    dispatcher in this process; returns how many entries."""
    from numba.core.dispatcher import Dispatcher

    entries = {}
    for obj in gc.get_objects():
        if not isinstance(obj, Dispatcher):
            continue
        name = f"{obj.py_func.__module__}.{obj.py_func.__qualname__}"
        for result in obj.overloads.values():
            for symbol, label in (
                (result.fndesc.llvm_func_name, name),
                (result.fndesc.llvm_cpython_wrapper_name, f"{name}[wrapper]"),
            ):
                try:
                    address = result.library.get_pointer_to_function(symbol)
                except Exception:  # noqa: BLE001 - a symbol the library does not export
                    continue
                if address:
                    entries[address] = label
    starts = sorted(entries)
    with open(path or f"/tmp/perf-{os.getpid()}.map", "w") as out:
        for i, start in enumerate(starts):
            size = starts[i + 1] - start if i + 1 < len(starts) else 0x10000
            out.write(f"{start:x} {min(size, 0x100000):x} {entries[start]}\n")
    return len(starts)


def main() -> None:
    if len(sys.argv) < 2:
        raise SystemExit("usage: python tools/numba_perf_map.py PROGRAM [ARG ...]")
    program = sys.argv[1]
    path = program if program.endswith(".py") else shutil.which(program)
    if path is None:
        raise SystemExit(f"{program}: not a .py file or a program on PATH")
    atexit.register(write_perf_map)
    sys.argv = [path, *sys.argv[2:]]
    runpy.run_path(path, run_name="__main__")


if __name__ == "__main__":
    main()
