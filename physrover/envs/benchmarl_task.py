"""physrover as a BenchMARL task (``pip install 'physrover[benchmarl]'``).

BenchMARL adds an environment as an enum of tasks whose members build a task class; this
module writes both for physrover, the way BenchMARL's own VMAS tasks are written, and
registers them with BenchMARL when it is imported:

- :class:`PhysroverTask` (the enum): ``ROVER_DOMAIN`` (the paper's domain, idealised
  motion) and ``ROVER_DOMAIN_PHYSICS`` (the same with pymunk bodies and collisions);
- :class:`PhysroverClass` (its task class): each team is one :class:`RoverTorchEnv` batch,
  one agent group ``"rover"``, continuous actions, the team reward per rover;
- the YAML of each task (``physrover/envs/benchmarl_conf/task/physrover/<task>.yaml``)
  holds the :class:`~physrover.config.DomainConfig` fields by name, with the paper's
  values, and :data:`TaskConfig` is its schema (made from DomainConfig's fields, so a
  misspelt ``task.n_rover=4`` is a one-line error from Hydra).

From Python::

    from physrover.envs.benchmarl_task import PhysroverTask
    task = PhysroverTask.ROVER_DOMAIN.get_from_yaml()          # the YAML's fields
    task = PhysroverTask.ROVER_DOMAIN.get_task({"n_rovers": 4, "n_req": 1})  # others default

and then BenchMARL's ``Experiment(task=task, algorithm_config=MappoConfig.get_from_yaml(),
...)``. From the command line, ``physrover benchmarl algorithm=mappo
task=physrover/rover_domain task.n_req=1`` (:func:`compose_experiment` reads the
overrides exactly as BenchMARL's ``benchmarl/run.py`` does).

The episode's return is the team's G (Eq. 11): each step's reward is the increase of G.
"""

from __future__ import annotations

import copy
import dataclasses
import sys
import types
import typing
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from benchmarl.environments import Task, TaskClass, _task_class_registry, task_config_registry
from torchrl.data import Composite
from torchrl.envs import EnvBase

from physrover.config import DomainConfig
from physrover.envs.torchrl_env import GROUP, RoverTorchEnv

ENV_NAME = "physrover"
CONF_DIR = Path(__file__).with_name("benchmarl_conf")
"""Hydra's search path entry for the tasks' YAML (``task/physrover/<task>.yaml``)."""


def _schema_field(field: dataclasses.Field) -> tuple[str, Any, dataclasses.Field]:
    """One DomainConfig field as a field of an OmegaConf structured config (lists, not
    tuples; ``Any`` where DomainConfig takes several forms), with DomainConfig's default."""
    annotation = typing.get_type_hints(DomainConfig)[field.name]
    if typing.get_origin(annotation) is tuple:
        default = list(field.default)
        return field.name, list[typing.get_args(annotation)[0]], dataclasses.field(
            default_factory=lambda: list(default))  # fmt: skip
    if annotation in (int, float, str, bool):
        return field.name, annotation, dataclasses.field(default=field.default)
    if isinstance(field.default, tuple):  # [[pois]], [[agents]]: lists of tables
        return field.name, Any, dataclasses.field(default_factory=list)
    return field.name, Any, dataclasses.field(default=field.default)


TaskConfig = dataclasses.make_dataclass(
    "TaskConfig", [_schema_field(f) for f in dataclasses.fields(DomainConfig)]
)
TaskConfig.__doc__ = """The schema of a physrover task's YAML: DomainConfig's fields, defaults
and types (BenchMARL's ``TaskConfig`` convention)."""


class PhysroverClass(TaskClass):
    """The task class of :class:`PhysroverTask`: how BenchMARL builds and reads the env.

    ``config`` holds DomainConfig fields by name (missing ones take the paper's values);
    it is validated on construction, so a bad value fails before an experiment starts,
    with the field named.
    """

    def __init__(self, name: str, config: dict[str, Any]):
        super().__init__(name=name, config=config)
        self.domain = DomainConfig.from_dict(dict(config))
        if self.domain.agents:  # its specs name the one group "rover"
            raise ValueError("agents: BenchMARL tasks take the paper's rovers; agent classes "
                             "train with the CCEA (physrover train)")  # fmt: skip

    def get_env_fun(self, num_envs: int, continuous_actions: bool, seed: int | None,
                    device: Any) -> typing.Callable[[], EnvBase]:  # fmt: skip
        """A function making ``num_envs`` teams as one batched env, seeded with ``seed``
        (team i's first episode from seed + i, as :class:`RoverVectorEnv`)."""
        if not continuous_actions:
            raise ValueError("physrover's actions are continuous: choose an algorithm that "
                             "supports them (mappo, ippo, maddpg, iddpg, masac, isac)")  # fmt: skip
        domain = copy.deepcopy(self.domain)

        def make() -> EnvBase:
            env = RoverTorchEnv(num_envs, domain, device=device)
            if seed is not None:
                env.set_seed(seed)
            return env

        return make

    def supports_continuous_actions(self) -> bool:
        return True

    def supports_discrete_actions(self) -> bool:
        return False

    def has_render(self, env: EnvBase) -> bool:
        return False  # videos: `physrover render` on a physrover run

    def max_steps(self, env: EnvBase) -> int:
        return self.domain.steps

    def group_map(self, env: EnvBase) -> dict[str, list[str]]:
        return env.group_map

    def state_spec(self, env: EnvBase) -> Composite | None:
        return None

    def action_mask_spec(self, env: EnvBase) -> Composite | None:
        return None

    def observation_spec(self, env: EnvBase) -> Composite:
        """The group's observations alone (BenchMARL's models take every key here as an
        input): the info and, with ``[failures]``, the live agents' mask are infos."""
        spec = env.full_observation_spec_unbatched.clone()
        del spec[(GROUP, "info")]
        if (GROUP, "mask") in spec.keys(True):
            del spec[(GROUP, "mask")]
        return spec

    def info_spec(self, env: EnvBase) -> Composite | None:
        spec = env.full_observation_spec_unbatched.clone()
        del spec[(GROUP, "observation")]
        return spec

    def action_spec(self, env: EnvBase) -> Composite:
        return env.full_action_spec_unbatched

    @staticmethod
    def env_name() -> str:
        return ENV_NAME


class PhysroverTask(Task):
    """physrover's BenchMARL tasks; each member's YAML is in :data:`CONF_DIR`."""

    ROVER_DOMAIN = None
    ROVER_DOMAIN_PHYSICS = None

    @staticmethod
    def associated_class():
        return PhysroverClass

    def get_from_yaml(self, path: str | None = None) -> TaskClass:
        """The task with its YAML's fields (physrover's own YAML unless ``path`` is given)."""
        from benchmarl.utils import _read_yaml_config

        if path is None:
            path = str(CONF_DIR / "task" / ENV_NAME / f"{self.name.lower()}.yaml")
        config = _read_yaml_config(path)
        return self.get_task(config=dataclasses.asdict(TaskConfig(**config)))


def register() -> None:
    """Register the tasks as BenchMARL registers its own (idempotent): the enum members in
    ``task_config_registry`` ("physrover/rover_domain", ...), the schema in
    ``_task_class_registry`` and Hydra's ConfigStore (``physrover_<task>_config``), and
    the schema where BenchMARL's type check imports it from
    (``benchmarl.environments.physrover.<task>``, as a module object: BenchMARL's check
    imports its own package's modules by name)."""
    from hydra.core.config_store import ConfigStore

    for task in PhysroverTask:
        name = task.name.lower()
        task_config_registry[f"{ENV_NAME}/{name}"] = task
        _task_class_registry[f"{ENV_NAME}_{name}"] = TaskConfig
        ConfigStore.instance().store(name=f"{ENV_NAME}_{name}_config", group="task",
                                     node=TaskConfig)  # fmt: skip
        module = types.ModuleType(f"benchmarl.environments.{ENV_NAME}.{name}")
        module.TaskConfig = TaskConfig
        sys.modules[module.__name__] = module


def compose_experiment(overrides: Sequence[str], save_folder: str | Path | None = None):
    """A BenchMARL ``Experiment`` from Hydra overrides, as ``benchmarl/run.py`` makes it
    (``algorithm=mappo task=physrover/rover_domain task.n_req=1 seed=0 ...``), with
    physrover's task YAML on the search path. ``save_folder`` (created) overrides
    ``experiment.save_folder``; Hydra's errors name the bad override."""
    from benchmarl.hydra_config import load_experiment_from_hydra
    from hydra import compose, initialize_config_module

    register()
    overrides = list(overrides)
    choices = dict(o.split("=", 1) for o in overrides if o.split("=", 1)[0] in ("task",))
    task_name = choices.get("task")
    if task_name not in task_config_registry:
        known = ", ".join(sorted(k for k in task_config_registry if k.startswith(ENV_NAME)))
        raise ValueError(f"task={task_name}: expected a BenchMARL task such as {known}")
    if save_folder is not None:  # quoted: a run folder's name may hold "=" (n_req=1_seed=0)
        quoted = str(Path(save_folder).resolve()).replace("\\", "\\\\").replace("'", "\\'")
        overrides.append(f"experiment.save_folder='{quoted}'")
    search = f"hydra.searchpath=[file://{CONF_DIR}]"
    with initialize_config_module(config_module="benchmarl.conf", version_base=None):
        cfg = compose(config_name="config", overrides=[*overrides, search])
    if save_folder is not None:  # BenchMARL writes into it; it does not make it
        Path(save_folder).mkdir(parents=True, exist_ok=True)
    return load_experiment_from_hydra(cfg, task_name=task_name)


register()
