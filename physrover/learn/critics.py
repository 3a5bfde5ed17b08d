"""Fitness critics (paper Section 3): intermediate critics, aggregation, updates, replay.

Intermediate critic of rover i (Eq. 2), for a state-action pair x = (s, a) in R^10:

    C(x; w) = sum_h lrelu(x . W1[:, h] + b1[h]) + b2

a 10 -> 80 -> 1 network with leaky-ReLU hidden units (slope 0.01) whose hidden-to-output
weights are fixed to 1; only W1, b1 and the output bias b2 train (paper Section 4.2). The
critics of all R rovers are stacked and evaluated and trained together.

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
Adam on the same gradient instead. Gradients are written out by hand (tested against
finite differences): for weights ``u_n`` on pairs x_n,
``sum_n u_n grad C(x_n) = (X^T (u * g), sum_n u_n g_n, sum_n u_n)`` with
``g = lrelu'(X W1 + b1)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from physrover.engine import resolve

PAIR_DIM = 10  # 8 observation + 2 action


class IntermediateCritics:
    """R critics ``C(x) = sum_h lrelu(x W1 + b1)_h + b2``, stacked; float32 parameters.

    ``engine`` chooses how :meth:`__call__` evaluates them: the compiled kernel (``"numba"``)
    or the numpy code of this class (``"numpy"``); default from ``PHYSROVER_ENGINE``.
    """

    def __init__(
        self,
        n_critics: int,
        hidden: int,
        slope: float,
        rng: np.random.Generator,
        engine: str | None = None,
    ):
        self.engine = resolve(engine)
        bound = 1.0 / np.sqrt(PAIR_DIM)  # PyTorch's default initialisation of a linear layer
        self.W1 = rng.uniform(-bound, bound, (n_critics, PAIR_DIM, hidden)).astype(np.float32)
        self.b1 = rng.uniform(-bound, bound, (n_critics, hidden)).astype(np.float32)
        self.b2 = np.zeros(n_critics, dtype=np.float32)
        self.slope = np.float32(slope)

    def params(self) -> list[np.ndarray]:
        return [self.W1, self.b1, self.b2]

    def _hidden(self, x: np.ndarray) -> np.ndarray:
        z = x @ self.W1  # (R, N, H) pre-activations
        z += self.b1[:, None, :]
        return z

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """C for (R, N, 10) pairs -> (R, N) float32."""
        if self.engine == "numpy":
            return self._output(x, self._hidden(x))
        from physrover.learn.kernels import critic_values

        # The kernel keeps pairs in its innermost loop: pairs (R, 10, N), weights (R, H, 10).
        xT = np.ascontiguousarray(np.swapaxes(x, 1, 2), dtype=np.float32)
        out = np.empty(x.shape[:2], dtype=np.float32)
        critic_values(self.W1T(), self.b1, self.b2, self.slope, xT, out)
        return out

    def W1T(self) -> np.ndarray:
        """(R, H, 10) contiguous copy of W1, the layout of the compiled kernels."""
        return np.ascontiguousarray(np.swapaxes(self.W1, 1, 2))

    def _output(self, x: np.ndarray, z: np.ndarray) -> np.ndarray:
        """C from the pairs and their pre-activations (``z`` is overwritten).

        ``sum_h lrelu(z_h) = slope * sum_h z_h + (1 - slope) * sum_h relu(z_h)``, and the
        linear sum is ``x . sum_h W1[:, h] + sum_h b1[h]``: one pass over z instead of three.
        """
        linear = (x @ self.W1.sum(-1)[..., None])[..., 0] + self.b1.sum(-1)[:, None]
        relu_sum = np.maximum(z, 0.0, out=z).sum(-1)
        return self.slope * linear + (1 - self.slope) * relu_sum + self.b2[:, None]

    def values_and_slopes(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """C(x) (R, N) and lrelu'(z) (R, N, H) from one forward pass."""
        z = self._hidden(x)
        g = (z > 0).astype(np.float32)  # lrelu'(z) = slope + (1 - slope) [z > 0]
        g *= 1 - self.slope
        g += self.slope
        return self._output(x, z), g

    def weighted_grad(self, x: np.ndarray, u: np.ndarray, g: np.ndarray | None = None):
        """``sum_n u_n grad_w C(x_n)`` for (R, N, 10) pairs and (R, N) weights, per critic;
        ``g`` (from :meth:`values_and_slopes`) is reused, and overwritten, when given."""
        if g is None:
            g = self.values_and_slopes(x)[1]
        g *= u[..., None].astype(np.float32)  # (R, N, H): u_n dC(x_n)/db1
        return [np.swapaxes(x, 1, 2) @ g, g.sum(1), u.sum(1)]


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

    def sample_index(self, rng: np.random.Generator, batch: int) -> np.ndarray:
        """(R, batch) slots drawn uniformly (with replacement) from each rover's entries."""
        return rng.integers(0, self.size, (self.items.shape[0], batch))

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


class Optimizer:
    """Ascent steps ``w += lr * d`` (plain, Eq. 6) or Adam on the descent gradient ``-d``."""

    def __init__(self, params: list[np.ndarray], lr: float, kind: str = "sgd"):
        self.params, self.lr, self.kind = params, lr, kind
        self.t = 0
        self.m = [np.zeros_like(p) for p in params]
        self.v = [np.zeros_like(p) for p in params]

    def step(self, directions: list[np.ndarray]) -> None:
        if self.kind == "sgd":
            for p, d in zip(self.params, directions, strict=True):
                p += self.lr * d
            return
        b1, b2, eps = 0.9, 0.999, 1e-8
        self.t += 1
        for p, d, m, v in zip(self.params, directions, self.m, self.v, strict=True):
            m *= b1
            m += (1 - b1) * d
            v *= b2
            v += (1 - b2) * d * d
            p += self.lr * (m / (1 - b1**self.t)) / (np.sqrt(v / (1 - b2**self.t)) + eps)


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


class FitnessCritic:
    """The fitness critics of R rovers: evaluation (Eqs. 3-4), replay and updates (6-10)."""

    def __init__(
        self,
        n_rovers: int,
        steps: int,
        settings: CriticSettings,
        rng: np.random.Generator,
        engine: str | None = None,
    ):
        self.settings = settings
        self.critics = IntermediateCritics(
            n_rovers, settings.hidden, settings.slope, rng, engine=engine
        )
        self.optimizer = Optimizer(self.critics.params(), settings.lr, settings.optimizer)
        item = (steps, PAIR_DIM) if settings.update == "regular" else (PAIR_DIM,)
        self.buffer = ReplayBuffer(n_rovers, settings.capacity, item)

    def fitness(self, trajectories: np.ndarray) -> np.ndarray:
        """F(T) of (R, k, T, 10) trajectories -> (R, k)."""
        n_rovers, k, steps, _ = trajectories.shape
        values = self.critics(trajectories.reshape(n_rovers, k * steps, PAIR_DIM))
        return aggregate(values.reshape(n_rovers, k, steps), self.settings.aggregation)[0]

    def store(self, trajectories: np.ndarray, feedback: np.ndarray) -> None:
        """Add (R, k, T, 10) trajectories with their (R, k) immediate feedback."""
        if self.settings.update == "regular":
            self.buffer.add(trajectories, feedback)
        else:  # every pair carries its trajectory's feedback
            n_rovers, k, steps, _ = trajectories.shape
            self.buffer.add(
                trajectories.reshape(n_rovers, k * steps, PAIR_DIM),
                np.repeat(feedback, steps, axis=1),
            )

    def errors_and_directions(
        self, items: np.ndarray, feedback: np.ndarray
    ) -> tuple[np.ndarray, list[np.ndarray]]:
        """delta (R, B) and the update direction ``sum_k delta_k grad`` (Eq. 7 or Eq. 9)."""
        if self.settings.update == "inexact":
            values, g = self.critics.values_and_slopes(items)
            delta = feedback - values  # Eq. 10
            return delta, self.critics.weighted_grad(items, delta, g)
        n_rovers, batch, steps, _ = items.shape
        pairs = items.reshape(n_rovers, batch * steps, PAIR_DIM)
        values, g = self.critics.values_and_slopes(pairs)
        F, dF = aggregate(values.reshape(n_rovers, batch, steps), self.settings.aggregation)
        delta = feedback - F  # Eq. 8
        u = (delta[..., None] * dF).reshape(n_rovers, batch * steps)
        return delta, self.critics.weighted_grad(pairs, u, g)

    def update(self, rng: np.random.Generator) -> float:
        """The generation's mini-batch updates; returns the mean squared error seen."""
        s = self.settings
        if self.buffer.size == 0:
            return float("nan")
        # All mini-batches are drawn up front (one draw instead of one per batch); the
        # batches are independent uniform draws either way, and both engines draw the same.
        if self.critics.engine == "numba" and s.optimizer == "sgd":
            from physrover.learn.kernels import critic_sgd

            index = self.buffer.sample_index(rng, s.batches * s.batch)
            items = self.buffer.items  # (R, C, T, 10) trajectories or (R, C, 10) pairs
            if items.ndim == 3:  # inexact: entries of one pair
                items = items[:, :, None, :]
            c, W1T = self.critics, self.critics.W1T()
            loss = critic_sgd(
                W1T,
                c.b1,
                c.b2,
                c.slope,
                np.float32(s.lr),
                items,
                self.buffer.feedback,
                index,
                s.batch,
                s.aggregation == "max",
            )
            c.W1[...] = np.swapaxes(W1T, 1, 2)
            return float(loss)
        all_items, all_feedback = self.buffer.sample(rng, s.batches * s.batch)
        losses = []
        for b in range(s.batches):
            part = slice(b * s.batch, (b + 1) * s.batch)
            items, feedback = all_items[:, part], all_feedback[:, part]
            delta, directions = self.errors_and_directions(items, feedback)
            self.optimizer.step(directions)
            losses.append(np.mean(delta**2))
        return float(np.mean(losses))

    def state(self) -> dict:
        opt = self.optimizer
        return {
            "params": [p.copy() for p in self.critics.params()],
            "adam_m": opt.m,
            "adam_v": opt.v,
            "adam_t": opt.t,
            "buffer": self.buffer.state(),
        }

    def load(self, state: dict) -> None:
        for p, saved in zip(self.critics.params(), state["params"], strict=True):
            p[...] = saved
        for mine, saved in zip(
            self.optimizer.m + self.optimizer.v, state["adam_m"] + state["adam_v"], strict=True
        ):
            mine[...] = saved
        self.optimizer.t = int(state["adam_t"])
        self.buffer.load(state["buffer"])
