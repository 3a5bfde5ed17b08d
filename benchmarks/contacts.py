"""How hard are the physical model's contacts? Pass-throughs and overlaps at step ends.

    python benchmarks/contacts.py [--set FIELD=VALUE ...]

Three cases, each under the given config (default: physics with collisions, the defaults):

- head-on: two rovers driving at each other at full command, started 6.0 to 7.0 apart (41
  distances, so the impact falls at every phase of a step): how many pass through each
  other, and the worst overlap at a step end;
- crowd: 15 rovers from the spawn disc, all driving forward at full command with random
  lateral components, 50 steps, seeds 0-19: worst and median overlap at step ends (pairs in
  contact);
- pushing: two rovers started touching, pushing into each other for 30 steps: the overlap
  at the end (steady contact);
- column: ten rovers in a column driven into a box, and into the walls, for 30 steps: the
  worst overlap of two rovers at a step end (the wall stops the front rover; the pass must
  stop the rest behind it);
- converge: a team driven at full command towards its centre for 50 steps, a jam that
  tightens every step, at 15 rovers (the paper's spawn) and at 1000 (spread as ``physrover
  bench world --rovers`` spreads them, where the grid finds the contact pairs): worst and
  median overlap of the pairs in contact (issue 32: contacts at 1000 rovers as at 15).

Overlap is ``max(0, r_i + r_j - distance) / (r_i + r_j)``: a fraction of a diameter.
The time per step is ``physrover bench world --motion physics``'s job.
"""

from __future__ import annotations

import argparse

import numpy as np

from physrover.config import DomainConfig, parse_override
from physrover.domain.motion.separation import pair_overlaps as overlaps
from physrover.envs.gymnasium_env import RoverVectorEnv


def head_on(config: DomainConfig) -> dict:
    distances = np.linspace(6.0, 7.0, 41)
    cfg = config.replace(n_rovers=2, n_req=1, steps=12)
    env = RoverVectorEnv(len(distances), config=cfg)
    start = np.zeros((len(distances), 2, 2))
    start[:, 0, 0], start[:, 1, 0] = -distances / 2, distances / 2
    env.reset(seed=0, options={"rover_positions": start, "rover_headings": [0.0, np.pi]})
    worst, crossed = 0.0, np.zeros(len(distances), dtype=bool)
    for _ in range(cfg.steps):
        _, _, _, _, info = env.step(np.tile([1.0, 0.0], (len(distances), 2, 1)))
        pos = info["rover_positions"]
        crossed |= pos[:, 0, 0] > pos[:, 1, 0]
        worst = max(worst, overlaps(pos, cfg.physics.rover_radius).max())
    return {"pass_throughs": int(crossed.sum()), "cases": len(distances), "worst": worst}


def crowd(config: DomainConfig, seeds: int = 20) -> dict:
    cfg = config.replace(n_rovers=15, steps=50)
    env = RoverVectorEnv(seeds, config=cfg)
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    seen = []
    for _ in range(cfg.steps):
        action = np.stack([np.ones((seeds, 15)), rng.uniform(-1, 1, (seeds, 15))], axis=-1)
        _, _, _, _, info = env.step(action)
        seen.append(overlaps(info["rover_positions"], cfg.physics.rover_radius))
    seen = np.concatenate(seen, axis=None)
    touching = seen[seen > 0]
    median = float(np.median(touching)) if touching.size else 0.0
    return {"worst": float(seen.max()), "median_in_contact": median}


def pushing(config: DomainConfig) -> dict:
    cfg = config.replace(n_rovers=2, n_req=1, steps=30)
    env = RoverVectorEnv(1, config=cfg)
    r = cfg.physics.rover_radius
    env.reset(seed=0, options={"rover_positions": [(-r, 0.0), (r, 0.0)],
                               "rover_headings": [0.0, np.pi]})  # fmt: skip
    for _ in range(cfg.steps):
        _, _, _, _, info = env.step(np.tile([1.0, 0.0], (1, 2, 1)))
    return {"steady": float(overlaps(info["rover_positions"], r).max())}


def column(config: DomainConfig, into: str) -> dict:
    """Ten rovers in a column, driven at full command for 30 steps into a box (``into =
    "box"``, its face 2 units ahead of the front rover) or the walls (``"wall"``, half side
    8): the worst overlap of any two rovers at a step end, over 3 teams."""
    n, start_x = 10, np.linspace(-3.0, 3.0, 10) - 1.0
    fields = {"scenario": "explicit", "poi_positions": [[0.0, 2.0]]}
    if into == "box":
        fields["obstacle_boxes"] = [[8.5, 0.0, 0.5, 3.0, 0.0]]
    else:
        fields.update(walls=True, wall_half_size=8.0)
    cfg = config.replace(n_rovers=n, n_req=1, poi_values=(1.0,), steps=30, **fields)
    env = RoverVectorEnv(3, config=cfg)
    start = np.stack([start_x, np.linspace(-0.3, 0.3, n)], axis=-1)
    env.reset(seed=0, options={"rover_positions": start, "rover_headings": np.zeros(n)})
    worst = 0.0
    for _ in range(cfg.steps):
        _, _, _, _, info = env.step(np.tile([1.0, 0.0], (3, n, 1)))
        worst = max(worst, overlaps(info["rover_positions"], cfg.physics.rover_radius).max())
    return {"worst": float(worst)}


def converge(config: DomainConfig, n_rovers: int, teams: int = 2) -> dict:
    from physrover.experiment.bench import scaling_config

    cfg = scaling_config(config, n_rovers).replace(steps=50)
    env = RoverVectorEnv(teams, config=cfg)
    _, info = env.reset(seed=0)
    positions, headings = info["rover_positions"], info["rover_headings"]
    seen = []
    for _ in range(cfg.steps):
        toward = -positions / np.maximum(np.linalg.norm(positions, axis=-1, keepdims=True), 1e-9)
        c, s = np.cos(headings), np.sin(headings)  # the command is in the rover's frame
        command = np.stack([c * toward[..., 0] + s * toward[..., 1],
                            -s * toward[..., 0] + c * toward[..., 1]], axis=-1)  # fmt: skip
        _, _, _, _, info = env.step(command)
        positions, headings = info["rover_positions"], info["rover_headings"]
        seen.append(overlaps(positions, cfg.physics.rover_radius))
    seen = np.concatenate(seen, axis=None)
    touching = seen[seen > 0]
    return {"worst": float(seen.max()), "median_in_contact": float(np.median(touching)),
            "contacts": int(touching.size)}  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE")
    args = parser.parse_args()
    fields = dict(parse_override(text) for text in args.set)
    config = DomainConfig(motion="physics").replace(collisions=True, **fields)
    h, c, p = head_on(config), crowd(config), pushing(config)
    box, wall = column(config, "box"), column(config, "wall")
    print(
        f"head-on: {h['pass_throughs']}/{h['cases']} pass through, worst overlap "
        f"{100 * h['worst']:.0f}%; crowd: worst {100 * c['worst']:.0f}%, median in contact "
        f"{100 * c['median_in_contact']:.1f}%; pushing: {100 * p['steady']:.1f}%; column "
        f"into a box: worst {100 * box['worst']:.1f}%, into a wall: {100 * wall['worst']:.1f}%"
    )
    for n_rovers in (15, 1000):
        jam = converge(config, n_rovers)
        print(
            f"converge, {n_rovers} rovers: worst {100 * jam['worst']:.1f}%, median in contact "
            f"{100 * jam['median_in_contact']:.2f}% ({jam['contacts']} pair-steps in contact)"
        )


if __name__ == "__main__":
    main()
