"""Rendering and MP4 writing."""

import cv2
import numpy as np
import pytest

from physrover import RoverEnv
from physrover.render import RenderConfig, Transform, VideoError, VideoWriter, rover_rgb


def _record(path, render, steps=6):
    env = RoverEnv(n_rovers=3, n_req=2, steps=steps, render_mode="rgb_array",
                   render_config=render)  # fmt: skip
    start = {"rover_positions": [(0.0, 0.0), (6.0, 6.0), (-6.0, -6.0)],
             "rover_headings": [0.0, 0.0, 0.0]}  # fmt: skip
    env.reset(seed=0, options=start)
    with VideoWriter(path, render.width, render.height, render.fps) as video:
        video.write(env.render())
        for _ in range(steps):
            env.step(np.array([[0.0, 0.0], [0.0, 0.0], [0.5, 0.0]]))
            video.write(env.render())
    return env


def test_video_round_trip(tmp_path):
    render = RenderConfig(width=320, height=240, fps=5, trail=0)
    path = tmp_path / "ep.mp4"
    env = _record(path, render)
    cap = cv2.VideoCapture(str(path))
    assert int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) == 7  # steps + 1
    assert (cap.get(cv2.CAP_PROP_FRAME_WIDTH), cap.get(cv2.CAP_PROP_FRAME_HEIGHT)) == (320, 240)
    assert cap.get(cv2.CAP_PROP_FPS) == pytest.approx(5.0)
    frames = []
    while True:
        ok, frame = cap.read()
        if not ok:
            break
        frames.append(frame[..., ::-1])  # BGR -> RGB
    last = frames[-1].astype(int)
    tf = Transform.fit(env.config, render)
    for i, pos in enumerate(env.unwrapped.world.rover_positions[0]):
        col, row = np.round(tf(pos)).astype(int)
        # Rover 0 stands still at the origin, rover 1 at (6, 6) (mp4v is lossy: +-24 levels).
        if i < 2:
            assert np.abs(last[row, col] - rover_rgb(i)).max() <= 24, i
    # A far corner away from POIs, rovers and the HUD is the background.
    assert np.abs(last[200, 300] - (246, 246, 246)).max() <= 8


def test_wrong_frame_size_raises(tmp_path):
    with pytest.raises(VideoError, match=r"shape \(240, 320, 3\)"):
        with VideoWriter(tmp_path / "x.mp4", 320, 240, 10) as video:
            video.write(np.zeros((240, 321, 3), dtype=np.uint8))
    with pytest.raises(VideoError, match="uint8"):
        with VideoWriter(tmp_path / "y.mp4", 320, 240, 10) as video:
            video.write(np.zeros((240, 320, 3), dtype=np.float32))


def test_unwritable_path_raises(tmp_path):
    with pytest.raises(VideoError, match="no directory"):
        VideoWriter(tmp_path / "missing" / "x.mp4", 64, 64, 10)
    (tmp_path / "dir.mp4").mkdir()
    with pytest.raises(VideoError, match="cannot open"):
        VideoWriter(tmp_path / "dir.mp4", 64, 64, 10)


def test_a_short_file_is_detected(tmp_path):
    video = VideoWriter(tmp_path / "z.mp4", 64, 64, 10)
    video.write(np.zeros((64, 64, 3), dtype=np.uint8))
    video.frames += 1  # pretend a frame went missing
    with pytest.raises(VideoError, match="holds 1 frames, 2 were written"):
        video.close()


def test_check_env_with_rendering():
    import warnings

    import gymnasium
    from gymnasium.utils.env_checker import check_env

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        check_env(
            gymnasium.make("physrover/Rover-v0", render_mode="rgb_array", n_rovers=4).unwrapped
        )


def test_poi_turns_green_when_captured():
    render = RenderConfig(width=200, height=200)
    env = RoverEnv(n_rovers=2, n_req=2, render_mode="rgb_array", render_config=render)
    # Both rovers sit near POI 1 at (15, 0), away from its centre: captured at reset.
    env.reset(seed=0, options={"rover_positions": [(13.0, 2.0), (13.0, -2.0)]})
    frame = env.render().astype(int)
    assert frame.shape == (200, 200, 3)
    tf = Transform.fit(env.config, render)
    col, row = np.round(tf([15.0, 0.0])).astype(int)  # POI 1 (captured)
    assert np.abs(frame[row, col] - (60, 170, 60)).max() <= 2
    col, row = np.round(tf([0.0, 15.0])).astype(int)  # POI 2 (not captured)
    assert np.abs(frame[row, col] - (150, 150, 150)).max() <= 2
