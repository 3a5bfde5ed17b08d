"""Crashes for test_durability, run in a process of their own (``python tests/crashes.py``).

The process imports physrover once, then forks a child per crash, so each crash is a real
process death (SIGKILL) or a real error exit, not an exception a test catches. Its
children inherit the compiled kernels, so a crash costs milliseconds, not an import. It
keeps to one thread (no BLAS or numba pool: see ``main``), which is what makes forking
safe.

    python tests/crashes.py faults ROOT GENERATION LEARNER    a run per fault at each step
                                                              of the checkpoint of GENERATION
    python tests/crashes.py kill-loop RUN KILLS SEED   SIGKILL a run at random points,
                                                       resuming it each time, KILLS times

Both print one JSON line describing what they did; test_durability resumes and compares.
"""

from __future__ import annotations

import errno
import json
import os
import random
import signal
import sys
import time
from pathlib import Path

GENERATIONS = 6
CONFIG = dict(n_rovers=3, n_req=1, population=6, steps=15, method="max-critic",
              checkpoint_every=2, eval_episodes=2, seed=3,
              generations=GENERATIONS)  # fmt: skip
# The CCEA's max critic ([critic]), and the gradient-based trainers, which share the run
# directory's checkpoint: 6 iterations each.
LEARNERS = {
    "ccea": dict(replay_pairs=400),
    "mappo": dict(method="mappo", num_envs=4, total_episodes=24, poi_ring_radius=5.0),
    "maddpg": dict(method="maddpg", num_envs=4, total_episodes=24, poi_ring_radius=5.0,
                   warmup_steps=40, batch_size=32, buffer_capacity=200, update_every=10),
}  # fmt: skip

# The calls a checkpoint makes that can fail or be interrupted: each is a step at which a
# fault is injected. os.write may also be cut in the middle (half its bytes written).
STEPS = ("write", "fsync", "replace")


def config(learner: str = "ccea"):
    """The run's config: the CCEA's (``ccea``) or a trainer's (``mappo``, ``maddpg``)."""
    from physrover.config import RunConfig

    return RunConfig().with_overrides({**CONFIG, **LEARNERS[learner]})


def _child(work, errors: Path | None = None) -> int:
    """Fork; the child runs ``work()`` and exits with its return code: 2 on a RunError,
    3 on another exception, whose one-line message goes to the file ``errors``."""
    pid = os.fork()
    if pid == 0:
        code = 1
        try:
            code = work()
        except BaseException as exc:  # noqa: BLE001 (the child reports, the parent judges)
            from physrover.experiment.store import RunError

            code = 2 if isinstance(exc, RunError) else 3
            if errors is not None:
                errors.write_text(f"{type(exc).__name__}: {exc}")
        finally:
            os._exit(code)
    return pid


def _status(pid: int) -> str:
    _, status = os.waitpid(pid, 0)
    if os.WIFSIGNALED(status):
        return signal.Signals(os.WTERMSIG(status)).name
    return f"exit {os.WEXITSTATUS(status)}"


def _inject(generation: int, step: int, mode: str) -> None:
    """Make the ``step``-th I/O call (counting os.write, os.fsync, os.replace) of the
    checkpoint of ``generation`` fail: ``kill`` before it, ``torn`` (os.write: half the
    bytes, then killed), ``enospc`` (raises, the disk is full)."""
    from physrover.experiment import loop

    count = [None]  # None outside the target checkpoint, else the calls seen so far

    def fault(name, real):
        def call(*args):
            if count[0] is not None:
                count[0] += 1
                if count[0] == step:
                    if mode == "enospc":
                        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
                    if mode == "torn" and name == "write":
                        real(args[0], bytes(args[1])[: max(1, len(args[1]) // 2)])
                    os.kill(os.getpid(), signal.SIGKILL)
            return real(*args)

        return call

    for name in STEPS:
        setattr(os, name, fault(name, getattr(os, name)))
    real_save = loop.save_state

    def save_state(run_dir, learner):
        count[0] = 0 if learner.generation == generation else None
        try:
            real_save(run_dir, learner)
        finally:
            count[0] = None
        if learner.generation == generation and step == 0:  # after the whole checkpoint
            os.kill(os.getpid(), signal.SIGKILL)

    loop.save_state = save_state  # what the training loop calls


def _count_steps(root: Path, generation: int, learner: str) -> list[str]:
    """The I/O calls of the checkpoint of ``generation``, by name, in order."""
    from physrover.experiment import loop, training

    seen: list[str] = []
    active = [False]
    reals = {name: getattr(os, name) for name in STEPS}

    def spy(name):
        def call(*args):
            if active[0]:
                seen.append(name)
            return reals[name](*args)

        return call

    real_save = loop.save_state

    def save_state(run_dir, learner):
        active[0] = learner.generation == generation
        try:
            real_save(run_dir, learner)
        finally:
            active[0] = False

    def work():
        for name in STEPS:
            setattr(os, name, spy(name))
        loop.save_state = save_state  # what the training loop calls
        training.train(config(learner), root / "count", progress=False)
        (root / "steps.json").write_text(json.dumps(seen))
        return 0

    errors = root / "count.error"
    status = _status(_child(work, errors))
    assert status == "exit 0", errors.read_text() if errors.exists() else status
    return json.loads((root / "steps.json").read_text())


def last_saved(out: Path, learner: str) -> int | None:
    """The generation of the checkpoint a resume of ``out`` starts from (None: none)."""
    from physrover.core.registry import TRAINERS
    from physrover.experiment.store import load_state
    from physrover.learn.ccea import CCEA

    cfg = config(learner)
    if cfg.trainer is None:
        meta = load_state(out, CCEA(cfg))
    else:
        meta = load_state(out, TRAINERS[cfg.learn.method].load()(cfg.trainer, cfg.domain))
    return None if meta is None else meta["generation"]


def faults(root: Path, generation: int, learner: str) -> dict:
    """A run for each fault of the checkpoint of ``generation``: killed before each of its
    I/O calls and just after the whole checkpoint, killed in the middle of each write, and
    the disk full at each call; then resumed to its end. Also the uninterrupted run,
    ``reference``. Everything trains here, in one thread: a trainer's torch sums in
    another order with more threads."""
    from physrover.experiment import training

    steps = _count_steps(root, generation, learner)
    reference = _status(_child(lambda: training.train(config(learner), root / "reference",
                                                  progress=False) and 0))  # fmt: skip
    assert reference == "exit 0", reference
    scenarios = [("kill", k) for k in range(len(steps) + 1)]  # 0: after the checkpoint
    scenarios += [("torn", k + 1) for k, name in enumerate(steps) if name == "write"]
    scenarios += [("enospc", k + 1) for k in range(len(steps))]
    done = []
    for mode, step in scenarios:
        out = root / f"{mode}-{step}"

        def work(mode=mode, step=step, out=out):
            _inject(generation, step, mode)
            training.train(config(learner), out, progress=False)
            return 0

        errors = root / f"{mode}-{step}.error"
        status = _status(_child(work, errors))
        error = errors.read_text() if errors.exists() else None
        left = len(list(out.rglob(".*.tmp")))  # temporary files the crash left
        saved = last_saved(out, learner)
        resumed = _status(_child(lambda out=out: training.train(None, out, resume=True,
                                                            progress=False) and 0))  # fmt: skip
        done.append({"dir": out.name, "mode": mode, "step": step, "status": status,
                     "call": "after the checkpoint" if step == 0 else steps[step - 1],
                     "error": error, "temporaries": left, "saved": saved,
                     "resumed": resumed})  # fmt: skip
    return {"steps": steps, "scenarios": done}


def kill_loop(out: Path, kills: int, seed: int, generations: int) -> dict:
    """Train a run (checkpointing every generation) to ``generations``, SIGKILLing it at
    random instants and resuming, until ``kills`` kills have landed; then let it finish."""
    from physrover.experiment import store, training

    rng = random.Random(seed)
    cfg = config().with_overrides({"checkpoint_every": 1})

    def work():
        started = (out / store.CONFIG).exists()
        training.train(None if started else cfg, out, resume=started, generations=generations,
                   progress=False)  # fmt: skip
        return 0

    def uninterrupted():
        training.train(cfg, out.parent / "reference", generations=generations, progress=False)
        return 0

    assert _status(_child(uninterrupted)) == "exit 0"
    # Each life is killed once the run has checkpointed a target generation, plus a random
    # few milliseconds (so a kill falls anywhere in a generation: stepping, mid-write,
    # between renames), or, with target 0, at once (while it starts or loads). The targets
    # spread the kills over the generations left, so however slow the machine (a loaded
    # CI runner starts a child in seconds), the run cannot end before the last kill: the
    # last target leaves 10 generations, more than the few milliseconds after it can step.
    landed, lives, start = [], 0, time.monotonic()
    while len(landed) < kills:
        lives += 1
        before = store.last_checkpoint(out) or 0
        room = max(0, (generations - 10 - before) // (kills - len(landed)))
        target = before + rng.randint(0, room)
        pid = _child(work)
        deadline = time.monotonic() + 120.0
        while (store.last_checkpoint(out) or 0) < target and time.monotonic() < deadline:
            time.sleep(0.0005)
        time.sleep(rng.uniform(0.0, 0.01))
        os.kill(pid, signal.SIGKILL)
        status = _status(pid)
        if status != "SIGKILL":  # it finished (or failed) before the kill
            raise RuntimeError(
                f"life {lives} ended {status} at checkpoint "
                f"{store.last_checkpoint(out)} after {len(landed)} kills"
            )
        landed.append(store.last_checkpoint(out))
    last = _status(_child(work))
    return {"kills": len(landed), "lives": lives, "checkpoints_at_kill": landed,
            "final": last, "seconds": time.monotonic() - start}  # fmt: skip


def main(argv: list[str]) -> None:
    # One thread: BLAS and numba pools would make forking unsafe; the runs use neither.
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
        os.environ[var] = "1"
    from physrover.experiment import training

    command, path = argv[0], Path(argv[1])
    path.mkdir(parents=True, exist_ok=True)
    if command == "faults":
        training.train(config(argv[3]), path / "warm-up", progress=False)  # compile once
        report = faults(path, int(argv[2]), argv[3])
    else:
        training.train(config(), path / "warm-up", generations=1, progress=False)
        report = kill_loop(path / "run", int(argv[2]), int(argv[3]), int(argv[4]))
    print(json.dumps(report), flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
