"""Where a CCEA rollout's time goes, part by part, in one process (issue 41).

    python benchmarks/rollout_parts.py [--config FILE.toml] [--episodes 150]

Builds the CCEA of ``--config`` (default: the paper's domain) with D, plays three
generations, then times, interleaved episode by episode so that every figure sees the same
machine: the reset of every team (the scenario's draws, spawns, the sensing of state 0)
and the compiled episode (:func:`physrover.learn.rollout.policy_episode`) under the world's
step plan, and again with parts of the plan switched off (no sensing, no classes' roles,
no scoring, ...: the episode then plays other trajectories, whose cost is the same work).
Prints the median ms of each, one thread.

Why in one process: on a shared host the same command's median differs by 10-40% from
one process to the next (seen 2026-12-06: 15.5 and 21.6 ms for one D generation), more
than most changes this measures; interleaving within a process cancels it. What it does
not cancel: each variant is its own compiled episode, and where its code lands moves it by
up to ~1 ms (the same "no roles" variant took 10.1 ms in one build and 11.1 in another that
differed only in code the variant never runs), so read a part's cost to about 1 ms.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from physrover.config import RunConfig
from physrover.core.threads import pin_threads
from physrover.learn.ccea import CCEA
from physrover.learn.rollout import policy_episode


def plan_variants(plan) -> dict:
    """The world's step plan and the same plan with each present part switched off."""
    variants = {"episode": plan, "no scoring": plan._replace(t_final=-1)}
    if plan.density is not None or plan.classes is not None:
        variants["no sensing"] = plan._replace(density=None, classes=None)
    roles = plan.motion.roles
    if roles is not None:
        variants["no roles"] = plan._replace(motion=plan.motion._replace(roles=None))
        ungated = roles._replace(n_gate=np.zeros_like(roles.n_gate),
                                 gated=np.zeros_like(roles.gated))  # fmt: skip
        variants["roles, no gates"] = plan._replace(motion=plan.motion._replace(roles=ungated))
    if plan.rules is not None:
        variants["no POI rules"] = plan._replace(rules=None)
    if plan.vanish is not None:
        variants["no vanishing"] = plan._replace(vanish=None)
    return variants


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", help="a run's TOML (default: the paper's domain)")
    parser.add_argument("--episodes", type=int, default=150)
    args = parser.parse_args()
    pin_threads(1)
    config = RunConfig.load(args.config) if args.config else RunConfig()
    ccea = CCEA(config.with_overrides({"method": "D"}))
    for _ in range(3):
        ccea.run_generation()
    world = ccea.env.world
    rngs = [np.random.default_rng(seed) for seed in range(world.n_teams)]  # fresh starts
    rovers = np.arange(world.n_rovers)
    teams = np.random.default_rng(0).integers(0, ccea.k, (world.n_teams, world.n_rovers))
    policy = ccea.layout.prepare(ccea.genomes[rovers[None], teams])
    records = (world.observations, world.actions, world.position_history, world.heading_history)
    times: dict[str, list[float]] = {"reset": []}
    variants = plan_variants(world.plan.step)
    for _ in range(args.episodes):
        for name, plan in variants.items():
            start = time.perf_counter()
            world.reset(rngs)
            reset = time.perf_counter()
            policy_episode(policy.genomes, policy.hidden, policy.tanh_hidden, policy.dims,
                           False, plan, *records, *world.state)  # fmt: skip
            times.setdefault(name, []).append(time.perf_counter() - reset)
            if name == "episode":
                times["reset"].append(reset - start)
    print(f"{world.n_teams} teams of {world.n_rovers}, median of {args.episodes}, ms:")
    for name, seconds in times.items():
        print(f"  {name:16s} {1000 * statistics.median(seconds):6.2f}")


if __name__ == "__main__":
    main()
