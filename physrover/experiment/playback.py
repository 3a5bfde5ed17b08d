"""Play a run's champion team in the single env and record the episodes to H.264 MP4.

``record_run`` is what ``physrover render`` calls: it loads the run's config and the
champion genomes saved at a checkpoint, plays ``episodes`` episodes (seeds ``seed``,
``seed + 1``, ...) and writes one frame per step (``steps + 1`` per episode). With
``side_by_side`` the same team and start state run under the idealised and the physical
model, the two frames next to each other with a dark bar of :data:`DIVIDER_PX` pixels
between them.

Each episode is played to its end first (:func:`play` keeps the state of every step), then
drawn in one view (:meth:`~physrover.viz.render.Transform.fit_states`) that holds the POIs and
every position of every rover of the episode, common to both panels so they compare.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from physrover.config import ConfigError, DomainConfig
from physrover.envs.gymnasium_env import RoverEnv
from physrover.experiment.store import load_champions, load_run_config
from physrover.learn.classes import team_layout
from physrover.viz.render import (
    FrameState,
    RenderConfig,
    VideoWriter,
    draw_frame,
    label,
    world_state,
)

DIVIDER_PX = 4
"""Width of the bar between side-by-side panels, pixels (even, so the video width stays even)."""
DIVIDER_RGB = (40, 40, 40)
"""Colour of that bar (dark grey, the colour of the text)."""


def play(env: RoverEnv, layout, genomes: np.ndarray, seed: int) -> list[FrameState]:
    """Play one episode; the states of its ``steps + 1`` frames (reset, then every step).

    The last G is also ``env.world.G``."""
    obs, _ = env.reset(seed=seed)
    states = [world_state(env.world, 0)]
    truncated = False
    while not truncated:
        action = layout.act(genomes[None], obs[None])[0]
        obs, _, _, truncated, _ = env.step(action)
        states.append(world_state(env.world, 0))
    return states


def join_panels(frames: list[np.ndarray]) -> np.ndarray:
    """(H, n W + (n - 1) DIVIDER_PX, 3) RGB: the (H, W, 3) frames left to right, separated
    by dark bars."""
    bar = np.empty((frames[0].shape[0], DIVIDER_PX, 3), dtype=np.uint8)
    bar[:] = DIVIDER_RGB
    parts = [bar if j % 2 else frames[j // 2] for j in range(2 * len(frames) - 1)]
    return np.concatenate(parts, axis=1)


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
    if episodes < 1:
        raise ConfigError("--episodes", f"must be >= 1, got {episodes}")
    config = load_run_config(run_dir)
    generation, genomes = load_champions(run_dir, checkpoint)
    render = render or RenderConfig()
    domains: list[DomainConfig] = [config.domain]
    if side_by_side:
        domains = [config.domain.replace(motion="ideal"), config.domain.replace(motion="physics")]
    envs = [RoverEnv(config=d) for d in domains]
    layout = team_layout(config.learn, config.domain)
    width = render.width * len(envs) + DIVIDER_PX * (len(envs) - 1)
    scores = []
    with VideoWriter(out, width, render.height, render.fps) as video:
        for episode in range(episodes):
            played = [play(env, layout, genomes, seed + episode) for env in envs]
            # Each panel frames its POIs and its team's trajectory so far (draw_frame's view):
            # the start is not lost in a view of the whole episode, no rover is ever cut.
            for states in zip(*played, strict=True):
                tagged = [
                    label(
                        draw_frame(state, env.config, render),
                        f"{env.config.motion}  gen {generation}  episode {episode + 1}",
                    )
                    for state, env in zip(states, envs, strict=True)
                ]
                video.write(join_panels(tagged))
            scores.extend(float(env.world.G[0]) for env in envs)
    return out, scores
