"""physrover as a BenchMARL task: registration the way BenchMARL registers its own, the YAML
against DomainConfig, the env BenchMARL builds against TorchRL's checks, seeding, one-line
errors, and BenchMARL's MAPPO training on physrover end to end until it beats random.

BenchMARL pins an older TorchRL and PyAV than physrover's test extras install, so these
tests run in a venv of their own (``pip install -e ".[benchmarl]" pytest``; ``.ci/run``
makes one); elsewhere they skip.
"""

import dataclasses
import re
import warnings
from pathlib import Path

import pytest

pytest.importorskip("benchmarl")

import torch  # noqa: E402
from benchmarl.environments import task_config_registry  # noqa: E402
from benchmarl.environments.common import _type_check_task_config  # noqa: E402
from torchrl.envs.utils import check_env_specs  # noqa: E402

from physrover.cli import main  # noqa: E402
from physrover.cli.benchmarl_cmd import random_return  # noqa: E402
from physrover.config import ConfigError, DomainConfig  # noqa: E402
from physrover.envs.benchmarl_task import (  # noqa: E402
    CONF_DIR,
    PhysroverTask,
    TaskConfig,
    compose_experiment,
)
from physrover.envs.torchrl_env import GROUP  # noqa: E402

SMALL = {"n_rovers": 4, "n_req": 1, "steps": 20}


def test_tasks_are_registered_as_benchmarls_own():
    assert task_config_registry["physrover/rover_domain"] is PhysroverTask.ROVER_DOMAIN
    assert task_config_registry["physrover/rover_domain_physics"] is (
        PhysroverTask.ROVER_DOMAIN_PHYSICS
    )
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # BenchMARL warns where it finds no schema
        checked = _type_check_task_config("physrover", "rover_domain", {"n_rovers": 6})
    assert checked["n_rovers"] == 6 and checked["n_req"] == DomainConfig().n_req


def test_the_yaml_holds_every_domain_field_with_the_papers_values():
    yaml_files = sorted((CONF_DIR / "task" / "physrover").glob("*.yaml"))
    assert [p.stem for p in yaml_files] == [t.name.lower() for t in PhysroverTask]
    fields = {f.name for f in dataclasses.fields(DomainConfig)}
    assert {f.name for f in dataclasses.fields(TaskConfig)} == fields
    for path in yaml_files:
        keys = set(re.findall(r"^(\w+):", path.read_text(), re.M)) - {"defaults"}
        assert keys == fields, path.name
    assert PhysroverTask.ROVER_DOMAIN.get_from_yaml().domain == DomainConfig()
    physical = PhysroverTask.ROVER_DOMAIN_PHYSICS.get_from_yaml().domain
    assert physical == DomainConfig(motion="physics", physics={"collisions": True})


def test_agent_classes_are_refused_with_the_reason():
    with pytest.raises(ValueError, match="agents: BenchMARL tasks take the paper's rovers"):
        PhysroverTask.ROVER_DOMAIN.get_task(
            {"n_req": 1, "agents": [{"name": "rover", "count": 2}]})  # fmt: skip


def test_a_bad_field_fails_when_the_task_is_made():
    with pytest.raises(ConfigError, match="n_req"):
        PhysroverTask.ROVER_DOMAIN.get_task({"n_rovers": 3, "n_req": 4})
    with pytest.raises(Exception, match="n_rover"):
        compose_experiment(["algorithm=mappo", "task=physrover/rover_domain", "task.n_rover=3"])


@pytest.mark.parametrize("task", list(PhysroverTask))
def test_the_env_benchmarl_builds_passes_torchrls_checks(task):
    task_class = task.get_task({**SMALL, "motion": task.get_from_yaml().domain.motion})
    env = task_class.get_env_fun(num_envs=3, continuous_actions=True, seed=5, device="cpu")()
    check_env_specs(env, seed=0)
    assert task_class.group_map(env) == {GROUP: [f"rover_{i}" for i in range(4)]}
    assert task_class.max_steps(env) == 20
    assert set(task_class.observation_spec(env)[GROUP].keys()) == {"observation"}
    assert set(task_class.info_spec(env)[GROUP, "info"].keys()) == {"D"}
    assert task_class.supports_continuous_actions() and not task_class.supports_discrete_actions()


def test_failing_agents_mask_is_an_info_not_a_model_input():
    task_class = PhysroverTask.ROVER_DOMAIN.get_task({**SMALL, "failures": {"n_failing": 1}})
    env = task_class.get_env_fun(num_envs=3, continuous_actions=True, seed=5, device="cpu")()
    check_env_specs(env, seed=0)
    assert set(task_class.observation_spec(env)[GROUP].keys()) == {"observation"}
    assert set(task_class.info_spec(env)[GROUP].keys()) == {"info", "mask"}


def test_a_seed_gives_the_same_episodes():
    task_class = PhysroverTask.ROVER_DOMAIN.get_task(SMALL)

    def rollout(seed):
        env = task_class.get_env_fun(2, True, seed, "cpu")()
        torch.manual_seed(0)  # the random actions
        return env.rollout(40, break_when_any_done=False)

    a, b, c = rollout(7), rollout(7), rollout(8)
    assert torch.equal(a[GROUP, "observation"], b[GROUP, "observation"])
    assert not torch.equal(a[GROUP, "observation"], c[GROUP, "observation"])


def test_benchmarl_mappo_trains_physrover_past_random(tmp_path, capsys):
    """BenchMARL's MAPPO, as the documented command runs it, for 10 iterations of 3000
    frames (4 rovers, n_req 1): the evaluation G is well above a random policy's."""
    code = main([
        "benchmarl", "task.n_rovers=4", "task.n_req=1", "experiment.lr=0.0003",
        "experiment.max_n_iters=10", "experiment.max_n_frames=null",
        "experiment.on_policy_collected_frames_per_batch=3000",
        "experiment.on_policy_n_envs_per_worker=60", "experiment.on_policy_minibatch_size=1000",
        "experiment.on_policy_n_minibatch_iters=10", "experiment.evaluation_interval=30000",
        "experiment.evaluation_episodes=60", "seed=0", "--out", str(tmp_path / "bm"),
    ])  # fmt: skip
    assert code == 0
    line = capsys.readouterr().out.strip().splitlines()[-1]
    trained, floor = map(float, re.findall(r"[-\d.]+(?=;|$)", line))
    assert floor == pytest.approx(random_return(DomainConfig(n_rovers=4, n_req=1)))
    assert floor < 0.5 and trained > 1.5, line
    assert list((tmp_path / "bm").rglob("*.json")), "BenchMARL's marl-eval json is missing"


@pytest.mark.parametrize("name", ["n_req=1_seed=0", "it's [a] run, 1"])
def test_a_save_folder_may_hold_hydras_own_characters(tmp_path, name):
    """A sweep's run folder is named ``n_req=1_seed=0``: Hydra's override grammar reads "="
    (and quotes, brackets, commas) as its own unless the value is quoted."""
    folder = tmp_path / name / "bm"
    experiment = compose_experiment(["algorithm=mappo", "task=physrover/rover_domain",
                                     "experiment.loggers=[csv]"],
                                    save_folder=folder)  # fmt: skip
    assert Path(experiment.config.save_folder) == folder.resolve()
    assert folder.is_dir()
