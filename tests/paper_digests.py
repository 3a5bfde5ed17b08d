"""Digests of what the paper's 2020 domain computes, to guard it while the domain grows
(issue 33's first slice: every later slice must leave these unchanged, bit for bit).

    python tests/paper_digests.py --write   # record tests/data/paper-digests.json

Each digest is sha256 over the bytes of a seeded computation's outputs:

- ``world/NAME``: a 4-team episode of 50 steps under seeded random commands through
  :class:`~physrover.envs.RoverVectorEnv` (the observations, rewards, positions, headings,
  G and D of every step), for the paper's idealised world, a 6-sector sensor of radius 5,
  the compiled physical world and the physical world with walls (pymunk);
- ``ccea/METHOD``: 5 generations of the CCEA at paper scale for D and the average of 10
  episodes, at n_req 1 so that teams capture from the first generations (each
  generation's eval and train G, then the whole checkpoint's arrays);
- ``config``: the default config's TOML.

The critics' sums are reassociated by the compiler (their last bits follow the CPU's
vector width), so the critic methods are left out. Everything else is compiled without
fast-math (no reassociation, no fused multiply-adds) and the policies' tanh is our own,
correctly rounded: the digests do not depend on the x86-64 CPU (the same on znver4, where
they were recorded, and znver3, listed under ``verified_on``). They do depend on numpy,
numba and pymunk (random streams, codegen, Chipmunk), whose versions are recorded;
``tests/test_paper_unchanged.py`` compares them on any x86-64 machine with those versions.
"""

from __future__ import annotations

import hashlib
import json
import sys
from pathlib import Path

import numpy as np

DIGESTS = Path(__file__).parent / "data" / "paper-digests.json"

_LIDAR = {"kind": "lidar", "empty": -1.0, "channels": "by-class"}
WORLDS = {
    "ideal": {},
    "sectors6-radius5": {"sensor": {"kind": "density", "sectors": 6, "radius": 5.0}},
    "physics": {"motion": "physics"},
    "physics-walls": {"motion": "physics", "walls": True},
    # the mixed-team study's task at n_req 1 (physrover/sweeps/mixed-team.toml), and an
    # ordered and a final POI: what issue 33 added, recorded from f2ead5f, where it still
    # stepped in Python, and compiled into the one step since
    "mixed-team": {
        "n_req": 1, "scenario": {"kind": "uniform", "half_size": 15.0, "min_separation": 8.0},
        "pois": [{"value": float(v), "visible_to": ["uav"], "disappear": "captured"}
                 for v in (1, 2, 3, 4)],
        "agents": [{"name": "rover", "count": 4, "moves_with": ["uav"],
                    "sensor": {**_LIDAR, "radius": 3.0}},
                   {"name": "uav", "count": 2, "captures": False, "influence_radius": 5.0,
                    "sensor": {**_LIDAR, "radius": 100.0}}],
    },
    "chain": {"n_req": 2, "poi_ring_radius": 4.0,
              "pois": [{"value": 1.0}, {"value": 2.0, "after": [0]}, {"value": 3.0},
                       {"value": 4.0, "score_at": "final"}]},
}  # fmt: skip


def _hash(arrays) -> str:
    digest = hashlib.sha256()
    for array in arrays:
        digest.update(np.ascontiguousarray(array).tobytes())
    return digest.hexdigest()


def world_digest(fields: dict, n_teams: int = 4, seed: int = 0) -> str:
    from physrover import DomainConfig, RoverVectorEnv

    config = DomainConfig().replace(**fields)
    env = RoverVectorEnv(n_teams, config=config)
    rng = np.random.default_rng(seed)
    obs, _ = env.reset(seed=seed)
    outputs = [obs]
    for _ in range(config.steps):
        commands = rng.uniform(-1.0, 1.0, (n_teams, config.n_rovers, 2))
        obs, reward, _, _, info = env.step(commands)
        outputs += [obs, reward, info["rover_positions"], info["rover_headings"], info["G"],
                    info["D"]]  # fmt: skip
    return _hash(outputs)


def ccea_digest(method: str, generations: int = 5, seed: int = 0) -> str:
    from physrover.config import RunConfig
    from physrover.learn.ccea import CCEA

    ccea = CCEA(RunConfig().with_overrides({"method": method, "seed": seed, "n_req": 1}))
    outputs = []
    for _ in range(generations):
        stats = ccea.run_generation()
        outputs.append(np.array([stats.eval_G, stats.train_G_mean]))
    arrays, _ = ccea.state()
    outputs += [arrays[name] for name in sorted(arrays)]
    return _hash(outputs)


def platform() -> dict:
    import numba
    import pymunk

    from physrover.experiment.provenance import describe

    segment = describe(0)
    return {"llvm_cpu": segment["llvm_cpu"], "cpu_features": segment["cpu_features"],
            "numpy": np.__version__, "numba": numba.__version__,
            "pymunk": pymunk.version}  # fmt: skip


def digests() -> dict:
    from physrover import DomainConfig

    found = {f"world/{name}": world_digest(fields) for name, fields in WORLDS.items()}
    found.update({f"ccea/{method}": ccea_digest(method) for method in ("D", "average")})
    found["config"] = hashlib.sha256(DomainConfig().to_toml().encode()).hexdigest()
    return found


if __name__ == "__main__":
    if sys.argv[1:] != ["--write"]:
        sys.exit(__doc__)
    record = {"platform": platform(), "verified_on": [platform()], "digests": digests()}
    DIGESTS.write_text(json.dumps(record, indent=1) + "\n")
    print(f"wrote {DIGESTS}")
