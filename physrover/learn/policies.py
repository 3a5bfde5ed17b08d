"""Populations of feed-forward policies, stored as one stacked genome array.

Each rover r has a population of k policies ``8 -> hidden -> 2`` (ReLU hidden layer, tanh
output "to simulate motor saturation", paper Section 4.2). A policy's parameters are one
flat genome vector of length P, laid out as ``W1 (8 x H) | b1 (H) | W2 (H x 2) | b2 (2)``;
the populations are a (R, k, P) float32 array, so selection, copying and mutation are array
operations and a batch of teams is evaluated with two batched matrix products.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from physrover.domain.sensing import OBS_DIM
from physrover.domain.world import ACTION_DIM
from physrover.engine import resolve


class PolicyLayout:
    """Offsets of the weight blocks inside a genome of a policy with ``hidden`` units.

    ``engine`` chooses how :meth:`prepare` evaluates policies: the compiled kernel
    (``"numba"``, :func:`physrover.learn.kernels.policy_forward`) or :meth:`forward`
    (``"numpy"``, the reference); default from ``PHYSROVER_ENGINE``.
    """

    def __init__(
        self, hidden: int, n_in: int = OBS_DIM, n_out: int = ACTION_DIM, engine: str | None = None
    ):
        self.n_in, self.hidden, self.n_out = n_in, hidden, n_out
        self.engine = resolve(engine)
        sizes = [n_in * hidden, hidden, hidden * n_out, n_out]
        self.bounds = np.concatenate([[0], np.cumsum(sizes)])
        self.size = int(self.bounds[-1])

    def init(self, shape: tuple[int, ...], rng: np.random.Generator) -> np.ndarray:
        """Genomes of ``shape + (P,)``: weights and biases uniform in +-1/sqrt(fan_in)
        (PyTorch's default for linear layers)."""
        out = np.empty((*shape, self.size), dtype=np.float32)
        fan_in = [self.n_in, self.n_in, self.hidden, self.hidden]
        for block, fan in enumerate(fan_in):
            lo, hi = self.bounds[block], self.bounds[block + 1]
            bound = 1.0 / np.sqrt(fan)
            out[..., lo:hi] = rng.uniform(-bound, bound, (*shape, hi - lo))
        return out

    def split(self, genomes: np.ndarray) -> tuple[np.ndarray, ...]:
        """(W1, b1, W2, b2) of (..., P) genomes as contiguous arrays, for repeated forwards."""
        b, batch = self.bounds, genomes.shape[:-1]
        return (
            np.ascontiguousarray(genomes[..., b[0] : b[1]].reshape(*batch, self.n_in, self.hidden)),
            np.ascontiguousarray(genomes[..., b[1] : b[2]]),
            np.ascontiguousarray(
                genomes[..., b[2] : b[3]].reshape(*batch, self.hidden, self.n_out)
            ),
            np.ascontiguousarray(genomes[..., b[3] : b[4]]),
        )

    def forward(self, weights: tuple[np.ndarray, ...], obs: np.ndarray) -> np.ndarray:
        """Actions from :meth:`split` weights of shape (E, R, ...) and (E, R, 8) observations:
        (E, R, 2) float32 in (-1, 1)."""
        w1, b1, w2, b2 = weights
        h = (obs[..., None, :].astype(np.float32) @ w1)[..., 0, :]
        h += b1
        np.maximum(h, 0.0, out=h)
        out = (h[..., None, :] @ w2)[..., 0, :]
        out += b2
        return np.tanh(out, out=out)

    def prepare(self, genomes: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
        """A function ``obs (E, R, 8) -> actions (E, R, 2)`` of fixed (E, R, P) genomes, for
        the steps of an episode (the weights are laid out once)."""
        # The kernel is compiled for the domain's sizes (8 observations, 2 actions).
        if self.engine == "numpy" or (self.n_in, self.n_out) != (OBS_DIM, ACTION_DIM):
            weights = self.split(genomes)
            return lambda obs: self.forward(weights, obs)
        from physrover.learn.kernels import policy_forward

        genomes = np.ascontiguousarray(genomes, dtype=np.float32)
        if genomes.shape[-1] != self.size:
            raise ValueError(f"genomes must have {self.size} parameters, got {genomes.shape[-1]}")

        def act(obs: np.ndarray) -> np.ndarray:
            out = np.empty((*genomes.shape[:-1], self.n_out), dtype=np.float32)
            obs = np.asarray(obs, dtype=np.float32)
            policy_forward(genomes, self.hidden, obs, out)
            return np.tanh(out, out=out)

        return act

    def act(self, genomes: np.ndarray, obs: np.ndarray) -> np.ndarray:
        """Actions of every rover of every team.

        Args:
            genomes: (E, R, P) the genome each rover of each team plays.
            obs: (E, R, 8) observations.

        Returns:
            (E, R, 2) float32 actions in (-1, 1).
        """
        return self.prepare(genomes)(obs)
