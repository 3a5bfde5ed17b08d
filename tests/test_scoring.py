"""Scoring (Eqs. 11-14) and difference evaluations (Eq. 1), worked by hand."""

import numpy as np
import pytest
from oracles import score_episode

from physrover.config import DomainConfig
from physrover.domain.world import RoverWorld, StartOverrides


def _world(n_rovers, n_req, poi_values=(5.0,)):
    cfg = DomainConfig(n_rovers=n_rovers, n_req=n_req, poi_values=poi_values, steps=5)
    return RoverWorld(cfg, n_teams=1)


def _reset(world, rovers, pois=((0.0, 0.0),)):
    return world.reset(
        [np.random.default_rng(0)],
        StartOverrides(
            rover_positions=rovers, rover_headings=np.zeros(len(rovers)), poi_positions=pois
        ),
    )


def test_capture_needs_n_req_rovers_in_range():
    # POI at the origin, d_cap 4: (3, 0) is in (9 <= 16), (0, 4) is on the circle (16 <= 16,
    # in), (4.01, 0) is out.
    rovers = [(3.0, 0.0), (0.0, 4.0), (4.01, 0.0)]
    w = _world(3, n_req=2)
    _reset(w, rovers)
    assert w.G[0] == 5.0
    w = _world(3, n_req=3)
    _reset(w, rovers)
    assert w.G[0] == 0.0


def test_d_min_does_not_block_capture():
    # A rover exactly on the POI has delta = d_min, still within d_cap.
    w = _world(1, n_req=1)
    _reset(w, [(0.0, 0.0)])
    assert w.G[0] == 5.0


def test_capture_at_one_step_only_counts():
    # Two rovers drive along y = +-3.9 past a POI at the origin, 1 unit per step from x = -3.
    # In range iff x^2 + 3.9^2 <= 16, i.e. |x| <= 0.889: only at x = 0 (step 3).
    w = _world(2, n_req=2)
    _reset(w, [(-3.0, 3.9), (-3.0, -3.9)])
    history = []
    for _ in range(5):
        w.step(np.array([[[1.0, 0.0], [1.0, 0.0]]]))
        history.append(w.G[0])
    assert history == [0.0, 0.0, 5.0, 5.0, 5.0]
    assert np.all(np.hypot(*w.rover_positions[0].T) > 4.0)  # nobody is in range at the end


def test_each_poi_counts_once():
    in_range = np.ones((4, 1, 2, 2), dtype=bool)  # captured at every step
    G, D = score_episode(in_range, np.array([1.0, 2.0]), n_req=2)
    assert G[0] == 3.0


def test_difference_evaluations_essential_redundant_idle():
    # One POI (V=5), n_req 2. Team A: rovers 0, 1 in range, 2 far -> D = (5, 5, 0).
    # Team B: rovers 0, 1, 2 in range -> each redundant, D = (0, 0, 0).
    # Team C: only rover 0 in range -> G = 0, D = 0.
    in_range = np.array(
        [[[[True], [True], [False]], [[True], [True], [True]], [[True], [False], [False]]]]
    )  # (T=1, E=3, R=3, K=1)
    G, D = score_episode(in_range, np.array([5.0]), n_req=2)
    np.testing.assert_array_equal(G, [5.0, 5.0, 0.0])
    np.testing.assert_array_equal(D, [[5.0, 5.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])


def test_difference_removes_the_whole_trajectory():
    # Two POIs (V 1, 2), n_req 2. Step 0: rovers 0, 1 at POI 0. Step 1: rovers 1, 2 at POI 1.
    # Without rover 1 nothing is captured: D_1 = 3. Without 0: POI 1 still -> D_0 = 1.
    t0 = [[[True, False], [True, False], [False, False]]]
    t1 = [[[False, False], [False, True], [False, True]]]
    G, D = score_episode(np.array([t0, t1]), np.array([1.0, 2.0]), n_req=2)
    assert G[0] == 3.0
    np.testing.assert_array_equal(D[0], [1.0, 3.0, 2.0])


def test_world_D_matches_brute_force_recomputation():
    # D_i from the online records equals rescoring the episode with rover i deleted.
    cfg = DomainConfig(n_rovers=6, n_req=2, poi_values=(1.0, 2.0, 3.0), steps=20).replace(
        poi_ring_radius=4.0
    )
    w = RoverWorld(cfg, n_teams=8)
    w.reset([np.random.default_rng(s) for s in range(8)])
    rng = np.random.default_rng(9)
    history = []
    d_cap2 = cfg.d_cap**2

    def record():
        diff = w.rover_positions[:, :, None, :] - w.poi_positions[:, None, :, :]
        history.append(np.maximum((diff**2).sum(-1), cfg.d_min**2) <= d_cap2)

    record()
    for _ in range(cfg.steps):
        w.step(rng.uniform(-1, 1, (8, 6, 2)))
        record()
    in_range = np.array(history)
    G, _ = score_episode(in_range, w.poi_values, cfg.n_req)
    np.testing.assert_array_equal(G, w.G)
    assert G.max() > 0  # the check is not vacuous
    for i in range(6):
        G_minus_i, _ = score_episode(np.delete(in_range, i, axis=2), w.poi_values, cfg.n_req)
        np.testing.assert_array_equal(w.D[:, i], G - G_minus_i)


@pytest.mark.parametrize("n_req", [1, 2, 3])
def test_score_is_bounded_by_poi_values(n_req):
    in_range = np.random.default_rng(n_req).random((10, 5, 4, 3)) < 0.5
    G, D = score_episode(in_range, np.array([1.0, 2.0, 4.0]), n_req)
    assert np.all((G >= 0) & (G <= 7.0))
    assert np.all((D >= 0) & (D <= G[:, None]))
