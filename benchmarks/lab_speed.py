"""Time a generation of the lab's own CCEA (AADILab/influence-shaping) on one of its configs,
single-threaded, for the side-by-side speed comparison with physrover (BENCHMARKS.md).

Run it in the lab's environment, not physrover's (its C++ core is JIT-compiled by cppyy:
cppyy 3.5.0 from PyPI builds it on Python 3.11), from a checkout of the lab's code:

    python3 -m venv venv-lab && venv-lab/bin/pip install cppyy==3.5.0 deap==1.4.1 \\
        numpy==2.1.2 PyYAML==6.0.2 tqdm==4.66.5 pandas matplotlib "setuptools<70"
    PYTHONPATH=LAB/src venv-lab/bin/python benchmarks/lab_speed.py LAB/example/results/config.yaml

It times the lab's second generation in a process of its own, three times (the lab's code
under cppyy 3.5 crashes many processes that build many envs, as issue 43 says: it starts
new ones, up to 15), and prints the median. Compare with
``physrover import-lab CONFIG -o lab.toml`` and ``physrover bench train --config lab.toml
--methods D`` on the same machine.
"""

from __future__ import annotations

import copy
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import yaml


def _reset_without_tuples() -> None:
    """cppyy 3.5's ``std::get`` cannot read the lab's ``env.reset()`` tuple of Eigen
    matrices (its class spelled ``Matrix<double,-1,-1,0>`` against the instantiation's
    spelled-out default arguments), so ``observations, _ = env.reset()`` fails; reset
    through a C++ helper that takes the observations out in C++ (the same reset and
    values; the rewards, which the lab drops there, are not read)."""
    import cppyy
    from influence.librovers import rovers

    cppyy.cppdef("namespace lab_speed { auto reset(rovers::Environment<rovers::CustomInit>& "
                 "env) { return std::get<0>(env.reset()); } }")  # fmt: skip
    env = rovers.Environment[rovers.CustomInit]
    env.reset = lambda self: (cppyy.gbl.lab_speed.reset(self), None)


def _keep_constraints() -> None:
    """``custom_env.createRoverPOI`` keeps no reference to the Python constraint it hands
    to C++, so a process that builds many envs (the lab builds one per team and rollout)
    crashes once Python frees one: keep every constraint alive (memory only)."""
    from influence import custom_env

    kept = []
    init = custom_env.AbstractRoverConstraint.__init__

    def keeping(self, *args, **kwargs):
        init(self, *args, **kwargs)
        kept.append(self)

    custom_env.AbstractRoverConstraint.__init__ = keeping


def generation_seconds(config: dict) -> float:
    """Wall seconds of the lab's second generation, as its ``runTrial`` plays it
    (selection, mutation, every team's rollout; multiprocessing off, nothing saved), after
    its first evaluation (which also compiles its C++ templates: left out)."""
    from influence.ccea_lib import CooperativeCoevolutionaryAlgorithm

    config = copy.deepcopy(config)
    config["processing"] = {"use_multiprocessing": False, "num_threads": 1}
    config["data"]["checkpoints"]["save"] = False
    for kind in config["data"].get("save_trajectories", {}).values():
        kind["switch"] = False
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "results" / "config.yaml"
        path.parent.mkdir()
        path.write_text(yaml.safe_dump(config))
        ccea = CooperativeCoevolutionaryAlgorithm(str(path))
        ccea.trial_dir = Path(folder) / "trial_0"
        ccea.init_trial_dir()
        agent_pops, team_pop, team_packs = ccea.init_trial(0)
        start = time.perf_counter()  # runTrial's loop body, without its checkpoint
        ccea.gen += 1
        ccea.set_generation_seed(0)
        agent_offspring, team_offspring = ccea.generate_offspring(agent_pops, team_packs)
        ccea.evaluate_populations(agent_offspring, team_offspring)
        ccea.set_populations(agent_pops, agent_offspring, team_pop, team_offspring)
        return time.perf_counter() - start


def main() -> None:
    if sys.argv[2:] == ["--child"]:  # one measurement, in a process of its own
        _reset_without_tuples()
        _keep_constraints()
        print(f"GEN {generation_seconds(yaml.safe_load(Path(sys.argv[1]).read_text()))}")
        return
    seconds, attempts = [], 0
    while len(seconds) < 3 and attempts < 15:  # a process may crash (module docstring)
        attempts += 1
        done = subprocess.run([sys.executable, __file__, sys.argv[1], "--child"],
                              capture_output=True, text=True, timeout=600)  # fmt: skip
        seconds += [float(line.split()[1]) for line in done.stdout.splitlines()
                    if line.startswith("GEN ")]  # fmt: skip
    if not seconds:
        raise SystemExit(f"lab_speed: every one of {attempts} processes crashed")
    print(f"lab CCEA, one generation: median {statistics.median(seconds):.3f} s "
          f"({', '.join(f'{t:.3f}' for t in seconds)}; {attempts} processes, "
          f"{attempts - len(seconds)} crashed)")  # fmt: skip


if __name__ == "__main__":
    main()
