"""A natively batched TorchRL env over :class:`~physrover.envs.gymnasium_env.RoverVectorEnv`
(``pip install 'physrover[torchrl]'``).

``RoverTorchEnv(num_envs, **fields)`` is a :class:`torchrl.envs.EnvBase` with
``batch_size = [num_envs]`` in the layout of TorchRL's MARL envs (compare
``torchrl.envs.libs.vmas.VmasEnv``): one agent group, ``"rover"``, holding per rover

- ``("rover", "observation")``: (E, R, n_obs) float32, the paper's sensor (Eqs. 14-16);
- ``("rover", "action")``: (E, R, 2) float32 in [-1, 1] (the motion model's command);
- ``("rover", "reward")``: (E, R, 1) float32, the team reward: the increase of the team's
  G this step (Eq. 11), the same for every rover of a team (the task is cooperative);
- ``("rover", "info", "D")``: (E, R) float32, each rover's difference evaluation (Eq. 1)
  on the episode's last step, zeros before;
- ``("rover", "mask")``: (E, R) bool, with ``[failures]`` only (agents that fail
  mid-episode): the agents that have not failed, as TorchRL's PettingZoo wrapper marks
  live agents (a failed agent's observation is 0, its action ignored, its reward the
  team's);

and the done flags ``"done"``, ``"terminated"`` (always False) and ``"truncated"`` (after
``steps`` steps), (E, 1) bool. With agent classes (``[[agents]]``) there is one group per
class, named after it (as VMAS gives heterogeneous agents groups of their own), each with
its agents' observations at its class's size (``("uav", "observation")`` (E, 2, 12)).
A reset resets every team, or those TorchRL's ``"_reset"`` entry (E, 1) names (a rollout's
done teams, for example), each as a reset of it alone would; teams then run at different
steps (:class:`RoverVectorEnv`'s ``reset_mask``).
The batch moves between numpy and torch as whole arrays (``torch.from_numpy``): no Python
loop over teams or rovers. Seeding: ``set_seed(s)``, then the next reset seeds team i with
``s + i``, as :class:`RoverVectorEnv` does; later resets continue the teams' generators.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.data import Bounded, Categorical, Composite, Unbounded
from torchrl.envs import EnvBase

from physrover.domain.agents.classes import agent_names, class_rows
from physrover.domain.sensing.sensor import agent_obs_sizes
from physrover.envs.gymnasium_env import RoverVectorEnv

GROUP = "rover"


class RoverTorchEnv(EnvBase):
    """The rover domain as a batched TorchRL env (see the module docstring).

    Arguments: ``RoverTorchEnv(num_envs=1, config=None, device="cpu", **fields)``, with
    ``config`` and ``fields`` as :class:`RoverVectorEnv` takes them (a DomainConfig, or
    its fields by name: ``n_rovers=4, n_req=2, motion="physics"``).
    """

    def __init__(self, num_envs: int = 1, config: Any = None, device: Any = "cpu", **fields):
        self.vector_env = RoverVectorEnv(num_envs, config, **fields)
        super().__init__(device=device, batch_size=torch.Size([num_envs]))
        self.config = self.vector_env.config
        E, R = num_envs, self.config.n_rovers
        self.n_rovers = R
        names, sizes = agent_names(self.config), agent_obs_sizes(self.config)
        self.groups = [(c.name, rows, sizes[rows.start]) for c, rows in
                       zip(self.config.agents, class_rows(self.config), strict=False)] or [
            (GROUP, slice(0, R), sizes[0])]  # fmt: skip
        """(name, rows of the team, observation size) of each group: one per agent class."""
        f32, dev = torch.float32, self.device

        def per_group(make) -> Composite:
            return Composite({name: Composite(make(rows.stop - rows.start, n_obs),
                                              shape=(E, rows.stop - rows.start))
                              for name, rows, n_obs in self.groups}, shape=(E,))  # fmt: skip

        self.masked = self.config.failures.on
        """Whether each group carries a ``"mask"`` of its live agents (``[failures]``)."""
        mask = {"mask": lambda n: Categorical(2, (E, n), dtype=torch.bool, device=dev)}
        self.full_observation_spec = per_group(
            lambda n, n_obs: {
                "observation": Unbounded((E, n, n_obs), dtype=f32, device=dev),
                "info": Composite({"D": Unbounded((E, n), dtype=f32, device=dev)}, shape=(E, n)),
                **{key: spec(n) for key, spec in mask.items() if self.masked},
            }
        )
        self.full_action_spec = per_group(
            lambda n, _: {"action": Bounded(-1.0, 1.0, (E, n, 2), dtype=f32, device=dev)}
        )
        self.full_reward_spec = per_group(
            lambda n, _: {"reward": Unbounded((E, n, 1), dtype=f32, device=dev)}
        )
        flag = Categorical(2, (E, 1), dtype=torch.bool, device=self.device)
        self.full_done_spec = Composite(
            {"done": flag, "terminated": flag.clone(), "truncated": flag.clone()}, shape=(E,)
        )
        self._seed: int | None = None
        self.group_map = {name: names[rows] for name, rows, _ in self.groups}
        """TorchRL's MARL convention (as ``VmasEnv.group_map``): group -> agent names."""

    def _tensor(self, array: np.ndarray) -> torch.Tensor:
        """A float32 tensor on the env's device, from the whole batch at once."""
        return torch.from_numpy(np.ascontiguousarray(array, dtype=np.float32)).to(self.device)

    def _groups(self, obs: np.ndarray, infos: dict) -> dict[str, TensorDict]:
        """Each group's (E, n) tensordict: its agents' observations (its class's columns)
        and info."""
        out = {}
        for name, rows, n_obs in self.groups:
            shape = (self.batch_size[0], rows.stop - rows.start)
            info = TensorDict({"D": self._tensor(infos["D"][:, rows])}, batch_size=shape,
                              device=self.device)  # fmt: skip
            observation = self._tensor(obs[:, rows, :n_obs])
            out[name] = TensorDict(
                {"observation": observation, "info": info}, batch_size=shape, device=self.device
            )
            if self.masked:
                out[name]["mask"] = torch.from_numpy(infos["alive"][:, rows].copy()).to(self.device)
        return out

    def _flags(self, truncated: np.ndarray) -> dict:
        shape = (self.batch_size[0], 1)
        truncated = torch.as_tensor(np.asarray(truncated, dtype=bool), device=self.device)
        return {
            "done": truncated.reshape(shape).clone(),
            "terminated": torch.zeros(shape, dtype=torch.bool, device=self.device),
            "truncated": truncated.reshape(shape).clone(),
        }

    def _reset(self, tensordict: TensorDictBase | None = None, **kwargs) -> TensorDictBase:
        seed, self._seed = self._seed, None  # a set seed seeds the next reset only
        options = None
        if tensordict is not None and "_reset" in tensordict.keys():
            mask = tensordict.get("_reset").reshape(-1).cpu().numpy().astype(bool)
            options = None if mask.all() else {"reset_mask": mask}
        obs, infos = self.vector_env.reset(seed=seed, options=options)
        source = {**self._groups(obs, infos), **self._flags(np.zeros(self.batch_size[0]))}
        return TensorDict(source, batch_size=self.batch_size, device=self.device)

    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        action = np.concatenate(
            [
                tensordict.get((name, "action")).detach().to("cpu").numpy()
                for name, _, _ in self.groups
            ],
            axis=1,
        )  # team order
        obs, reward, _, truncated, infos = self.vector_env.step(action)
        groups = self._groups(obs, infos)
        team = self._tensor(reward)  # (E,): the increase of each team's G
        for name, rows, _ in self.groups:
            n = rows.stop - rows.start
            groups[name]["reward"] = team.reshape(-1, 1, 1).expand(-1, n, 1).clone()
        source = {**groups, **self._flags(truncated)}
        return TensorDict(source, batch_size=self.batch_size, device=self.device)

    def _set_seed(self, seed: int | None) -> None:
        self._seed = None if seed is None else int(seed)
