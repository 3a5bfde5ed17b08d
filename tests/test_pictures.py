"""Rendering, H.264 MP4 writing and side-by-side playback."""

import colorsys
import math
from pathlib import Path

import av
import numpy as np
import pytest

from physrover import RoverEnv
from physrover.config import ConfigError, DomainConfig, LearnConfig, RunConfig
from physrover.experiment.playback import DIVIDER_PX, record_run
from physrover.learn.policies import PolicyLayout
from physrover.viz.classes import ring_pixels
from physrover.viz.labels import poi_status
from physrover.viz.render import (
    BACKGROUND,
    FOOTER_PX,
    HUD_PX,
    PALETTE_RGB,
    POI_CAPTURED,
    POI_FREE,
    ROVER_PX,
    TEXT,
    RenderConfig,
    Transform,
    VideoError,
    VideoWriter,
    rover_rgb,
    world_state,
)

TEXT_RGB = np.array(TEXT[::-1])


def _view(env, render):
    """The transform ``env.render()`` draws its current frame with."""
    return Transform.fit_states([world_state(env.unwrapped.world, 0)], env.config, render)


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


def _read(path):
    """(stream facts, RGB frames) of a video, decoded with PyAV."""
    with av.open(str(path)) as container:
        stream = container.streams.video[0]
        facts = {
            "codec": stream.codec_context.name,
            "pix_fmt": stream.codec_context.pix_fmt,
            "size": (stream.width, stream.height),
            "fps": float(stream.average_rate),
        }
        frames = [f.to_ndarray(format="rgb24") for f in container.decode(stream)]
    return facts, frames


def test_video_is_h264_and_round_trips(tmp_path):
    render = RenderConfig(width=320, height=240, fps=5, trail=0)
    path = tmp_path / "ep.mp4"
    env = _record(path, render)
    facts, frames = _read(path)
    assert facts == {"codec": "h264", "pix_fmt": "yuv420p", "size": (320, 240), "fps": 5.0}
    assert len(frames) == 7  # steps + 1
    last = frames[-1].astype(int)
    tf = _view(env, render)
    for i, pos in enumerate(env.unwrapped.world.rover_positions[0]):
        col, row = np.round(tf(pos)).astype(int)
        # Rover 0 stands still at the origin, rover 1 at (6, 6) (H.264 is lossy: +-24 levels).
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


def test_odd_sizes_are_rejected(tmp_path):
    with pytest.raises(VideoError, match="even width and height, got 63x64"):
        VideoWriter(tmp_path / "odd.mp4", 63, 64, 10)
    assert not (tmp_path / "odd.mp4").exists()
    with pytest.raises(ConfigError, match="height: must be even"):
        RenderConfig(height=321)


def test_unwritable_path_raises(tmp_path):
    with pytest.raises(VideoError, match="no directory"):
        VideoWriter(tmp_path / "missing" / "x.mp4", 64, 64, 10)
    (tmp_path / "dir.mp4").mkdir()
    with pytest.raises(VideoError, match="cannot open"):
        VideoWriter(tmp_path / "dir.mp4", 64, 64, 10)


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="needs /dev/full")
def test_a_write_failure_names_the_file():
    # /dev/full accepts the open and fails every write with ENOSPC, like a full disk.
    with pytest.raises(VideoError, match="/dev/full"):
        with VideoWriter("/dev/full", 64, 64, 10) as video:
            for _ in range(3):
                video.write(np.zeros((64, 64, 3), dtype=np.uint8))


def test_a_failed_recording_leaves_the_previous_video_in_place(tmp_path):
    path = tmp_path / "good.mp4"
    with VideoWriter(path, 64, 64, 10) as video:
        video.write(np.zeros((64, 64, 3), dtype=np.uint8))
    good = path.read_bytes()
    with pytest.raises(RuntimeError, match="interrupted"):
        with VideoWriter(path, 64, 64, 10) as video:
            video.write(np.full((64, 64, 3), 255, dtype=np.uint8))
            raise RuntimeError("interrupted")
    assert path.read_bytes() == good  # before: overwritten by the unfinished file
    assert sorted(p.name for p in tmp_path.iterdir()) == ["good.mp4"]  # no .partial left


def test_a_short_file_is_detected(tmp_path):
    video = VideoWriter(tmp_path / "z.mp4", 64, 64, 10)
    video.write(np.zeros((64, 64, 3), dtype=np.uint8))
    video.frames += 1  # pretend a frame went missing
    with pytest.raises(VideoError, match="holds 1 frames, 2 were written"):
        video.close()
    with pytest.raises(VideoError, match="no frames"):
        VideoWriter(tmp_path / "empty.mp4", 64, 64, 10).close()


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
    render = RenderConfig(width=320, height=320)
    env = RoverEnv(n_rovers=2, n_req=2, render_mode="rgb_array", render_config=render)
    # Both rovers sit near POI 1 at (15, 0), away from its centre: captured at reset.
    env.reset(seed=0, options={"rover_positions": [(13.0, 2.0), (13.0, -2.0)]})
    frame = env.render().astype(int)
    assert frame.shape == (320, 320, 3)
    tf = _view(env, render)
    col, row = np.round(tf([15.0, 0.0])).astype(int)  # POI 1 (captured)
    assert np.abs(frame[row, col] - (60, 170, 60)).max() <= 2
    col, row = np.round(tf([-15.0, 0.0])).astype(int)  # POI 3 (not captured)
    assert np.abs(frame[row, col] - (150, 150, 150)).max() <= 2


def _lab(rgb):
    """CIE L*a*b* of an sRGB colour (D65), written from the standard's formulas."""
    linear = [((c / 255 + 0.055) / 1.055) ** 2.4 if c / 255 > 0.04045 else c / 255 / 12.92
              for c in rgb]  # fmt: skip
    r, g, b = linear
    xyz = (
        (0.4124 * r + 0.3576 * g + 0.1805 * b) / 0.95047,
        0.2126 * r + 0.7152 * g + 0.0722 * b,
        (0.0193 * r + 0.1192 * g + 0.9505 * b) / 1.08883,
    )
    f = [t ** (1 / 3) if t > 0.008856 else 7.787 * t + 16 / 116 for t in xyz]
    return 116 * f[1] - 16, 500 * (f[0] - f[1]), 200 * (f[1] - f[2])


def test_palette_tells_twenty_rovers_apart_and_from_the_pois():
    assert len(set(PALETTE_RGB)) == 20
    others = [POI_FREE[::-1], POI_CAPTURED[::-1], BACKGROUND[::-1]]  # RGB
    for i, colour in enumerate(PALETTE_RGB):
        for other in [*PALETTE_RGB[:i], *others]:
            assert math.dist(_lab(colour), _lab(other)) >= 30, (colour, other)  # CIE76
        hue, saturation, _ = colorsys.rgb_to_hsv(*(c / 255 for c in colour))
        assert saturation >= 0.4, colour  # not grey
        assert not 70 <= 360 * hue <= 170, colour  # not green (yellow ends at ~60 deg)


def test_the_hud_and_the_label_bands_stay_clear_of_rovers_and_pois():
    render = RenderConfig(width=320, height=320)
    env = RoverEnv(n_rovers=3, n_req=1, steps=5, render_mode="rgb_array", render_config=render)
    # A rover far above the ring and one far below: the view's extremes.
    env.reset(seed=0, options={"rover_positions": [(0.0, 40.0), (0.0, -40.0), (0.0, 0.0)]})
    tf = _view(env, render)
    rows = tf(env.unwrapped.world.rover_positions[0])[:, 1]
    assert rows.min() - ROVER_PX >= HUD_PX and rows.max() + ROVER_PX <= 320 - FOOTER_PX
    frame = env.render()
    for band in (frame[:HUD_PX], frame[320 - FOOTER_PX :]):
        for i in range(3):  # no body's colour (the HUD's text is grey, anti-aliased)
            assert not (band == rover_rgb(i)).all(-1).any(), i
    for i, row in enumerate(np.round(rows).astype(int)):  # the bodies are where the view says
        assert (frame[row] == rover_rgb(i)).all(-1).any(), i


def test_rover_ids_on_request():
    plain = RenderConfig(width=240, height=240)
    env = RoverEnv(n_rovers=3, n_req=1, render_mode="rgb_array", render_config=plain)
    env.reset(seed=1)
    with_ids = RoverEnv(n_rovers=3, n_req=1, render_mode="rgb_array",
                        render_config=plain.replace(ids=True))  # fmt: skip
    with_ids.reset(seed=1)
    assert not np.array_equal(env.render(), with_ids.render())


def test_rover_ids_are_dark_on_a_light_rim_and_legible():
    """An index is drawn in the text colour at 0.5 scale beside the body's top right (not
    in the body's colour: a yellow digit on grey could not be read)."""
    render = RenderConfig(width=320, height=320, ids=True)
    env = RoverEnv(n_rovers=5, n_req=1, render_mode="rgb_array", render_config=render)
    spread = [(-8.0, 8.0), (8.0, 8.0), (-8.0, -8.0), (8.0, -8.0), (0.0, 0.0)]
    env.reset(seed=0, options={"rover_positions": spread, "rover_headings": [np.pi] * 5})
    frame = env.render()
    tf = _view(env, render)
    for i, (x, y) in enumerate(np.round(tf(np.array(spread))).astype(int)):
        corner = frame[y - ROVER_PX - 16 : y - ROVER_PX, x + ROVER_PX : x + ROVER_PX + 14]
        dark = (np.abs(corner.astype(int) - TEXT_RGB).max(-1) <= 6).sum()
        assert dark >= 5, (i, dark)  # the digit's strokes (the tick points left, away)
        assert not (corner == rover_rgb(i)).all(-1).any(), i


def test_a_captured_poi_says_when_and_labels_keep_off_rovers():
    render = RenderConfig(width=400, height=400)
    env = RoverEnv(n_rovers=2, n_req=2, steps=3, render_mode="rgb_array", render_config=render)
    # both on POI 1 at (15, 0): captured at reset; then they leave
    env.reset(seed=0, options={"rover_positions": [(14.0, 1.0), (14.0, -1.0)],
                               "rover_headings": [np.pi, np.pi]})  # fmt: skip
    world = env.unwrapped.world
    assert poi_status(world_state(world, 0), env.config, 0)[:2] == ("captured t0", POI_CAPTURED)
    assert poi_status(world_state(world, 0), env.config, 1) == ("0/2", TEXT, 1)
    for _ in range(3):
        env.step(np.array([[1.0, 0.0], [1.0, 0.0]]))  # heading pi: away from POI 1
    state = world_state(world, 0)
    assert state.poi_counts[0] == 0 and poi_status(state, env.config, 0)[0] == "captured t0"
    # a rover parked where POI 2's count would first go (under its ring, at (0, 15))
    tf = _view(env, render)
    poi = np.round(tf([0.0, 15.0])).astype(int)
    px, py = poi[0], poi[1] + ring_pixels(tf, env.config, 1) + 12
    far_px, far_py = np.round(tf([-10.0, -10.0])).astype(int)
    at_pixels = [((x - tf.cx) / tf.scale, (tf.cy - y) / tf.scale)  # pixel -> world
                 for x, y in ((px, py), (far_px, far_py))]  # fmt: skip
    env.reset(seed=0, options={"rover_positions": at_pixels, "rover_headings": [0.0, 0.0]})
    assert _view(env, render) == tf  # the rovers are inside the POIs' view
    frame = env.render()
    patch = lambda x, y: frame[y - ROVER_PX : y + ROVER_PX + 1, x - ROVER_PX : x + ROVER_PX + 1]  # noqa: E731
    own = (patch(px, py) == rover_rgb(0)).all(-1).sum()
    assert own == (patch(far_px, far_py) == rover_rgb(1)).all(-1).sum()  # no label over it


def test_view_keeps_a_far_rover_in_frame():
    render = RenderConfig(width=200, height=160)
    env = RoverEnv(n_rovers=2, n_req=1, steps=40, render_mode="rgb_array", render_config=render)
    # Rover 1 starts far beyond the ring (15 + d_cap 4) and drives outwards 1 unit a step.
    env.reset(seed=0, options={"rover_positions": [(0.0, 0.0), (30.0, 0.0)],
                               "rover_headings": [0.0, 0.0]})  # fmt: skip
    for t in range(41):
        frame = env.render().astype(int)
        tf = _view(env, render)
        history = env.unwrapped.world.position_history[: t + 1, 0]  # (t + 1, R, 2)
        pixels = tf(history)  # the whole trajectory so far is in view, not just now
        assert (pixels >= 0).all() and (pixels[..., 0] < 200).all() and (pixels[..., 1] < 160).all()
        col, row = np.round(pixels[-1, 1]).astype(int)
        assert np.abs(frame[row, col] - rover_rgb(1)).max() <= 2, t
        # The view is one scale for x and y, and keeps the POIs with their capture rings.
        lo, hi = tf([-19.0, -19.0]), tf([19.0, 19.0])
        assert lo.min() >= 0 and hi[0] < 200 and lo[1] < 160
        if t < 40:
            env.step(np.array([[0.0, 0.0], [1.0, 0.0]]))
    assert env.unwrapped.world.rover_positions[0, 1, 0] == pytest.approx(70.0)


def test_clump_inset_only_while_clumped():
    render = RenderConfig()  # 640 x 640: the inset is 160 px square at the top right
    env = RoverEnv(render_mode="rgb_array", render_config=render)
    env.reset(seed=0)  # 15 rovers in the spawn disc
    top = (8, slice(640 - 168, 640 - 8))  # the inset's top border
    assert (env.render()[top] == 40).all()
    spread = [(15.0 * np.cos(a), 15.0 * np.sin(a)) for a in np.linspace(0, 6, 15)]
    env.reset(seed=0, options={"rover_positions": spread})
    assert (env.render()[top] == 246).all()


def test_poi_counts_shown_are_the_scorings():
    # POI 1 at (15, 0), POI 2 at (0, 15), POIs 3, 4 at (-15, 0), (0, -15); d_cap 4, d_min 1.
    env = RoverEnv(n_rovers=5, n_req=2, render_mode="rgb_array")
    positions = [
        (15.0, 0.0),  # on POI 1 (distance 0, bounded to d_min)
        (19.0, 0.0),  # exactly d_cap from POI 1: in range (<=, Eq. 13)
        (15.0, 4.01),  # just outside POI 1
        (0.5, 12.0),  # inside POI 2
        (-5.0, -5.0),  # near nothing
    ]
    env.reset(seed=0, options={"rover_positions": positions, "rover_headings": [0.0] * 5})
    world = env.unwrapped.world
    assert world.poi_counts[0].tolist() == [2, 1, 0, 0]
    assert world_state(world, 0).poi_counts.tolist() == [2, 1, 0, 0]
    # The same convention as the scoring: POI 1 (2 >= n_req) is captured at reset, no other.
    assert world.state.capture_step[0].tolist() == [0, -1, -1, -1]


def test_record_run_side_by_side(tmp_path):
    config = RunConfig(DomainConfig(n_rovers=3, steps=4), LearnConfig(hidden=4))
    (tmp_path / "config.toml").write_text(config.to_toml())
    (tmp_path / "champions").mkdir()
    genomes = PolicyLayout(4, 8).init((3,), np.random.default_rng(0))
    np.save(tmp_path / "champions" / "gen_000007.npy", genomes)
    render = RenderConfig(width=160, height=120)
    out, scores = record_run(tmp_path, tmp_path / "sbs.mp4", episodes=2, side_by_side=True,
                             render=render)  # fmt: skip
    assert len(scores) == 4  # (ideal, physics) per episode
    facts, frames = _read(out)
    assert facts["codec"] == "h264" and facts["pix_fmt"] == "yuv420p"
    assert facts["size"] == (2 * 160 + DIVIDER_PX, 120)
    assert len(frames) == 2 * 5
    divider = frames[0][:, 160 : 160 + DIVIDER_PX].astype(int)
    assert divider.max() <= 80  # a dark bar between the panels


def test_obstacles_are_drawn_where_they_are():
    render = RenderConfig(width=320, height=320)
    scenario = {"kind": "explicit", "obstacle_discs": [[7.0, 7.0, 2.0]]}
    env = RoverEnv(n_rovers=2, n_req=1, scenario=scenario, motion="physics",
                   render_mode="rgb_array", render_config=render)  # fmt: skip
    env.reset(seed=0)
    frame = env.render().astype(int)
    tf = _view(env, render)
    col, row = np.round(tf([7.0, 7.0])).astype(int)  # the disc's centre
    assert np.abs(frame[row, col] - (110, 110, 110)).max() <= 2
    col, row = np.round(tf([7.0, 7.0 + 2.5])).astype(int)  # just outside it: background
    assert np.abs(frame[row, col] - (246, 246, 246)).max() <= 2


def test_a_crowd_of_a_thousand_is_dots_of_one_colour_under_visible_pois():
    from physrover.viz.render import CROWD_COLOUR, PALETTE_RGB, POI_CAPTURED, POI_FREE

    env = RoverEnv(render_mode="rgb_array", n_rovers=1000, motion="physics",
                   scenario={"kind": "ring", "spawn_density": 0.2})  # fmt: skip
    env.reset(seed=0)
    frame = env.render()
    colours = {tuple(c) for c in frame.reshape(-1, 3)[::7]}
    assert not colours & {tuple(c) for c in PALETTE_RGB}  # no rover in its own colour
    crowd = np.all(frame == CROWD_COLOUR[::-1], axis=-1)
    assert crowd.sum() >= 1000 // 2  # a dot a rover (some touch), at least a pixel each
    tf = Transform.fit_states([world_state(env.unwrapped.world, 0)], env.unwrapped.config,
                              RenderConfig())  # fmt: skip
    for centre in np.round(tf(env.unwrapped.world.poi_positions[0])).astype(int):
        pixel = tuple(frame[centre[1], centre[0]])
        assert pixel in (POI_FREE[::-1], POI_CAPTURED[::-1])  # drawn over the crowd


def test_agents_that_do_not_capture_wear_a_diamond():
    """Issue 33: a UAV (a class that does not capture) is drawn with a diamond around its
    body in its colour, 2 ROVER_PX from its centre; a rover is not."""
    from physrover.domain.world import RoverWorld, StartOverrides
    from physrover.viz.render import ROVER_PX, RenderConfig, Transform, draw_frame, world_state

    domain = DomainConfig(n_req=1, agents=[{"name": "rover"},
                                           {"name": "uav", "captures": False}])  # fmt: skip
    world = RoverWorld(domain, 1)
    world.reset([np.random.default_rng(0)], StartOverrides(
        rover_positions=[(-5.0, 0.0), (5.0, 0.0)], rover_headings=[0.0, 0.0]))  # fmt: skip
    state, render = world_state(world, 0), RenderConfig()
    tf = Transform.fit_states([state], domain, render)
    frame = draw_frame(state, domain, render, tf)
    for i, wears in ((0, False), (1, True)):
        x, y = np.round(tf(state.positions[-1, i : i + 1])[0]).astype(int)
        top = frame[y - 2 * ROVER_PX - 1 : y - 2 * ROVER_PX + 2, x - 1 : x + 2].reshape(-1, 3)
        colour = np.array(rover_rgb(i))
        assert (np.abs(top.astype(int) - colour).sum(1) < 60).any() == wears


def test_a_label_at_the_frames_edge_goes_inside():
    """A POI at the left edge of the view: its value label goes right of it, not cut off."""
    from physrover.viz.labels import label_at

    img = np.zeros((100, 200, 3), dtype=np.uint8)
    placed: list = []
    spots = [(3 - 12, 50, "right"), (3 + 12, 50, "left")]  # left of a POI at x = 3 first
    label_at(img, "2 sees: uav", spots, 0.45, (255, 255, 255), 1, [], placed)
    assert placed[0][0] == 15  # the second spot, inside the frame
    assert img[:, :15].max() == 0 and img[:, 15:].max() > 0
