"""Populations of feed-forward policies, stored as one stacked genome array.

Each rover r has a population of k policies ``n_in -> hidden -> 2`` (ReLU hidden layer,
tanh output "to simulate motor saturation", paper Section 4.2; n_in = 8 with the paper's
sensor; ``[learn] activation = "tanh"`` and ``weight_init = "uniform"`` are the lab's
network, a tanh hidden layer and weights from U(-1, 1)). A policy's parameters are one
flat genome vector of length P, laid out as ``W1 (n_in x H) | b1 (H) | W2 (H x 2) | b2 (2)``;
the populations are a (R, k, P) float32 array, so selection, copying and mutation are array
operations; a batch of teams plays through the compiled forward pass
(:mod:`physrover.learn.forward`), a whole episode at once on a compiled world
(:mod:`physrover.learn.rollout`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from physrover.learn.rollout import TeamPolicy


class PolicyLayout:
    """Offsets of the weight blocks inside a genome of an ``n_in -> hidden -> n_out`` policy.

    ``n_in`` is the sensor's observation size (8 for the paper's), ``n_out`` the action size
    (2); the compiled forward pass (:func:`physrover.learn.forward.policy_forward`) takes
    any ``n_in`` and 2 outputs. A picking agent's policy (``action = "pick"``, the lab's
    ``pick_uav``) has ``n_out = U + 1`` outputs, one per agent it may pick and one to stay,
    and plays the largest (:func:`physrover.learn.forward.pick_forward`). ``activation``:
    the hidden layer's, ``"relu"`` (the paper's) or ``"tanh"`` (the lab's); ``weight_init``:
    ``"fan-in"`` (:meth:`init`) or ``"uniform"``, U(-1, 1) (the lab's).
    """

    def __init__(self, hidden: int, n_in: int, n_out: int = 2, activation: str = "relu",
                 weight_init: str = "fan-in"):  # fmt: skip
        if n_out < 2:
            raise ValueError(f"policies have at least 2 outputs, got {n_out}")
        self.n_in, self.hidden, self.n_out = n_in, hidden, n_out
        self.activation, self.weight_init = activation, weight_init
        sizes = [n_in * hidden, hidden, hidden * n_out, n_out]
        self.bounds = np.concatenate([[0], np.cumsum(sizes)])
        self.size = int(self.bounds[-1])

    def init(self, shape: tuple[int, ...], rng: np.random.Generator) -> np.ndarray:
        """Genomes of ``shape + (P,)``: weights and biases uniform in +-1/sqrt(fan_in)
        (PyTorch's default for linear layers), or in +-1 (``weight_init = "uniform"``)."""
        out = np.empty((*shape, self.size), dtype=np.float32)
        fan_in = [self.n_in, self.n_in, self.hidden, self.hidden]
        for block, fan in enumerate(fan_in):
            lo, hi = self.bounds[block], self.bounds[block + 1]
            bound = 1.0 if self.weight_init == "uniform" else 1.0 / np.sqrt(fan)
            out[..., lo:hi] = rng.uniform(-bound, bound, (*shape, hi - lo))
        return out

    def prepare(self, genomes: np.ndarray) -> TeamPolicy:
        """The policy ``obs (E, R, n_in) -> actions (E, R, n_out)`` of fixed (E, R, P)
        genomes, for the steps of an episode (the genomes are laid out once); a
        :class:`~physrover.learn.rollout.TeamPolicy`, which a compiled world plays as one
        compiled episode."""
        from physrover.learn.forward import PickPolicy
        from physrover.learn.rollout import TeamPolicy

        genomes = np.asarray(genomes)
        if genomes.shape[-1] != self.size:
            raise ValueError(f"genomes must have {self.size} parameters, got {genomes.shape[-1]}")
        tanh_hidden = self.activation == "tanh"
        if self.n_out != 2:
            return PickPolicy(genomes, self.hidden, self.n_in, self.n_out, tanh_hidden)
        return TeamPolicy(genomes, self.hidden, self.n_in, tanh_hidden)

    def act(self, genomes: np.ndarray, obs: np.ndarray) -> np.ndarray:
        """Actions of every rover of every team.

        Args:
            genomes: (E, R, P) the genome each rover of each team plays.
            obs: (E, R, n_in) observations.

        Returns:
            (E, R, 2) float32 actions in (-1, 1).
        """
        return self.prepare(genomes)(obs)
