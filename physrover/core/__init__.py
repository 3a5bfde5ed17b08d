"""Plumbing every wing may use: nothing here knows the rover domain or a learner.

- :mod:`~physrover.core.registry`: the named registries (fitness methods, credit signals,
  scenarios, sensors, motion models, trainers) that config, CLI, plots and docs all read;
- :mod:`~physrover.core.compiled`: numba's on-disk cache of the compiled kernels;
- :mod:`~physrover.core.streams`: numpy generators' draws read inside compiled kernels;
- :mod:`~physrover.core.borrow`: a kernel's arrays without numba's atomic reference counts;
- :mod:`~physrover.core.threads`: pinning BLAS, OpenMP and torch to a number of threads;
- :mod:`~physrover.core.progress`: progress bars of long runs;
- :mod:`~physrover.core.plugins`: ``--import`` of a researcher's own parts;
- :mod:`~physrover.core.stats`: the statistics every report uses (Student-t intervals,
  permutation tests, Holm, rank correlation);
- :mod:`~physrover.core.deprecation`: old module paths that still import, with a warning;
- :mod:`~physrover.core.trees`: nested state as flat ``{"a/0/b": leaf}`` maps (checkpoints).

May import: the standard library and third-party packages only, never another wing.
"""
