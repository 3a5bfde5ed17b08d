"""The credit seam: built-in D and G, and a signal defined here, outside the package."""

import numpy as np
import pytest

from physrover.config import ConfigError, RunConfig
from physrover.core.registry import CREDITS
from physrover.domain.scoring.credit import Credit, register_credit
from physrover.learn.ccea import CCEA

EASY = {"n_rovers": 3, "n_req": 1, "population": 6, "steps": 20, "eval_episodes": 2,
        "poi_ring_radius": 6.0, "method": "D"}  # fmt: skip


class HalfG(Credit):
    """A signal that lives only in this test file: half the team score for every rover."""

    def __call__(self, world):
        return np.repeat(0.5 * world.G[:, None], world.n_rovers, axis=1)


@pytest.fixture
def half_g():
    register_credit("half-G", HalfG(), replace=True)  # the README's example has one too
    yield "half-G"
    del CREDITS._entries["half-G"]


def test_a_credit_defined_outside_the_package_drives_the_ccea(half_g):
    ccea = CCEA(RunConfig().with_overrides({**EASY, "feedback": half_g}))
    for _ in range(5):
        stats = ccea.run_generation()
        # method D takes each policy's feedback as its fitness: the mean fitness over the
        # population is half the mean G of the teams it played in
        assert stats.fitness_mean == pytest.approx(0.5 * stats.train_G_mean, abs=1e-12)


@pytest.mark.parametrize("signal", ["D", "G"])
def test_built_in_signals_are_the_worlds_scores(signal):
    ccea = CCEA(RunConfig().with_overrides({**EASY, "feedback": signal}))
    order = ccea.method.plan(np.random.default_rng(0), 3, 6)
    teams = order.transpose(0, 2, 1).reshape(6, 3)
    G, credit = ccea.rollout(np.concatenate([teams, teams[:2]]))  # + the 2 eval episodes
    world = ccea.env.world
    expected = world.D if signal == "D" else np.repeat(world.G[:, None], 3, axis=1)
    np.testing.assert_array_equal(credit, expected)
    assert G.max() > 0  # a case that can tell D from G


def test_unknown_credit_names_are_errors_with_a_suggestion():
    with pytest.raises(ConfigError, match="unknown credit signal 'd'.*did you mean 'D'"):
        RunConfig().with_overrides({"feedback": "d"})
    with pytest.raises(TypeError, match="Credit instance"):
        register_credit("bad", lambda world: world.D)
