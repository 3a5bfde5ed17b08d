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

and the done flags ``"done"``, ``"terminated"`` (always False) and ``"truncated"`` (after
``steps`` steps), (E, 1) bool. All teams run in lock step, so a reset resets them all.
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
        n_obs = self.vector_env.single_observation_space.shape[-1]
        self.n_rovers = R
        f32 = torch.float32
        self.full_observation_spec = Composite(
            {GROUP: Composite(
                {"observation": Unbounded((E, R, n_obs), dtype=f32, device=self.device),
                 "info": Composite({"D": Unbounded((E, R), dtype=f32, device=self.device)},
                                   shape=(E, R))},
                shape=(E, R))},
            shape=(E,),
        )  # fmt: skip
        self.full_action_spec = Composite(
            {GROUP: Composite(
                {"action": Bounded(-1.0, 1.0, (E, R, 2), dtype=f32, device=self.device)},
                shape=(E, R))},
            shape=(E,),
        )  # fmt: skip
        self.full_reward_spec = Composite(
            {GROUP: Composite({"reward": Unbounded((E, R, 1), dtype=f32, device=self.device)},
                              shape=(E, R))},
            shape=(E,),
        )  # fmt: skip
        flag = Categorical(2, (E, 1), dtype=torch.bool, device=self.device)
        self.full_done_spec = Composite(
            {"done": flag, "terminated": flag.clone(), "truncated": flag.clone()}, shape=(E,)
        )
        self._seed: int | None = None
        self.group_map = {GROUP: [f"{GROUP}_{i}" for i in range(R)]}
        """TorchRL's MARL convention (as ``VmasEnv.group_map``): group -> agent names."""

    def _tensor(self, array: np.ndarray) -> torch.Tensor:
        """A float32 tensor on the env's device, from the whole batch at once."""
        return torch.from_numpy(np.ascontiguousarray(array, dtype=np.float32)).to(self.device)

    def _group(self, obs: np.ndarray, infos: dict) -> TensorDict:
        """The group's (E, R) tensordict: observation and info."""
        shape = (self.batch_size[0], self.n_rovers)
        info = TensorDict({"D": self._tensor(infos["D"])}, batch_size=shape, device=self.device)
        return TensorDict({"observation": self._tensor(obs), "info": info}, batch_size=shape,
                          device=self.device)  # fmt: skip

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
        obs, infos = self.vector_env.reset(seed=seed)
        source = {GROUP: self._group(obs, infos), **self._flags(np.zeros(self.batch_size[0]))}
        return TensorDict(source, batch_size=self.batch_size, device=self.device)

    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        action = tensordict.get((GROUP, "action")).detach().to("cpu").numpy()
        obs, reward, _, truncated, infos = self.vector_env.step(action)
        group = self._group(obs, infos)
        team = self._tensor(reward)  # (E,): the increase of each team's G
        group["reward"] = team.reshape(-1, 1, 1).expand(-1, self.n_rovers, 1).clone()
        source = {GROUP: group, **self._flags(truncated)}
        return TensorDict(source, batch_size=self.batch_size, device=self.device)

    def _set_seed(self, seed: int | None) -> None:
        self._seed = None if seed is None else int(seed)
