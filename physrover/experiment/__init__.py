"""Runs and what runs them: the run directory and everything that trains, resumes,
sweeps, evaluates, plays back and benchmarks.

- :mod:`~physrover.experiment.store`: the run-directory store (paths, atomic writes, the
  checkpoint, champion snapshots); the unit of durability; metrics.csv's rows are
  :mod:`~physrover.experiment.metrics_file`'s;
- :mod:`~physrover.experiment.training`: :func:`~physrover.experiment.training.train`, a run
  of the CCEA or a gradient-based trainer (:mod:`~physrover.experiment.trainer_runs`),
  started or resumed, in one run loop (:mod:`~physrover.experiment.loop`);
- :mod:`~physrover.experiment.stops`: Ctrl-C and SIGTERM as requests to stop at a checkpoint;
- :mod:`~physrover.experiment.provenance`: the code and machine of every start and resume;
- :mod:`~physrover.experiment.sweep`: sweep files, their runs and their status;
  :mod:`~physrover.experiment.execute`: running them on a process pool, or on Ray
  (:mod:`~physrover.experiment.on_ray`);
- :mod:`~physrover.experiment.evaluate`, :mod:`~physrover.experiment.playback`: a run's
  champions on fresh episodes, as numbers and as videos;
- :mod:`~physrover.experiment.bench`: benchmarks (not tests).

May import: :mod:`physrover.core`, :mod:`physrover.config`, :mod:`physrover.domain`,
:mod:`physrover.viz`, :mod:`physrover.envs`, :mod:`physrover.learn`, :mod:`physrover.marl`.
"""
