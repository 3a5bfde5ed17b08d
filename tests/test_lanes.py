"""The classes' lidar vectorised over a team's observers (physrover.domain.sensing.lanes)
reads what the agent-by-agent kernel reads, bit for bit, and is taken only where every
compiled class reads as the density sensor in one layout."""

from pathlib import Path

import numpy as np
import pytest

from physrover.config.run import RunConfig
from physrover.domain.sensing.classes import sense_classes, sensing_scratch
from physrover.domain.sensing.lanes import no_lanes
from physrover.domain.world import RoverWorld

MIXED = Path(__file__).parent.parent / "benchmarks" / "configs" / "mixed15.toml"


def _read(state, table, shape):
    obs = np.full(shape, 7.0, np.float32)
    scratch = sensing_scratch(table, shape[1])
    for e in range(shape[0]):
        sense_classes(e, state, table, obs, scratch)
    return obs


@pytest.mark.parametrize("seed", range(3))
def test_lanes_read_the_agent_by_agent_kernel_bit_for_bit(seed):
    domain = RunConfig.load(MIXED).domain
    world = RoverWorld(domain, 6)
    world.reset([np.random.default_rng([seed, e]) for e in range(6)])
    table = world.plan.step.classes
    assert table.lanes.on
    scalar = table._replace(lanes=no_lanes())
    rng = np.random.default_rng(seed)
    seen_empty = seen_value = False
    for _ in range(12):
        world.step(rng.uniform(-1, 1, (6, domain.n_rovers, 2)))
        shape = (6, domain.n_rovers, world.obs_dim)
        fast, slow = _read(world.state, table, shape), _read(world.state, scalar, shape)
        np.testing.assert_array_equal(fast, slow)
        seen_empty |= bool((fast == -1.0).any())
        seen_value |= bool((fast > 0).any())
    assert seen_empty and seen_value


def test_other_compositions_keep_the_agent_by_agent_kernel():
    text = MIXED.read_text().replace("radius = 3.0, empty",
                                     'radius = 3.0, compose = "average", empty')  # fmt: skip
    domain = RunConfig.from_toml(text).domain
    assert not RoverWorld(domain, 2).plan.step.classes.lanes.on
