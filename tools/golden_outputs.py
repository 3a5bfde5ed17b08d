"""Golden outputs of the command line: digests of what a short run, a resume, a sweep,
``render``, ``curves`` and ``table`` write, to compare two installs (a refactor must leave
them unchanged). Runs the ``physrover`` on PATH in a scratch directory and prints one
``name digest`` line per output; diff the lines of two installs:

    /path/to/venv-a/bin/python tools/golden_outputs.py > a.txt
    /path/to/venv-b/bin/python tools/golden_outputs.py > b.txt
    diff a.txt b.txt

Wall-clock columns and provenance (times, hosts, versions) are left out of the digests;
everything else a run writes is in them. About 2 minutes on 2 cores.
"""

from __future__ import annotations

import csv
import hashlib
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

TIMING = {"wall_seconds", "seconds", "rollout_seconds", "critic_seconds"}


def physrover(*args: str, cwd: Path) -> None:
    exe = Path(sys.executable).parent / "physrover"
    subprocess.run([str(exe), *args], cwd=cwd, check=True, capture_output=True)


def csv_digest(path: Path) -> str:
    """sha256 of a CSV's rows without its timing columns."""
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    keep = [c for c in (rows[0] if rows else {}) if c not in TIMING and "seconds" not in c]
    text = "\n".join(",".join(row[c] for c in keep) for row in rows)
    return hashlib.sha256(f"{keep}\n{text}".encode()).hexdigest()[:16]


def checkpoint_digest(run: Path) -> str:
    """sha256 of every array of a run's checkpoint, by name (not its ``__meta__``, which
    holds wall-clock times), and of its champions."""
    digest = hashlib.sha256()
    for path in sorted(run.rglob("*.npz")):
        with np.load(path) as arrays:
            for name in sorted(set(arrays.files) - {"__meta__"}):
                digest.update(name.encode() + np.ascontiguousarray(arrays[name]).tobytes())
    for path in sorted(run.rglob("champions/*.npy")):
        digest.update(path.name.encode() + np.load(path).tobytes())
    return digest.hexdigest()[:16]


def video_digest(path: Path) -> str:
    """sha256 of a video's decoded frames (the container's metadata left out)."""
    import av

    digest = hashlib.sha256()
    with av.open(str(path)) as video:
        for frame in video.decode(video=0):
            digest.update(frame.to_ndarray(format="rgb24").tobytes())
    return digest.hexdigest()[:16]


def main() -> None:
    with tempfile.TemporaryDirectory() as scratch:
        root = Path(scratch)
        mixed = Path(__file__).parents[1] / "benchmarks" / "configs" / "mixed15.toml"
        runs = {
            "run-D": ["--method", "D", "--generations", "30", "--set", "n_rovers=6",
                      "--set", "n_req=2"],
            "run-max-critic": ["--method", "max-critic", "--generations", "20", "--set",
                               "n_rovers=6", "--set", "n_req=1"],
            "run-mixed": ["--config", str(mixed), "--method", "D", "--generations", "20",
                          "--set", "feedback=ID"],
            "run-physics": ["--method", "D", "--generations", "5", "--set", "n_rovers=4",
                            "--set", "motion=physics", "--set", "n_req=1"],
        }  # fmt: skip
        for name, args in runs.items():
            physrover("train", *args, "--seed", "2", "--out", name, "--quiet", cwd=root)
            print(name, "metrics", csv_digest(root / name / "metrics.csv"))
            print(name, "checkpoint", checkpoint_digest(root / name))
        # resume: 10 generations, then on to 30: the same as 30 straight
        physrover("train", *runs["run-D"][:2], "--generations", "10", *runs["run-D"][4:],
                  "--seed", "2", "--out", "resumed", "--quiet", cwd=root)  # fmt: skip
        physrover("train", "--resume", "resumed", "--generations", "30", "--quiet", cwd=root)
        print("resume metrics", csv_digest(root / "resumed" / "metrics.csv"))
        print("resume checkpoint", checkpoint_digest(root / "resumed"))
        physrover("render", "run-mixed", "--out", "mixed.mp4", cwd=root)
        print("render mixed", video_digest(root / "mixed.mp4"))
        physrover("render", "run-D", "--out", "paper.mp4", cwd=root)
        print("render paper", video_digest(root / "paper.mp4"))
        physrover("curves", "run-D", "run-max-critic", "--out", "curves.png", cwd=root)
        print("curves", csv_digest(root / "curves.csv"))
        table = subprocess.run([str(Path(sys.executable).parent / "physrover"), "table",
                                "run-D", "run-max-critic"], cwd=root, check=True,
                               capture_output=True, text=True).stdout  # fmt: skip
        print("table", hashlib.sha256(table.encode()).hexdigest()[:16])
        physrover("sweep", "smoke", "--root", "sweeps", "--set", "generations=20",
                  "--workers", "2", cwd=root)  # fmt: skip
        for run in sorted((root / "sweeps").rglob("metrics.csv")):
            print("sweep", run.parent.name, csv_digest(run))


if __name__ == "__main__":
    main()
