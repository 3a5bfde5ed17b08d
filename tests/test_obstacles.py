"""Static boxes and segments (and discs) under physical motion: contacts hold at every
impact phase and aim, the capsules the contact pass sees are the shapes' own, bad values
and idealised motion are errors, runs are deterministic, and videos draw them."""

import math

import numpy as np
import pytest

from physrover import RoverEnv
from physrover.config import ConfigError, DomainConfig
from physrover.domain.obstacles import box_corners, capsules
from physrover.domain.world import RoverWorld, StartOverrides
from physrover.experiment.playback import world_state
from physrover.viz.render import RenderConfig, Transform

BOX = [0.0, 0.0, 1.5, 0.8, 0.3]  # centred at the origin, 3 x 1.6, turned 0.3 rad
SEGMENT = [0.0, -2.0, 0.5, 2.0, 0.2]  # a slanted wall, 0.4 thick


def _distance_to_box(points: np.ndarray, box) -> np.ndarray:
    """Signed distance from (N, 2) points to the box (negative inside), a plain loop."""
    x, y, hw, hh, a = box
    out = []
    for px, py in points:
        dx, dy = px - x, py - y
        lx = math.cos(a) * dx + math.sin(a) * dy  # in the box's frame
        ly = -math.sin(a) * dx + math.cos(a) * dy
        qx, qy = abs(lx) - hw, abs(ly) - hh
        outside = math.hypot(max(qx, 0.0), max(qy, 0.0))
        out.append(outside if outside > 0 else max(qx, qy))
    return np.array(out)


def _distance_to_segment(points: np.ndarray, seg) -> np.ndarray:
    ax, ay, bx, by, r = seg
    out = []
    for px, py in points:
        t = ((px - ax) * (bx - ax) + (py - ay) * (by - ay)) / ((bx - ax) ** 2 + (by - ay) ** 2)
        t = min(max(t, 0.0), 1.0)
        out.append(math.hypot(px - (ax + t * (bx - ax)), py - (ay + t * (by - ay))) - r)
    return np.array(out)


def _aimed_runs(scenario, distance_to, steps=10, collisions=True):
    """Rovers start 3.0-4.5 from the origin on 8 bearings (so impacts fall at every phase
    of a step), aimed at the origin or 0.6 to its side, driving at full speed; returns the
    closest any rover centre came to the obstacle, over every step end."""
    starts, headings = [], []
    for bearing in np.linspace(0.0, 2 * math.pi, 8, endpoint=False):
        for distance in np.linspace(3.0, 4.5, 7):
            for offset in (0.0, 0.6):
                x, y = distance * math.cos(bearing), distance * math.sin(bearing)
                x, y = x - offset * math.sin(bearing), y + offset * math.cos(bearing)
                starts.append([x, y])
                headings.append(bearing + math.pi)
    n = len(starts)
    config = DomainConfig(scenario=scenario, n_rovers=1, n_req=1, poi_values=(1.0,),
                          steps=steps, motion="physics",
                          physics={"collisions": collisions})  # fmt: skip
    world = RoverWorld(config, n)
    world.reset([np.random.default_rng(e) for e in range(n)],
                StartOverrides(np.array(starts)[:, None], np.array(headings)[:, None]))  # fmt: skip
    worst = np.inf
    for _ in range(steps):
        world.step(np.tile([1.0, 0.0], (n, 1, 1)))
        worst = min(worst, distance_to(world.rover_positions[:, 0]).min())
    return worst, config.physics.rover_radius


@pytest.mark.parametrize("collisions", [True, False])  # obstacles hold either way
@pytest.mark.parametrize("kind", ["box", "segment"])
def test_full_speed_impacts_stop_at_contact(kind, collisions):
    if kind == "box":
        scenario = {"kind": "explicit", "poi_positions": [[0.0, 30.0]], "obstacle_boxes": [BOX]}
        worst, radius = _aimed_runs(scenario, lambda p: _distance_to_box(p, BOX),
                                    collisions=collisions)  # fmt: skip
    else:
        scenario = {"kind": "explicit", "poi_positions": [[0.0, 30.0]],
                    "obstacle_segments": [SEGMENT]}  # fmt: skip
        worst, radius = _aimed_runs(scenario, lambda p: _distance_to_segment(p, SEGMENT),
                                    collisions=collisions)  # fmt: skip
    # every rover centre stays a radius away, within Chipmunk's slop (1% of the radius)
    assert worst >= radius - 0.01 * radius - 1e-9
    assert worst <= radius + 0.05  # and some rover did reach it


def test_capsules_are_the_shapes_edges():
    caps = capsules([[1.0, 2.0, 0.5]], [BOX], [SEGMENT])
    assert caps.shape == (6, 5)
    np.testing.assert_array_equal(caps[0], [1.0, 2.0, 1.0, 2.0, 0.5])
    corners = box_corners(BOX)
    for k in range(4):  # consecutive corners, radius 0
        np.testing.assert_allclose(caps[1 + k], [*corners[k], *corners[(k + 1) % 4], 0.0])
    # the corners are the box's: each 1.5 and 0.8 from the centre along the turned axes
    axis_w = np.array([math.cos(0.3), math.sin(0.3)])
    np.testing.assert_allclose(np.abs(corners @ axis_w), 1.5)
    assert np.all(np.diff(np.unwrap(np.arctan2(corners[:, 1], corners[:, 0]))) > 0)  # ccw
    np.testing.assert_array_equal(caps[5], SEGMENT)


def test_bad_obstacles_and_idealised_motion_are_errors():
    with pytest.raises(ConfigError, match="obstacle_boxes: every box is"):
        DomainConfig(scenario={"kind": "explicit", "obstacle_boxes": [[0, 0, -1, 1, 0]]})
    with pytest.raises(ConfigError, match="obstacle_segments: every segment is"):
        DomainConfig(scenario={"kind": "explicit", "obstacle_segments": [[0, 0, 1, 1]]})
    for field, value in (("obstacle_boxes", [BOX]), ("obstacle_segments", [SEGMENT])):
        with pytest.raises(ConfigError, match="'ideal' motion cannot hold"):
            DomainConfig(scenario={"kind": "explicit", field: value})


def test_runs_with_obstacles_and_mixed_rovers_are_deterministic():
    scenario = {"kind": "explicit", "poi_positions": [[6.0, 0.0], [-6.0, 0.0]],
                "obstacle_boxes": [[3.0, 0.0, 0.5, 2.0, 0.0]],
                "obstacle_segments": [[-3.0, -2.0, -3.0, 2.0, 0.1]],
                "obstacle_discs": [[0.0, 3.0, 0.7]]}  # fmt: skip
    fields = dict(n_rovers=4, n_req=1, poi_values=(1.0, 2.0), steps=15, motion="physics",
                  physics={"rover_radius": [0.3, 0.5, 0.3, 0.4], "max_speed": [0.5, 1, 1, 1],
                           "rover_mass": [1.0, 2.0, 1.0, 1.0]})  # fmt: skip
    paths = []
    for _ in range(2):
        world = RoverWorld(DomainConfig(scenario=scenario, **fields), 5)
        world.reset([np.random.default_rng(e) for e in range(5)])
        rng = np.random.default_rng(9)
        for _ in range(15):
            world.step(rng.uniform(-1, 1, (5, 4, 2)))
        paths.append(world.position_history.copy())
    np.testing.assert_array_equal(paths[0], paths[1])
    assert np.ptp(paths[0]) > 1.0


def test_boxes_and_segments_are_drawn_where_they_are():
    render = RenderConfig(width=320, height=320)  # room below the HUD band
    scenario = {"kind": "explicit", "obstacle_boxes": [[7.0, 7.0, 2.0, 1.0, 0.0]],
                "obstacle_segments": [[-8.0, -6.0, -2.0, -6.0, 0.5]]}  # fmt: skip
    env = RoverEnv(n_rovers=2, n_req=1, scenario=scenario, motion="physics",
                   render_mode="rgb_array", render_config=render)  # fmt: skip
    env.reset(seed=0)
    frame = env.render().astype(int)
    tf = Transform.fit_states([world_state(env.unwrapped.world, 0)], env.config, render)
    for inside in ([7.0, 7.0], [8.7, 7.8], [-5.0, -6.0], [-8.2, -6.0]):
        col, row = np.round(tf(inside)).astype(int)
        assert np.abs(frame[row, col] - (110, 110, 110)).max() <= 2, inside
    for outside in ([7.0, 8.6], [9.5, 7.0], [-5.0, -7.2]):
        col, row = np.round(tf(outside)).astype(int)
        assert np.abs(frame[row, col] - (246, 246, 246)).max() <= 2, outside
