"""The seams take a researcher's own parts without touching the package.

Everything custom is defined in this file only: a scenario (POIs on a line), a sensor (six
sectors of rover and POI density), a motion model (half-length idealised steps) and a
credit signal (G scaled). They run through the vector env, the single env (gymnasium's
``check_env``), a TOML file and the CCEA; each is checked against values worked out here.
"""

import dataclasses
import math
from typing import ClassVar

import gymnasium
import numpy as np
import pytest
from conftest import play_alike
from gymnasium.utils.env_checker import check_env

from physrover import RoverEnv, RoverVectorEnv
from physrover.config import ConfigError, DomainConfig, LearnConfig, RunConfig
from physrover.domain.motion.dynamics import Dynamics, register_dynamics
from physrover.domain.scenarios import Scenario, StartState, register_scenario, spawn_in_disc
from physrover.domain.scoring.credit import Credit, register_credit
from physrover.domain.sensing.sensor import Sensor, register_sensor
from physrover.learn.ccea import CCEA
from physrover.learn.configs import CriticConfig


@register_scenario
@dataclasses.dataclass(frozen=True)
class PoisOnALine(Scenario):
    """POIs on the x axis at ``spacing`` apart starting at ``x0``; rovers in the spawn disc."""

    kind: ClassVar[str] = "test-line"
    x0: float = 3.0
    spacing: float = 2.0
    spawn_radius: float = 1.0

    def draw(self, rngs, n_rovers, poi_values):
        positions, headings = spawn_in_disc(rngs, n_rovers, self.spawn_radius)
        k = len(poi_values)
        pois = np.zeros((len(rngs), k, 2))
        pois[..., 0] = self.x0 + self.spacing * np.arange(k)
        values = np.broadcast_to(poi_values, (len(rngs), k)).copy()
        return StartState(positions, headings, pois, values)

    def extent(self):
        return self.x0 + self.spacing * 8


@register_sensor
@dataclasses.dataclass(frozen=True)
class Sectors(Sensor):
    """Rover then POI density (Eqs. 15-16's terms) in ``n`` equal sectors of bearing,
    sector 0 starting dead behind (bearing -pi), counter-clockwise. Plain numpy."""

    kind: ClassVar[str] = "test-sectors"
    n: int = 6

    @property
    def dim(self):
        return 2 * self.n

    def observe(self, state, d_min, out):
        pos, heading = state.rover_positions, state.rover_headings
        out[:] = 0.0
        n_rovers = pos.shape[1]
        for others, values, offset in (
            (pos, np.ones(pos.shape[:2]), 0),
            (state.poi_positions, state.poi_values, self.n),
        ):
            d = others[:, None, :, :] - pos[:, :, None, :]  # (E, R, J, 2)
            dist_sq = np.maximum((d**2).sum(-1), d_min**2)
            bearing = np.arctan2(d[..., 1], d[..., 0]) - heading[:, :, None]
            bearing = (bearing + np.pi) % (2 * np.pi)
            sector = np.minimum((bearing / (2 * np.pi) * self.n).astype(int), self.n - 1)
            terms = values[:, None, :] / dist_sq
            if offset == 0:  # not the rover itself
                terms = terms * (1 - np.eye(n_rovers))
            for s in range(self.n):
                out[..., offset + s] += (terms * (sector == s)).sum(-1)


@register_dynamics
class HalfSteps(Dynamics):
    """The idealised kinematics at half the displacement (no turning)."""

    name: ClassVar[str] = "test-half-steps"

    def step(self, state, actions):
        c, s = state.cos_h, state.sin_h
        a = 0.5 * actions
        state.rover_positions[..., 0] += c * a[..., 0] - s * a[..., 1]
        state.rover_positions[..., 1] += s * a[..., 0] + c * a[..., 1]


class ScaledG(Credit):
    def __call__(self, world):
        return np.repeat(3.0 * world.G[:, None], world.n_rovers, axis=1)


register_credit("test-3G", ScaledG())

CUSTOM = dict(
    n_rovers=4, n_req=1, steps=6, poi_values=(1.0, 2.0), scenario=PoisOnALine(), sensor=Sectors()
)


def test_custom_scenario_and_sensor_in_the_vector_env():
    env = RoverVectorEnv(3, **CUSTOM)
    assert env.single_observation_space.shape == (4, 12)
    obs, info = env.reset(seed=1)
    world = env.world
    assert obs.shape == (3, 4, 12) and obs.dtype == np.float32
    np.testing.assert_array_equal(world.poi_positions[:, :, 0], [[3.0, 5.0]] * 3)
    # A hand-worked observation: rover 0 of team 0 alone with the POIs on its line.
    world.reset(
        [np.random.default_rng(0)] * 3,
        overrides=_lone_rovers(),
    )
    obs = world.step(np.zeros((3, 4, 2)))
    # Rover 0 at the origin, heading 0: POI (3, 0) value 1 and (5, 0) value 2 straight ahead,
    # bearing 0 -> sector floor((0 + pi) / (2 pi) * 6) = 3; rovers far away behind it.
    expected = 1.0 / 9.0 + 2.0 / 25.0
    assert obs[0, 0, 6 + 3] == pytest.approx(expected, rel=1e-6)
    assert obs[0, 0, 6:].sum() == pytest.approx(expected, rel=1e-6)


def _lone_rovers():
    from physrover.domain.world import StartOverrides

    far = [[0.0, 0.0], [-50.0, 0.0], [-50.0, 10.0], [-50.0, -10.0]]
    return StartOverrides(rover_positions=far, rover_headings=[0.0] * 4)


def test_custom_parts_in_the_single_env_pass_check_env():
    env = RoverEnv(**CUSTOM, motion="test-half-steps")
    check_env(env, skip_render_check=True)
    env.reset(seed=0, options={"rover_positions": [[0.0, 0.0]] * 4,
                               "rover_headings": [0.0, math.pi / 2, 0.0, 0.0]})  # fmt: skip
    env.step(np.array([[1.0, 0.0], [1.0, 0.0], [0.0, -1.0], [0.0, 0.0]], dtype=np.float32))
    positions = env.unwrapped.world.rover_positions[0]
    np.testing.assert_allclose(positions, [[0.5, 0.0], [0.0, 0.5], [0.0, -0.5], [0.0, 0.0]],
                               atol=1e-15)  # fmt: skip


def test_custom_parts_by_name_from_toml_and_gymnasium_make():
    text = """
[domain]
n_rovers = 4
n_req = 1
steps = 6
poi_values = [1.0, 2.0]
motion = "test-half-steps"

[scenario]
kind = "test-line"
spacing = 4.0

[sensor]
kind = "test-sectors"
n = 3

[learn]
feedback = "test-3G"
"""
    config = RunConfig.from_toml(text)
    assert config.domain.scenario == PoisOnALine(spacing=4.0)
    assert config.domain.sensor == Sectors(n=3)
    assert RunConfig.from_toml(config.to_toml()) == config
    env = gymnasium.make("physrover/Rover-v0", config=config.domain)
    assert env.observation_space.shape == (4, 6)
    # A field of a custom part by its bare name, and a typo named with a suggestion.
    assert config.with_overrides({"spacing": 1.5}).domain.scenario.spacing == 1.5
    with pytest.raises(ConfigError, match="did you mean 'spacing'"):
        config.with_overrides({"spacnig": 1.5})
    with pytest.raises(ConfigError, match="unknown scenario 'test-lin'"):
        DomainConfig(scenario="test-lin")


@pytest.mark.parametrize("method", ["D", "max-critic"])
def test_five_ccea_generations_with_every_custom_part(method):
    domain = DomainConfig(**CUSTOM, motion="test-half-steps")
    learn = LearnConfig(method=method, generations=5, population=4, hidden=4, eval_episodes=2,
                        feedback="test-3G")  # fmt: skip
    critic = CriticConfig(critic_hidden=4, replay_pairs=200, pair_batch=5, pair_batches=2)
    ccea = CCEA(RunConfig(domain, learn, critic if method == "max-critic" else None))
    stats = [ccea.run_generation() for _ in range(5)]
    assert ccea.layout.n_in == 12  # policies sized from the sensor
    assert [s.generation for s in stats] == [1, 2, 3, 4, 5]
    assert all(np.isfinite(s.eval_G) for s in stats)
    if method == "D":  # fitness is the credit: every rover of a team gets 3 G
        assert any(s.train_G_mean > 0 for s in stats)
        for s in stats:
            assert s.fitness_mean == pytest.approx(3.0 * s.train_G_mean, rel=1e-12)
    else:
        assert all(np.isfinite(s.critic_loss) for s in stats)


def test_only_the_built_in_parts_compile_into_the_step():
    from physrover.domain.motion.dynamics import Ideal
    from physrover.domain.sensing.density import Density
    from physrover.domain.world import RoverWorld

    @dataclasses.dataclass(frozen=True)
    class MyDensity(Density):  # a subclass may override observe: it must be called
        kind: ClassVar[str] = "test-my-density"

    class MyIdeal(Ideal):
        name: ClassVar[str] = "test-my-ideal"

    register_dynamics(MyIdeal)
    assert RoverWorld(DomainConfig(), 1).compiled
    with pytest.warns(UserWarning, match="sensor MyDensity brings no compiled kernel"):
        world = RoverWorld(DomainConfig(sensor=MyDensity()), 1)
    assert not world.compiled and world.plan.step.density is None
    for motion in ("physics", MyIdeal.name):  # stepped from Python, sensed and scored compiled
        world = RoverWorld(DomainConfig(motion=motion), 1)
        assert not world.compiled and world.plan.step.motion is None
        assert world.plan.step.density is not None and not world.plan.python_sensors


def test_the_compiled_step_equals_its_parts_called_in_turn():
    from physrover.domain.motion.dynamics import Ideal
    from physrover.domain.world import RoverWorld

    class Unfused(Ideal):  # the same motion, called as its own step
        name: ClassVar[str] = "test-unfused-ideal"

    register_dynamics(Unfused)
    small = DomainConfig(n_req=2).replace(poi_ring_radius=5.0)  # random walks capture
    worlds = [RoverWorld(small.replace(motion=m), 6) for m in ("ideal", Unfused.name)]
    assert worlds[0].compiled and not worlds[1].compiled
    commands = np.random.default_rng(3).uniform(-1.2, 1.2, (50, 6, 15, 2))
    play_alike(worlds, commands)
    a, b = worlds
    assert a.G.max() > 0
    for name in ("observations", "actions", "position_history", "heading_history", "G", "D"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)


def test_a_name_in_two_tables_must_be_written_with_its_table():
    @dataclasses.dataclass(frozen=True)
    class SpawnSensor(Sectors):  # a sensor with a field named as the scenario's
        kind: ClassVar[str] = "test-spawn-sensor"
        spawn_radius: float = 1.0

    config = DomainConfig(sensor=SpawnSensor())
    with pytest.raises(ConfigError, match="spawn_radius: is in .scenario. and .sensor.: write"):
        config.replace(spawn_radius=5.0)
    assert config.replace(**{"sensor.spawn_radius": 5.0}).sensor.spawn_radius == 5.0
    assert config.replace(**{"scenario.spawn_radius": 5.0}).scenario.spawn_radius == 5.0


def test_a_class_with_a_sensor_of_its_own_is_observed_from_python():
    """In a mixed team, a class whose sensor brings no kernel (a user's) is observed from
    Python after the compiled step, into its rows (the rest of each row 0), and the world
    says so; the other class stays compiled, as it reads alone."""
    from physrover.domain.world import RoverWorld

    text = (
        '[domain]\nn_req = 1\n[[agents]]\nname = "rover"\ncount = 3\n'
        'sensor = { kind = "lidar", radius = 6.0, empty = -1.0 }\n'
        '[[agents]]\nname = "scout"\ncount = 2\nsensor = { kind = "test-sectors", n = 3 }\n'
    )
    domain = DomainConfig.from_toml(text)
    with pytest.warns(UserWarning, match="sensor Sectors brings no compiled kernel"):
        world = RoverWorld(domain, 2)
    assert world.obs_dim == 8 and world.plan.step.classes.compiled.tolist() == [True, False]
    world.reset([np.random.default_rng(e) for e in range(2)])
    obs = world.step(np.random.default_rng(0).uniform(-1, 1, (2, 5, 2)))
    scouts = np.zeros((2, 5, 6), dtype=np.float32)
    Sectors(n=3).observe(world.state, domain.d_min, scouts)
    np.testing.assert_array_equal(obs[:, 3:, :6], scouts[:, 3:])
    assert (obs[:, 3:, 6:] == 0).all() and (obs[:, 3:, :6] != 0).any()
    rovers = np.zeros((2, 5, 8), dtype=np.float32)
    lidar = domain.agents[0].sensor
    lidar.observe_class(world.state, domain.d_min, rovers, lidar.view(domain, 0), slice(0, 3))
    np.testing.assert_array_equal(obs[:, :3], rovers[:, :3])
