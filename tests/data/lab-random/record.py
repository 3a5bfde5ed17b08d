"""Record the lab's own rewards on random trajectories into cases.json (issue 43).

Random lab configs (1-3 rovers, 0-2 UAVs, rover and hidden POIs valued by distance, final or
sequential, captured by sight or within a capture radius, couplings 1-2 (at most the
rovers); every reward type:
Global, Difference, IndirectDifference on the trajectory or per step with every credit,
manual removal, add_G) and random joint paths of 1-12 steps, some of them leaving the map.
The lab's code (AADILab/influence-shaping, its C++ core through cppyy) computes each
agent's reward and G: ``env.reset()`` with the agents at the paths' first points, then
``set_position`` of every agent at every step, so each agent's path holds the T + 1 points
physrover scores (the lab's unit tests' way: its training paths hold three points a step,
a documented difference), then ``env.rewards()`` and ``Global().compute``.
``tests/test_lab_random.py`` replays every case on physrover.

Run in the lab's environment (see ``benchmarks/lab_speed.py`` for the venv), from the repo
root::

    PYTHONPATH=LAB/src venv-lab/bin/python tests/data/lab-random/record.py \
        --lab-commit COMMIT [--cases 300]

cppyy 3.5 crashes some processes: cases run a batch per child process, and a crashed batch
is run again (the lab's code is deterministic given the case). Writes cases.json beside
this file with the lab's commit (``--lab-commit``, of the checkout on the PYTHONPATH).
"""

import argparse
import copy
import json
import os
import random
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).parent
CREDITS = ["AllOrNothing", "Local", "System", "Difference"]


def random_case(rng: random.Random) -> dict:
    """One lab config (its ``env`` section), paths and POI positions."""
    size = [rng.choice([12.0, 15.0, 20.0])] * 2
    n_rovers, n_uavs = rng.randint(1, 3), rng.randint(0, 2)
    n_agents = n_rovers + n_uavs

    def agent() -> dict:
        a = {"observation_radius": rng.choice([3.0, 5.0, 1000.0]), "resolution": 90,
             "position": {"spawn_rule": "fixed", "fixed": [0.0, 0.0]},
             "reward_type": rng.choice(["Global", "Difference", "IndirectDifference",
                                        "IndirectDifference"])}  # fmt: skip
        if rng.random() < 0.8:
            a["IndirectDifference"] = {
                "type": "removal", "assignment": rng.choice(["automatic"] * 3 + ["manual"]),
                "manual": rng.sample(range(n_agents), rng.randint(0, min(2, n_agents))),
                "automatic": {"timescale": rng.choice(["trajectory", "timestep"]),
                              "credit": rng.choice(CREDITS)},
                "add_G": rng.random() < 0.3}  # fmt: skip
        return a

    def poi() -> dict:
        # a coupling no more than the rovers (physrover refuses one it could never meet)
        p = {"value": rng.choice([1.0, 2.0, 0.5]), "coupling": rng.choice([1, 1, min(2, n_rovers)]),
             "observation_radius": rng.choice([3.0, 5.0, 1000.0]),
             "position": {"spawn_rule": "fixed", "fixed": [0.0, 0.0]}}  # fmt: skip
        if rng.random() < 0.5:
            p["constraint"] = rng.choice(["final", "sequential"])
        if rng.random() < 0.3:
            p["capture_radius"] = rng.choice([2.0, 4.0])
        return p

    pois = {"rover_pois": [poi() for _ in range(rng.randint(0, 2))],
            "hidden_pois": [poi() for _ in range(rng.randint(1, 2))]}  # fmt: skip
    for p in pois["rover_pois"] + pois["hidden_pois"]:
        p["position"]["fixed"] = [rng.uniform(0, size[0]), rng.uniform(0, size[1])]
    agents = {"rovers": [agent() for _ in range(n_rovers)],
              "uavs": [agent() for _ in range(n_uavs)]}  # fmt: skip
    steps = rng.randint(1, 12)
    paths = []
    for a in agents["rovers"] + agents["uavs"]:
        path = [[rng.uniform(0, size[0]), rng.uniform(0, size[1])]]
        for _ in range(steps):
            x, y = path[-1][0] + rng.uniform(-2, 2), path[-1][1] + rng.uniform(-2, 2)
            if rng.random() > 0.1:  # mostly inside the map, sometimes outside
                x, y = min(max(x, 0.0), size[0]), min(max(y, 0.0), size[1])
            path.append([x, y])
        a["position"]["fixed"] = path[0]
        paths.append(path)
    return {"config": {"env": {"agents": agents, "pois": pois, "map_size": size}}, "paths": paths}


def lab_values(case: dict) -> dict:
    """The lab's G and rewards of a case (in the lab's environment)."""
    from influence.custom_env import createEnv
    from influence.librovers import rovers

    env = createEnv(copy.deepcopy(case["config"]))
    env.reset()
    for t in range(1, len(case["paths"][0])):
        for i, path in enumerate(case["paths"]):
            env.rovers()[i].set_position(float(path[t][0]), float(path[t][1]))
    rewards = [float(r) for r in env.rewards()]
    G = float(rovers.rewards.Global().compute(rovers.AgentPack(0, env.rovers(), env.pois())))
    return {"G": G, "rewards": rewards}


def child(cases_path: str, out_path: str) -> None:
    cases = json.loads(Path(cases_path).read_text())
    Path(out_path).write_text(json.dumps([lab_values(case) for case in cases]))
    os._exit(0)  # cppyy may crash while tearing the envs down


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--cases", type=int, default=300)
    parser.add_argument("--seed", type=int, default=43)
    parser.add_argument("--batch", type=int, default=10)
    parser.add_argument("--lab-commit", required=True, help="the lab code's commit (recorded)")
    parser.add_argument("--child", nargs=2, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        child(*args.child)
    rng = random.Random(args.seed)
    cases = [random_case(rng) for _ in range(args.cases)]
    for start in range(0, len(cases), args.batch):
        batch = cases[start : start + args.batch]
        with tempfile.TemporaryDirectory() as tmp:
            inp, out = Path(tmp, "in.json"), Path(tmp, "out.json")
            inp.write_text(json.dumps(batch))
            for _ in range(5):
                subprocess.run([sys.executable, __file__, "--lab-commit", args.lab_commit,
                                "--child", str(inp), str(out)],
                               capture_output=True)  # fmt: skip
                if out.exists():
                    break
            else:
                raise SystemExit(f"cases {start}..: the lab's process crashed 5 times")
            for case, values in zip(batch, json.loads(out.read_text()), strict=True):
                case.update(values)
        print(f"{start + len(batch)}/{len(cases)}", file=sys.stderr)
    doc = {"lab_repo": "AADILab/influence-shaping", "lab_commit": args.lab_commit,
           "seed": args.seed, "cases": cases}  # fmt: skip
    (HERE / "cases.json").write_text(json.dumps(doc, indent=None) + "\n")


if __name__ == "__main__":
    main()
