"""Play a run's champion team in the single env and record the episodes to MP4.

``record_run`` is what ``physrover render`` calls: it loads the run's config and the
champion genomes saved at a checkpoint, plays ``episodes`` episodes (seeds ``seed``,
``seed + 1``, ...) and writes one frame per step (``steps + 1`` per episode). With
``side_by_side`` the same team and start state run under the idealised and the physical
model, the two frames next to each other.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from physrover.config import DomainConfig
from physrover.envs import RoverEnv
from physrover.learn.policies import PolicyLayout
from physrover.render import RenderConfig, VideoWriter, label
from physrover.runs import CHAMPIONS, RunError, load_run_config


def champion_checkpoints(run_dir: Path) -> dict[int, Path]:
    """{generation: path} of the champion snapshots of a run."""
    found = {}
    for path in (run_dir / CHAMPIONS).glob("gen_*.npy"):
        match = re.fullmatch(r"gen_(\d+)\.npy", path.name)
        if match:
            found[int(match.group(1))] = path
    return found


def load_champions(run_dir: Path, checkpoint: int | None = None) -> tuple[int, np.ndarray]:
    """(generation, (R, P) genomes) of the champion team at ``checkpoint`` (default: last)."""
    found = champion_checkpoints(run_dir)
    if not found:
        raise RunError(f"{run_dir} has no champion checkpoints yet")
    if checkpoint is None:
        checkpoint = max(found)
    if checkpoint not in found:
        raise RunError(f"no checkpoint {checkpoint} in {run_dir}; have {sorted(found)}")
    return checkpoint, np.load(found[checkpoint])


def play(env: RoverEnv, layout: PolicyLayout, genomes: np.ndarray, seed: int):
    """Yield the frames of one episode (reset, then every step); the last G is env.world.G."""
    obs, _ = env.reset(seed=seed)
    yield env.render()
    truncated = False
    while not truncated:
        action = layout.act(genomes[None], obs[None])[0]
        obs, _, _, truncated, _ = env.step(action)
        yield env.render()


def record_run(
    run_dir: str | Path,
    out: str | Path,
    *,
    checkpoint: int | None = None,
    episodes: int = 3,
    seed: int = 0,
    side_by_side: bool = False,
    render: RenderConfig | None = None,
) -> tuple[Path, list[float]]:
    """Write the video; returns its path and the G of each episode (per model if paired)."""
    run_dir, out = Path(run_dir), Path(out)
    config = load_run_config(run_dir)
    generation, genomes = load_champions(run_dir, checkpoint)
    layout = PolicyLayout(config.learn.hidden)
    render = render or RenderConfig()
    domains: list[DomainConfig] = [config.domain]
    if side_by_side:
        domains = [config.domain.replace(motion="ideal"), config.domain.replace(motion="physics")]
    envs = [RoverEnv(config=d, render_mode="rgb_array", render_config=render) for d in domains]
    width = render.width * len(envs)
    scores = []
    with VideoWriter(out, width, render.height, render.fps) as video:
        for episode in range(episodes):
            streams = [play(env, layout, genomes, seed + episode) for env in envs]
            for frames in zip(*streams, strict=True):
                tagged = [
                    label(f, f"{env.config.motion}  gen {generation}  episode {episode + 1}")
                    for f, env in zip(frames, envs, strict=True)
                ]
                video.write(np.concatenate(tagged, axis=1))
            scores.extend(float(env.world.G[0]) for env in envs)
    return out, scores
