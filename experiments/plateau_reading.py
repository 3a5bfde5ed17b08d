"""What the n_req 5-6 plateau is made of: which POIs a trained team captures, and how its
rovers are spread over the POIs.

    python experiments/plateau_reading.py RUN_DIR [RUN_DIR ...] [--episodes 100] [--name NAME]

Plays each run's champion team on ``--episodes`` fresh episodes (the starts of ``physrover
evaluate``) and records, per run: the mean G; how often each POI is captured (in the order
of ``poi_values``); the most frequent set of captured POIs and its share of the episodes;
per POI, the most rovers within d_cap of it at any one step (the size of the group that
goes there; mean over episodes); the rovers never within d_cap of any POI; the surplus
rovers (beyond n_req, summed over the captured POIs); and the share of episodes in which
a POI was left uncaptured with n_req - 1 rovers at it at once ("one short"); and how far
the rovers end from the POIs (the median over episodes and rovers of a rover's distance to
its nearest POI at the last step, world units: a policy that never leaves the start, at
the centre of the paper's ring of radius 15, ends about 14 away). Writes
``results/NAME.{csv,md}`` (NAME: ``plateau_reading`` unless given).
"""

from __future__ import annotations

import argparse
import collections
from pathlib import Path

import numpy as np

from physrover.analysis.tables import write_csv
from physrover.experiment.evaluate import play_champion
from physrover.experiment.store import load_run_config

OUT = Path(__file__).parent / "results"


def reading(run_dir: Path, episodes: int) -> dict:
    """One run's row (module docstring)."""
    config = load_run_config(run_dir)
    _, env = play_champion(run_dir, episodes)
    world = env.world
    captured = world.state.capture_step >= 0  # (E, K)
    near = world.state.in_range  # (T + 1, E, R, K): rover r within d_cap of POI k at step t
    group = near.sum(axis=2).max(axis=0)  # (E, K) most rovers at POI k at any one step
    idle = (~near.any(axis=(0, 3))).sum(axis=1)  # (E,) rovers never near any POI
    rovers, pois = world.state.rover_positions, world.state.poi_positions  # (E, R | K, 2)
    to_poi = np.linalg.norm(rovers[:, :, None] - pois[:, None], axis=-1)  # (E, R, K) at the end
    n_req = config.domain.n_req
    # a gradient-based trainer (MAPPO...) learns from its own reward, not [learn] feedback
    feedback = config.trainer.reward if config.trainer is not None else config.learn.feedback
    if not np.array_equal(captured, group >= n_req):  # the paper's rule: n_req at one step
        raise SystemExit(f"{run_dir}: captures are not n_req rovers at once (POI rules?)")
    values = config.domain.poi_values
    sets = collections.Counter(
        "{" + ", ".join(f"{values[k]:g}" for k in np.flatnonzero(row)) + "}" for row in captured
    )
    common, count = sets.most_common(1)[0]
    return {
        "run": run_dir.name,
        "method": config.learn.method,
        "feedback": feedback,
        "n_req": config.domain.n_req,
        "seed": config.learn.seed,
        "G": float(world.G.mean()),
        **{f"captured_{v:g}": float(captured[:, k].mean()) for k, v in enumerate(values)},
        "most_common_set": common,
        "its_share": count / episodes,
        **{f"group_at_{v:g}": float(group[:, k].mean()) for k, v in enumerate(values)},
        "idle_rovers": float(idle.mean()),
        "surplus_rovers": float((np.maximum(group - n_req, 0) * captured).sum(axis=1).mean()),
        "one_short": float(((group == n_req - 1) & ~captured).any(axis=1).mean()),
        "end_to_poi": float(np.median(to_poi.min(axis=-1))),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", type=Path)
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--name", default="plateau_reading")
    args = parser.parse_args()
    rows = [reading(run, args.episodes) for run in args.runs]
    OUT.mkdir(exist_ok=True)
    write_csv(rows, list(rows[0]), OUT / f"{args.name}.csv")
    lines = [list(rows[0]), ["---"] * len(rows[0])]
    lines += [[f"{v:.2f}" if isinstance(v, float) else str(v) for v in r.values()] for r in rows]
    table = "".join("| " + " | ".join(cells) + " |\n" for cells in lines)
    (OUT / f"{args.name}.md").write_text(table)
    print(table, end="")


if __name__ == "__main__":
    main()
