"""Fitness critics (paper Section 3): intermediate critics, aggregation, updates, replay.

Intermediate critic of rover i (Eq. 2), for a state-action pair x = (s, a) in R^D:

    C(x; w) = sum_h lrelu(x . W1[:, h] + b1[h]) + b2

a D -> 80 -> 1 network (D = 10 with the paper's sensor) with leaky-ReLU hidden units
(slope 0.01) whose hidden-to-output weights are fixed to 1; only W1, b1 and the output
bias b2 train (paper Section 4.2). Beyond the paper, ``output_weights="trained"`` makes
them parameters W2 (initialised to 1) trained with the rest,
``C(x) = sum_h W2[h] lrelu(...)_h + b2`` (an ablation: with positive W2 the two critics
represent the same functions, lrelu being positively homogeneous, but learn differently).
The critics of all R rovers are stacked and evaluated and trained together.

Fitness critic (Eqs. 3-5): the aggregate of C over the policy's trajectory T of this
generation, ``F_max(T) = max_t C(x_t)`` or ``F_mean(T) = mean_t C(x_t)``.

Updates, once per generation, on mini-batches drawn uniformly (with replacement) from the
rover's replay buffer, each a plain gradient step by default:

- *regular* (Eqs. 6-8): the buffer holds trajectories with their immediate feedback f_k;
  ``dw = lr * sum_k (f_k - F(T_k)) grad_w F(T_k)``, where ``grad F_mean`` is the mean of the
  pairs' gradients and ``grad F_max`` is the gradient at the arg-max pair only;
- *inexact* (Eqs. 9-10): the buffer holds state-action pairs, each with the feedback of
  its trajectory; ``dw = lr * sum_k (f_k - C(x_k)) grad_w C(x_k)``.

Both are gradient descent on half the summed squared error, so ``optimizer="adam"`` runs
Adam on the same gradient instead. Gradients are written out by hand in the compiled
kernels (:mod:`physrover.learn.kernels`; tested against finite differences and a plain numpy
oracle): for weights ``u_n`` on pairs x_n,
``sum_n u_n grad C(x_n) = (X^T (u * g), sum_n u_n g_n, sum_n u_n)`` with
``g = lrelu'(X W1 + b1)``.

Pairs have D = n_in + 2 inputs: the sensor's observation and the action (10 with the
paper's sensor). Beyond the paper, ``step_input`` appends the pair's step t / (T - 1) as an
eleventh input, so a critic can value *when* a state is reached, not only where; and
``top_k`` > 1 makes the max critic's fitness the mean of the k largest values along the
trajectory instead of the largest alone (a softer max, less sensitive to one over-valued
pair; its inexact updates are per pair, so only the fitness changes); and ``ensemble`` = K
> 1 gives each rover K intermediate critics (own initialisations, each trained on its own
mini-batches drawn from the rover's one replay buffer), a pair's value being
``mean_k C_k(x) + optimism * std_k C_k(x)`` (population std): with ``optimism`` > 0 an
upper confidence value, optimism under the critic's uncertainty in the spirit of the
paper's optimistic max. Critics are stacked rover-major: critic ``r * K + k``. And
``target = "step"`` (inexact updates) stores each pair with its own step's credit (the
feedback signal of the step its action leads to, taken alone) instead of its trajectory's
feedback, so the critic is fitted pair by pair to where credit arose.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from physrover.core.compiled import dims
from physrover.learn.kernels import critic_update, critic_values


class IntermediateCritics:
    """R critics ``C(x) = sum_h lrelu(x W1 + b1)_h + b2`` (Eq. 2) on pairs of ``pair_dim``
    inputs, stacked; float32 parameters W1 (R, D, H), b1 (R, H), b2 (R,), and with
    ``trained_output`` W2 (R, H) (else None: the paper's fixed unit weights)."""

    def __init__(
        self,
        n_critics: int,
        pair_dim: int,
        hidden: int,
        slope: float,
        rng: np.random.Generator,
        trained_output: bool = False,
    ):
        bound = 1.0 / np.sqrt(pair_dim)  # PyTorch's default initialisation of a linear layer
        self.W1 = rng.uniform(-bound, bound, (n_critics, pair_dim, hidden)).astype(np.float32)
        self.b1 = rng.uniform(-bound, bound, (n_critics, hidden)).astype(np.float32)
        self.b2 = np.zeros(n_critics, dtype=np.float32)
        self.W2 = np.ones((n_critics, hidden), dtype=np.float32) if trained_output else None
        self.slope = np.float32(slope)

    def params(self) -> list[np.ndarray]:
        return [self.W1, self.b1, self.b2] + ([] if self.W2 is None else [self.W2])

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """C for (R, N, D) pairs -> (R, N) float32."""
        x = np.ascontiguousarray(x, dtype=np.float32)  # no copy if it already is
        out = np.empty(x.shape[:2], dtype=np.float32)
        critic_values(self.W1T(), self.b1, self.b2, self.W2, self.slope, x, out,
                      dims(x.shape[-1]))  # fmt: skip
        return out

    def W1T(self) -> np.ndarray:
        """(R, H, D) contiguous copy of W1, the layout of the compiled kernels."""
        return np.ascontiguousarray(np.swapaxes(self.W1, 1, 2))


def aggregate(values: np.ndarray, how: str) -> tuple[np.ndarray, np.ndarray]:
    """Eq. 3 / Eq. 4 over the last axis (the steps of a trajectory).

    Returns the aggregate and d(aggregate)/d(values), of the shapes of ``values[..., 0]``
    and ``values``: ``1/T`` everywhere for the mean, one-hot at the (first) arg-max for max.
    """
    if how == "mean":
        return values.mean(-1), np.full(values.shape, 1.0 / values.shape[-1], dtype=values.dtype)
    if how == "max":
        arg = values.argmax(-1)
        onehot = np.zeros(values.shape, dtype=values.dtype)
        np.put_along_axis(onehot, arg[..., None], 1.0, axis=-1)
        return np.take_along_axis(values, arg[..., None], -1)[..., 0], onehot
    raise ValueError(f"unknown aggregation {how!r}")


class ReplayBuffer:
    """Per-rover ring buffers of (item, feedback); the newest ``capacity`` entries are kept.

    All rovers receive the same number of entries, so one write pointer serves them all.
    """

    def __init__(self, n_rovers: int, capacity: int, item_shape: tuple[int, ...]):
        self.items = np.zeros((n_rovers, capacity, *item_shape), dtype=np.float32)
        self.feedback = np.zeros((n_rovers, capacity), dtype=np.float32)
        self.capacity, self.size, self.next = capacity, 0, 0

    def add(self, items: np.ndarray, feedback: np.ndarray) -> None:
        """Append (R, n, *item_shape) items with (R, n) feedback."""
        n = items.shape[1]
        if n > self.capacity:  # only the newest entries would survive anyway
            items, feedback, n = (
                items[:, -self.capacity :],
                feedback[:, -self.capacity :],
                self.capacity,
            )
        first = min(n, self.capacity - self.next)  # slots up to the end, then from the start
        self.items[:, self.next : self.next + first] = items[:, :first]
        self.feedback[:, self.next : self.next + first] = feedback[:, :first]
        self.items[:, : n - first] = items[:, first:]
        self.feedback[:, : n - first] = feedback[:, first:]
        self.next = int((self.next + n) % self.capacity)
        self.size = min(self.size + n, self.capacity)

    def sample_index(self, rng: np.random.Generator, batch: int, rows: int = 0) -> np.ndarray:
        """(rows, batch) slots drawn uniformly (with replacement) from the entries (rows: one
        per critic; by default one per rover)."""
        return rng.integers(0, self.size, (rows or self.items.shape[0], batch))

    def sample(self, rng: np.random.Generator, batch: int) -> tuple[np.ndarray, np.ndarray]:
        """(R, batch, *item_shape) items and (R, batch) feedback, uniform per rover."""
        idx = self.sample_index(rng, batch)
        rows = np.arange(self.items.shape[0])[:, None]
        return self.items[rows, idx], self.feedback[rows, idx]

    def state(self) -> dict:
        return {
            "items": self.items,
            "feedback": self.feedback,
            "size": self.size,
            "next": self.next,
        }

    def load(self, state: dict) -> None:
        self.items[...] = state["items"]
        self.feedback[...] = state["feedback"]
        self.size, self.next = int(state["size"]), int(state["next"])


@dataclass(frozen=True)
class CriticSettings:
    aggregation: str  # "mean" | "max"
    update: str  # "regular" | "inexact"
    hidden: int
    slope: float
    lr: float
    optimizer: str
    capacity: int  # trajectories (regular) or pairs (inexact)
    batch: int
    batches: int
    step_input: bool = False  # the critic also sees t / (T - 1) (beyond the paper)
    top_k: int = 1  # max aggregation as the mean of the k largest values (1: Eq. 3)
    ensemble: int = 1  # critics per rover (beyond the paper; 1: the paper's one)
    optimism: float = 0.0  # a pair's value is mean + optimism * std over the ensemble
    output_weights: str = "fixed"  # "fixed" (the paper's unit weights) | "trained"
    target: str = "episode"  # a pair's target: its trajectory's feedback | its step's credit

    @classmethod
    def from_config(cls, cfg, aggregation: str, update: str) -> CriticSettings:
        """The settings a :class:`~physrover.learn.configs.CriticConfig` (``[critic]``) gives
        the critic of ``aggregation`` and ``update``: the replay and mini-batches of
        trajectories (regular) or of pairs (inexact)."""
        regular = update == "regular"
        return cls(
            aggregation=aggregation,
            update=update,
            hidden=cfg.critic_hidden,
            slope=cfg.leaky_slope,
            lr=cfg.critic_lr,
            optimizer=cfg.critic_optimizer,
            capacity=cfg.replay_trajectories if regular else cfg.replay_pairs,
            batch=cfg.trajectory_batch if regular else cfg.pair_batch,
            batches=cfg.trajectory_batches if regular else cfg.pair_batches,
            step_input=cfg.critic_step_input,
            top_k=cfg.critic_top_k,
            ensemble=cfg.critic_ensemble,
            optimism=cfg.critic_optimism,
            output_weights=cfg.critic_output_weights,
            target=cfg.critic_target,
        )


class FitnessCritic:
    """The fitness critics of R rovers: evaluation (Eqs. 3-4), replay and updates (6-10)."""

    def __init__(
        self,
        n_rovers: int,
        steps: int,
        pair_dim: int,
        settings: CriticSettings,
        rng: np.random.Generator,
    ):
        if settings.optimizer not in ("sgd", "adam"):
            raise ValueError(f"unknown optimizer {settings.optimizer!r}")
        # With step_input each pair gains a last input, its step's t / (T - 1) in [0, 1].
        pair_dim += int(settings.step_input)
        self.settings, self.pair_dim = settings, pair_dim
        n_critics = n_rovers * settings.ensemble  # rover-major: critic r * K + k
        if settings.output_weights not in ("fixed", "trained"):
            raise ValueError(f"unknown output weights {settings.output_weights!r}")
        trained = settings.output_weights == "trained"
        if settings.target not in ("episode", "step"):
            raise ValueError(f"unknown critic target {settings.target!r}")
        if settings.target == "step" and settings.update != "inexact":
            raise ValueError("per-step targets need inexact updates (a replay of pairs)")
        self.critics = IntermediateCritics(n_critics, pair_dim, settings.hidden, settings.slope,
                                           rng, trained)  # fmt: skip
        self.buffer_of = np.repeat(np.arange(n_rovers), settings.ensemble)  # critic -> rover
        n_params = settings.hidden * (pair_dim + 1 + int(trained)) + 1
        # Adam's first and second moments of each critic's W1T | b1 | b2, and its step count.
        self.moments = np.zeros((n_critics, 2, n_params), dtype=np.float32)
        self.adam_steps = 0
        item = (steps, pair_dim) if settings.update == "regular" else (pair_dim,)
        self.buffer = ReplayBuffer(n_rovers, settings.capacity, item)

    def inputs(self, trajectories: np.ndarray) -> np.ndarray:
        """The critic's inputs for (R, k, T, D) state-action trajectories: themselves, or
        with ``step_input`` a last column t / (T - 1) (float32) appended to every pair."""
        if not self.settings.step_input:
            return trajectories
        n_rovers, k, steps, width = trajectories.shape
        out = np.empty((n_rovers, k, steps, width + 1), dtype=np.float32)
        out[..., :width] = trajectories
        out[..., width] = np.arange(steps, dtype=np.float32) / np.float32(max(steps - 1, 1))
        return out

    def fitness(self, trajectories: np.ndarray) -> np.ndarray:
        """F(T) of (R, k, T, D) trajectories -> (R, k)."""
        trajectories = self.inputs(trajectories)
        n_rovers, k, steps, _ = trajectories.shape
        values = self.values(trajectories.reshape(n_rovers, k * steps, self.pair_dim))
        values = values.reshape(n_rovers, k, steps)
        top_k = min(self.settings.top_k, steps)
        if self.settings.aggregation == "max" and top_k > 1:  # beyond the paper: a softer max
            return np.partition(values, steps - top_k, axis=-1)[..., steps - top_k :].mean(-1)
        return aggregate(values, self.settings.aggregation)[0]

    def values(self, pairs: np.ndarray) -> np.ndarray:
        """A pair's value for (R, N, D) pairs -> (R, N): its rover's critic (Eq. 2), or the
        ensemble's ``mean + optimism * std`` (module docstring)."""
        K = self.settings.ensemble
        if K == 1:
            return self.critics(pairs)
        each = self.critics(np.repeat(pairs, K, axis=0)).reshape(pairs.shape[0], K, -1)
        value = each.mean(axis=1)
        if self.settings.optimism:
            value += np.float32(self.settings.optimism) * each.std(axis=1)
        return value

    def store(self, trajectories: np.ndarray, feedback: np.ndarray) -> None:
        """Add (R, k, T, D) trajectories with their (R, k) immediate feedback, or, with
        ``target = "step"``, each pair's own target (R, k, T)."""
        trajectories = self.inputs(trajectories)
        if self.settings.update == "regular":
            self.buffer.add(trajectories, feedback)
            return
        n_rovers, k, steps, _ = trajectories.shape
        if self.settings.target == "step":  # every pair carries its own step's credit
            if feedback.shape != (n_rovers, k, steps):
                raise ValueError(f"per-step targets must be (R, k, T) = {(n_rovers, k, steps)},"
                                 f" got {feedback.shape}")  # fmt: skip
            per_pair = feedback.reshape(n_rovers, k * steps)
        else:  # every pair carries its trajectory's feedback (Eqs. 9-10)
            per_pair = np.repeat(feedback, steps, axis=1)
        self.buffer.add(trajectories.reshape(n_rovers, k * steps, self.pair_dim), per_pair)

    def update(self, rng: np.random.Generator) -> float:
        """The generation's mini-batch updates (compiled: ``learn.kernels.critic_update``);
        returns the mean squared error seen."""
        s = self.settings
        if self.buffer.size == 0:
            return float("nan")
        # All mini-batches are drawn up front (one draw instead of one per batch); the
        # batches are independent uniform draws either way.
        index = self.buffer.sample_index(rng, s.batches * s.batch, len(self.buffer_of))
        items = self.buffer.items  # (R, C, T, D) trajectories or (R, C, D) pairs
        if items.ndim == 3:  # inexact: entries of one pair
            items = items[:, :, None, :]
        c, W1T = self.critics, self.critics.W1T()
        adam = s.optimizer == "adam"
        loss = critic_update(W1T, c.b1, c.b2, c.W2, c.slope, np.float32(s.lr), items,
                             self.buffer.feedback, self.buffer_of, index, s.batch,
                             s.aggregation == "max", adam, self.moments, self.adam_steps,
                             dims(self.pair_dim))  # fmt: skip
        c.W1[...] = np.swapaxes(W1T, 1, 2)
        if adam:
            self.adam_steps += s.batches
        return float(loss)

    def _blocks(self) -> list:
        """Where each parameter sits in a critic's flat moments ``W1T | b1 | b2 [| W2]``:
        slices (an index for b2), in the order of ``critics.params()``."""
        n_w, hidden = self.W_size, self.settings.hidden
        blocks = [slice(0, n_w), slice(n_w, n_w + hidden), n_w + hidden]
        if self.critics.W2 is not None:
            blocks.append(slice(n_w + hidden + 1, None))
        return blocks

    def _moments_by_param(self) -> tuple[list[np.ndarray], list[np.ndarray]]:
        """Adam's m and v as [W1 (N, D, H), b1 (N, H), b2 (N,)] and, with trained output
        weights, W2 (N, H), N = R x ensemble critics (the checkpoint layout)."""
        n_critics, hidden = self.moments.shape[0], self.settings.hidden
        out = []
        for which in (0, 1):
            flat = self.moments[:, which]
            blocks = [flat[:, where].copy() for where in self._blocks()]
            W1T = blocks[0].reshape(n_critics, hidden, self.pair_dim)
            blocks[0] = np.swapaxes(W1T, 1, 2).copy()
            out.append(blocks)
        return out[0], out[1]

    @property
    def W_size(self) -> int:
        return self.settings.hidden * self.pair_dim

    def state(self) -> dict:
        m, v = self._moments_by_param()
        return {
            "params": [p.copy() for p in self.critics.params()],
            "adam_m": m,
            "adam_v": v,
            "adam_t": self.adam_steps,
            "buffer": self.buffer.state(),
        }

    def load(self, state: dict) -> None:
        for p, saved in zip(self.critics.params(), state["params"], strict=True):
            p[...] = saved
        n_critics = self.moments.shape[0]
        for which, key in enumerate(("adam_m", "adam_v")):
            saved = [np.asarray(a, dtype=np.float32) for a in state[key]]
            saved[0] = np.swapaxes(saved[0], 1, 2).reshape(n_critics, self.W_size)
            flat = self.moments[:, which]
            for where, values in zip(self._blocks(), saved, strict=True):
                flat[:, where] = values
        self.adam_steps = int(state["adam_t"])
        self.buffer.load(state["buffer"])
