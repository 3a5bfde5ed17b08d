"""Trajectory critics (beyond the paper): fitness critics that value a rover's whole episode.

The paper's critic values one (observation, action) pair at a time and aggregates by max
(Eq. 3); it cannot see that a rover waited for its teammates or arrived with them. These
critics read the whole trajectory T = (x_0 ... x_{T-1}), x_t = (s_t, a_t) in R^D, of a
rover's episode, one network per rover (batched over rovers: every weight has a leading
rover axis R), in torch:

- ``gru`` readout ``final``: a GRU over the steps, ``h_t = GRU(x_t, h_{t-1})``, h_{-1} = 0,
  hidden size H; ``F(T) = w . h_{T-1} + b``;
- ``gru`` readout ``sum``: ``F(T) = sum_t (w . h_t + b)``, a sum of per-step values each
  conditioned on the history (the lab's later GRU critics had both readouts);
- ``attention``: each pair embedded, ``e_t = relu(x_t W_e + b_e) + p_t`` (p_t a learned
  embedding of step t), one head of scaled dot-product self-attention over the steps,
  ``a = softmax(Q K^T / sqrt(H)) V`` with ``Q, K, V = e W_q, e W_k, e W_v``, mean-pooled
  over the steps, then ``F(T) = w . relu(mean_t a_t W_o + b_o) + b``.

Each is trained once per generation, after evolution (Algorithm 1), on ``batches``
mini-batches of ``batch`` trajectories drawn uniformly with replacement from the rover's
replay buffer of its last ``capacity`` trajectories with their immediate feedback f (D by
default; the paper's buffer of the regular update), with Adam (learning rate ``lr``), on
one of two losses, averaged over rovers:

- ``mse``: ``mean_k (F(T_k) - f_k)^2``, the value (the paper's loss, Eq. 6);
- ``rank`` (an "alignment" loss): ``mean over pairs (k, l) with f_k > f_l of
  softplus(-(F(T_k) - F(T_l)))``, a logistic loss on the order of each pair of
  trajectories (ties carry no pair). The CCEA selects on the order of its policies'
  fitness, not on its value, so this loss asks the critic for exactly that.

All draws are seeded: initial weights from the run's critic-initialisation generator
(numpy; PyTorch's default uniform(-1/sqrt(fan_in), 1/sqrt(fan_in)) bounds), mini-batches
from its critic generator. Everything a generation changes (weights, Adam's moments and
step, the buffer) is in :meth:`TrajectoryCritic.state`, so a resumed run is bit-identical.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from torch.nn import functional

from physrover.learn.critics import ReplayBuffer

MODELS = ("gru", "attention")
READOUTS = ("final", "sum")
LOSSES = ("mse", "rank")


@dataclass(frozen=True)
class TrajectorySettings:
    model: str  # "gru" | "attention"
    readout: str  # gru: "final" | "sum"
    loss: str  # "mse" | "rank"
    hidden: int
    lr: float
    capacity: int  # trajectories per rover
    batch: int
    batches: int


def _uniform(rng: np.random.Generator, fan_in: int, shape: tuple[int, ...]) -> torch.Tensor:
    bound = 1.0 / np.sqrt(fan_in)
    return torch.from_numpy(rng.uniform(-bound, bound, shape).astype(np.float32))


def init_params(model: str, n_rovers: int, steps: int, pair_dim: int, hidden: int,
                rng: np.random.Generator) -> dict[str, torch.Tensor]:  # fmt: skip
    """The R networks' parameters, each with a leading rover axis, float32."""
    R, D, H = n_rovers, pair_dim, hidden
    if model == "gru":  # gates in the order reset | update | candidate, as torch.nn.GRU
        names = {"W_x": (D, 3 * H), "b_x": (3 * H,), "W_h": (H, 3 * H), "b_h": (3 * H,),
                 "w": (H, 1), "b": (1,)}  # fmt: skip
        fans = {"W_x": H, "b_x": H, "W_h": H, "b_h": H, "w": H, "b": H}
    elif model == "attention":
        names = {"W_e": (D, H), "b_e": (H,), "pos": (steps, H), "W_q": (H, H), "W_k": (H, H),
                 "W_v": (H, H), "W_o": (H, H), "b_o": (H,), "w": (H, 1), "b": (1,)}  # fmt: skip
        fans = {"W_e": D, "b_e": D, "pos": H, "W_q": H, "W_k": H, "W_v": H, "W_o": H,
                "b_o": H, "w": H, "b": H}  # fmt: skip
    else:
        raise ValueError(f"unknown trajectory critic {model!r} (known: {', '.join(MODELS)})")
    return {name: _uniform(rng, fans[name], (R, *shape)) for name, shape in names.items()}


def gru_values(p: dict[str, torch.Tensor], x: torch.Tensor, readout: str) -> torch.Tensor:
    """F for (R, N, T, D) trajectories -> (R, N) (module docstring, ``gru``)."""
    R, N, T, _ = x.shape
    H = p["W_h"].shape[1]
    gx = torch.einsum("rntd,rdg->rntg", x, p["W_x"]) + p["b_x"][:, None, None, :]
    # One tensor per step (unbind's gradient is one stack; indexing gx[:, :, t] in the loop
    # would give each step's gradient gx's full size).
    gx_steps = gx.unbind(dim=2)
    h = x.new_zeros((R, N, H))
    out = []
    for t in range(T):
        gh = torch.baddbmm(p["b_h"][:, None, :], h, p["W_h"])  # (R, N, 3H)
        x_rz, x_n = gx_steps[t].split((2 * H, H), dim=-1)
        h_rz, h_n = gh.split((2 * H, H), dim=-1)
        r, z = torch.sigmoid(x_rz + h_rz).chunk(2, dim=-1)
        n = torch.tanh(x_n + r * h_n)
        h = n + z * (h - n)  # (1 - z) n + z h
        if readout == "sum":
            out.append(h)
    if readout == "final":
        return (torch.bmm(h, p["w"]) + p["b"][:, None, :])[..., 0]
    states = torch.stack(out, dim=2)  # (R, N, T, H)
    per_step = torch.einsum("rnth,rho->rnto", states, p["w"])[..., 0] + p["b"][:, None, :]
    return per_step.sum(-1)


def attention_values(p: dict[str, torch.Tensor], x: torch.Tensor) -> torch.Tensor:
    """F for (R, N, T, D) trajectories -> (R, N) (module docstring, ``attention``)."""
    H = p["W_q"].shape[-1]
    e = torch.relu(torch.einsum("rntd,rdh->rnth", x, p["W_e"]) + p["b_e"][:, None, None, :])
    e = e + p["pos"][:, None, : x.shape[2], :]
    q, k, v = (torch.einsum("rnth,rhg->rntg", e, p[w]) for w in ("W_q", "W_k", "W_v"))
    weights = torch.softmax(q @ k.transpose(-1, -2) / np.sqrt(H), dim=-1)  # (R, N, T, T)
    pooled = (weights @ v).mean(dim=2)  # (R, N, H)
    hidden = torch.relu(torch.bmm(pooled, p["W_o"]) + p["b_o"][:, None, :])
    return (torch.bmm(hidden, p["w"]) + p["b"][:, None, :])[..., 0]


def rank_loss(values: torch.Tensor, feedback: torch.Tensor) -> torch.Tensor:
    """The mean of softplus(-(F_k - F_l)) over the pairs (k, l) of each rover's mini-batch
    with f_k > f_l; (R, B) values and feedback. Zero where no pair is ordered."""
    ordered = (feedback[:, :, None] > feedback[:, None, :]).to(values.dtype)  # (R, B, B)
    margins = values[:, :, None] - values[:, None, :]
    pairs = ordered.sum()
    if pairs == 0:
        return (values * 0.0).sum()
    return (functional.softplus(-margins) * ordered).sum() / pairs


class TrajectoryCritic:
    """R trajectory critics: fitness of whole trajectories, replay and updates."""

    def __init__(self, n_rovers: int, steps: int, pair_dim: int, settings: TrajectorySettings,
                 rng: np.random.Generator):  # fmt: skip
        if settings.readout not in READOUTS:
            raise ValueError(f"unknown readout {settings.readout!r}")
        if settings.loss not in LOSSES:
            raise ValueError(f"unknown loss {settings.loss!r}")
        self.settings = settings
        self.params = init_params(settings.model, n_rovers, steps, pair_dim, settings.hidden,
                                  rng)  # fmt: skip
        for tensor in self.params.values():
            tensor.requires_grad_(True)
        self.optimizer = torch.optim.Adam(list(self.params.values()), lr=settings.lr)
        self.buffer = ReplayBuffer(n_rovers, settings.capacity, (steps, pair_dim))

    def values(self, trajectories: torch.Tensor) -> torch.Tensor:
        """F for (R, N, T, D) trajectories (a float32 tensor) -> (R, N), differentiable."""
        if self.settings.model == "gru":
            return gru_values(self.params, trajectories, self.settings.readout)
        return attention_values(self.params, trajectories)

    def fitness(self, trajectories: np.ndarray) -> np.ndarray:
        """F(T) of (R, k, T, D) trajectories -> (R, k) float32."""
        with torch.no_grad():
            return self.values(torch.from_numpy(np.ascontiguousarray(trajectories))).numpy()

    def store(self, trajectories: np.ndarray, feedback: np.ndarray) -> None:
        """Add (R, k, T, D) trajectories with their (R, k) immediate feedback."""
        self.buffer.add(trajectories, feedback)

    def loss(self, values: torch.Tensor, feedback: torch.Tensor) -> torch.Tensor:
        if self.settings.loss == "mse":
            return ((values - feedback) ** 2).mean()
        return rank_loss(values, feedback)

    def update(self, rng: np.random.Generator) -> float:
        """The generation's ``batches`` Adam steps; returns the mean loss seen (NaN before
        the buffer holds anything)."""
        s = self.settings
        if self.buffer.size == 0:
            return float("nan")
        index = self.buffer.sample_index(rng, s.batches * s.batch)  # one draw, as the paper's
        rows = np.arange(index.shape[0])[:, None]
        losses = []
        for b in range(s.batches):
            idx = index[:, b * s.batch : (b + 1) * s.batch]
            x = torch.from_numpy(self.buffer.items[rows, idx])
            f = torch.from_numpy(self.buffer.feedback[rows, idx])
            self.optimizer.zero_grad(set_to_none=True)
            loss = self.loss(self.values(x), f)
            loss.backward()
            self.optimizer.step()
            losses.append(float(loss.detach()))
        return float(np.mean(losses))

    def state(self) -> dict:
        """Weights, Adam's moments and step per parameter (in the order of ``params``) and the
        buffer, as numpy arrays."""
        params = list(self.params.values())
        adam = [self.optimizer.state.get(p) for p in params]  # None before the first step

        def moment(key: str) -> list[np.ndarray]:
            return [state[key].numpy().copy() if state else np.zeros(p.shape, np.float32)
                    for state, p in zip(adam, params, strict=True)]  # fmt: skip

        return {
            "params": {k: v.detach().numpy().copy() for k, v in self.params.items()},
            "adam_m": moment("exp_avg"),
            "adam_v": moment("exp_avg_sq"),
            "adam_t": int(adam[0]["step"]) if adam[0] else 0,
            "buffer": self.buffer.state(),
        }

    def load(self, state: dict) -> None:
        with torch.no_grad():
            for name, tensor in self.params.items():
                tensor.copy_(torch.from_numpy(np.asarray(state["params"][name], np.float32)))
        steps = int(state["adam_t"])
        if steps:
            for i, p in enumerate(self.params.values()):
                self.optimizer.state[p] = {
                    "step": torch.tensor(float(steps)),
                    "exp_avg": torch.from_numpy(np.array(state["adam_m"][i], np.float32)),
                    "exp_avg_sq": torch.from_numpy(np.array(state["adam_v"][i], np.float32)),
                }
        self.buffer.load(state["buffer"])
