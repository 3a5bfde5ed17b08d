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
- ``recurrent-max``: the paper's max critic with a memory: each pair x_t is valued by the
  paper's intermediate critic (Eq. 2: ``units`` leaky-ReLU units, output weights fixed
  to 1) on ``z_t = (x_t, h_{t-1})``, the pair and a GRU's summary of the steps before it,
  ``v_t = sum_u lrelu(z_t . W1[:, u] + b1[u]) + b2``, and ``F(T) = max_t v_t`` (Eq. 3).
  With ``mse`` every step's value is trained on its trajectory's feedback, the paper's
  inexact update (Eqs. 9-10) with the history as extra inputs, so values of pairs (and
  histories) never seen keep their initial, optimistic size: the paper's critic is the
  case of a GRU that always outputs 0;
- ``attention``: each pair embedded, ``e_t = relu(x_t W_e + b_e) + p_t`` (p_t a learned
  embedding of step t), one head of scaled dot-product self-attention over the steps,
  ``a = softmax(Q K^T / sqrt(H)) V`` with ``Q, K, V = e W_q, e W_k, e W_v``, mean-pooled
  over the steps, then ``F(T) = w . relu(mean_t a_t W_o + b_o) + b``.

Each is trained once per generation, after evolution (Algorithm 1), on ``batches``
mini-batches of ``batch`` trajectories drawn uniformly with replacement from the rover's
replay buffer of its last ``capacity`` trajectories with their immediate feedback f (D by
default; the paper's buffer of the regular update). ``recurrent-max`` learns as the
paper's critic does: plain gradient steps (``critic_optimizer``, ``critic_lr``) on half
the squared errors of every step's value summed over the mini-batch (Eqs. 9-10; with Adam
at ``trajectory_lr`` its history weights moved so fast that the values became noise and
no team captured a POI at n_req 5). The others use Adam (``trajectory_lr``) on one of two
losses, averaged over rovers:

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

MODELS = ("gru", "recurrent-max", "attention")
READOUTS = ("final", "sum", "max")
LOSSES = ("mse", "rank")


@dataclass(frozen=True)
class TrajectorySettings:
    model: str  # "gru" | "attention"
    readout: str  # gru: "final" | "sum"; recurrent-max: "max"
    loss: str  # "mse" | "rank"
    hidden: int
    lr: float
    capacity: int  # trajectories per rover
    batch: int
    batches: int
    units: int = 80  # recurrent-max: the intermediate critic's hidden units (critic_hidden)
    slope: float = 0.01  # recurrent-max: its leaky-ReLU slope (leaky_slope)
    optimizer: str = "adam"  # "adam" | "sgd" (plain gradient steps)

    @classmethod
    def from_config(cls, cfg, model: str, readout: str) -> TrajectorySettings:
        """The settings a :class:`~physrover.learn.configs.TrajectoryCriticConfig`
        (``[trajectory_critic]``) gives ``model`` read out by ``readout``; the recurrent max
        critic learns as the paper's critic (``critic_lr``, ``critic_optimizer``)."""
        recurrent_max = model == "recurrent-max"
        return cls(
            model=model,
            readout=readout,
            loss=cfg.trajectory_loss,
            hidden=cfg.trajectory_hidden,
            lr=cfg.critic_lr if recurrent_max else cfg.trajectory_lr,
            capacity=cfg.replay_trajectories,
            batch=cfg.trajectory_batch,
            batches=cfg.trajectory_batches,
            units=cfg.critic_hidden,
            slope=cfg.leaky_slope,
            optimizer=cfg.critic_optimizer if recurrent_max else "adam",
        )


def _uniform(rng: np.random.Generator, fan_in: int, shape: tuple[int, ...]) -> torch.Tensor:
    bound = 1.0 / np.sqrt(fan_in)
    return torch.from_numpy(rng.uniform(-bound, bound, shape).astype(np.float32))


def init_params(model: str, n_rovers: int, steps: int, pair_dim: int, hidden: int,
                rng: np.random.Generator, units: int = 80) -> dict[str, torch.Tensor]:  # fmt: skip
    """The R networks' parameters, each with a leading rover axis, float32."""
    R, D, H = n_rovers, pair_dim, hidden
    if model in ("gru", "recurrent-max"):  # gates reset | update | candidate (torch.nn.GRU)
        names = {"W_x": (D, 3 * H), "b_x": (3 * H,), "W_h": (H, 3 * H), "b_h": (3 * H,)}
        fans = {"W_x": H, "b_x": H, "W_h": H, "b_h": H, "w": H, "b": H}
        if model == "gru":
            names.update(w=(H, 1), b=(1,))
        else:  # the paper's intermediate critic on (x_t, h_{t-1}); b2 starts at 0 as Eq. 2's
            names.update(W1=(D + H, units), b1=(units,))
            fans.update(W1=D, b1=D)  # the paper's critic's bounds (Eq. 2 on the pair)
    elif model == "attention":
        names = {"W_e": (D, H), "b_e": (H,), "pos": (steps, H), "W_q": (H, H), "W_k": (H, H),
                 "W_v": (H, H), "W_o": (H, H), "b_o": (H,), "w": (H, 1), "b": (1,)}  # fmt: skip
        fans = {"W_e": D, "b_e": D, "pos": H, "W_q": H, "W_k": H, "W_v": H, "W_o": H,
                "b_o": H, "w": H, "b": H}  # fmt: skip
    else:
        raise ValueError(f"unknown trajectory critic {model!r} (known: {', '.join(MODELS)})")
    params = {name: _uniform(rng, fans[name], (R, *shape)) for name, shape in names.items()}
    if model == "recurrent-max":  # starts as the paper's critic: the history's weights at 0
        params["W1"][:, D:] = 0.0
        params["b2"] = torch.zeros((R, 1))
    return params


def gru_states(p: dict[str, torch.Tensor], x: torch.Tensor, keep: bool) -> list:
    """The GRU over (R, N, T, D) trajectories: [h_0 ... h_{T-1}] (each (R, N, H)) if
    ``keep``, else [h_{T-1}]."""
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
        if keep:
            out.append(h)
    return out if keep else [h]


def gru_values(p: dict[str, torch.Tensor], x: torch.Tensor, readout: str) -> torch.Tensor:
    """F for (R, N, T, D) trajectories -> (R, N) (module docstring, ``gru``)."""
    if readout == "final":
        (h,) = gru_states(p, x, keep=False)
        return (torch.bmm(h, p["w"]) + p["b"][:, None, :])[..., 0]
    states = torch.stack(gru_states(p, x, keep=True), dim=2)  # (R, N, T, H)
    per_step = torch.einsum("rnth,rho->rnto", states, p["w"])[..., 0] + p["b"][:, None, :]
    return per_step.sum(-1)


def recurrent_max_steps(p: dict[str, torch.Tensor], x: torch.Tensor,
                        slope: float) -> torch.Tensor:  # fmt: skip
    """Every step's value v_t for (R, N, T, D) trajectories -> (R, N, T) (module
    docstring, ``recurrent-max``): Eq. 2 on (x_t, h_{t-1}), h_{-1} = 0."""
    states = gru_states(p, x, keep=True)
    before = torch.stack([torch.zeros_like(states[0]), *states[:-1]], dim=2)  # h_{t-1}
    z = torch.cat([x, before], dim=-1)
    pre = torch.einsum("rntd,rdu->rntu", z, p["W1"]) + p["b1"][:, None, None, :]
    return functional.leaky_relu(pre, slope).sum(-1) + p["b2"][:, None, :]


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
                                  rng, settings.units)  # fmt: skip
        for tensor in self.params.values():
            tensor.requires_grad_(True)
        if settings.optimizer not in ("adam", "sgd"):
            raise ValueError(f"unknown optimizer {settings.optimizer!r}")
        make = torch.optim.Adam if settings.optimizer == "adam" else torch.optim.SGD
        self.optimizer = make(list(self.params.values()), lr=settings.lr)
        self.buffer = ReplayBuffer(n_rovers, settings.capacity, (steps, pair_dim))

    def values(self, trajectories: torch.Tensor) -> torch.Tensor:
        """F for (R, N, T, D) trajectories (a float32 tensor) -> (R, N), differentiable."""
        if self.settings.model == "gru":
            return gru_values(self.params, trajectories, self.settings.readout)
        if self.settings.model == "recurrent-max":
            return recurrent_max_steps(self.params, trajectories, self.settings.slope).amax(-1)
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
        """The generation's ``batches`` optimizer steps; returns the mean loss seen (NaN
        before the buffer holds anything)."""
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
            if self.settings.model == "recurrent-max":  # every step's value, Eqs. 9-10
                steps = recurrent_max_steps(self.params, x, s.slope)  # (R, B, T)
                loss = 0.5 * ((steps - f[..., None]) ** 2).sum()
            else:
                loss = self.loss(self.values(x), f)
            loss.backward()
            self.optimizer.step()
            losses.append(float(loss.detach()))
        return float(np.mean(losses))

    def state(self) -> dict:
        """Weights, Adam's moments and step per parameter (in the order of ``params``) and the
        buffer, as numpy arrays."""
        params = list(self.params.values())
        adam = [self.optimizer.state.get(p) or None for p in params]  # before a step, or SGD
        adam = [None if self.settings.optimizer == "sgd" else a for a in adam]

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
