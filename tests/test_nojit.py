"""NUMBA_DISABLE_JIT=1 runs the compiled kernels as plain Python (for debugging): the same
episode and the same CCEA generation give the same results as the compiled run."""

import json
import os
import subprocess
import sys

import numpy as np

SCRIPT = """
import json, numpy as np
from physrover.config import DomainConfig, RunConfig
from physrover.domain.world import RoverWorld
from physrover.learn.ccea import CCEA

cfg = DomainConfig(n_rovers=4, n_req=2, steps=8).replace(poi_ring_radius=5.0, spawn_radius=3.0)
world = RoverWorld(cfg, 3)
world.reset([np.random.default_rng(e) for e in range(3)])
for a in np.random.default_rng(5).uniform(-1, 1, (8, 3, 4, 2)):
    obs = world.step(a)
run = RunConfig().with_overrides({"n_rovers": 3, "n_req": 1, "population": 4, "steps": 6,
                                  "eval_episodes": 2, "method": "max-critic",
                                  "pair_batches": 2, "pair_batch": 8})
ccea = CCEA(run)
stats = [ccea.run_generation() for _ in range(2)]
print(json.dumps({"G": world.G.tolist(), "D": world.D.tolist(), "obs": obs.tolist(),
                  "eval_G": [s.eval_G for s in stats], "loss": stats[-1].critic_loss,
                  "genomes": float(np.abs(ccea.genomes).sum())}))
"""


def _run(disable_jit: bool) -> dict:
    env = {**os.environ, "NUMBA_DISABLE_JIT": "1" if disable_jit else "0"}
    out = subprocess.run([sys.executable, "-c", SCRIPT], env=env, capture_output=True,
                         text=True, check=True)  # fmt: skip
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_kernels_run_as_plain_python_with_the_same_results():
    python, compiled = _run(True), _run(False)
    assert python["G"] == compiled["G"] and python["D"] == compiled["D"]
    assert max(compiled["G"]) > 0
    np.testing.assert_allclose(python["obs"], compiled["obs"], rtol=1e-6)
    assert python["eval_G"] == compiled["eval_G"]
    np.testing.assert_allclose(python["loss"], compiled["loss"], rtol=1e-4)
    np.testing.assert_allclose(python["genomes"], compiled["genomes"], rtol=1e-5)
