"""The one implementation of the policies' forward pass (paper Section 4.2): an
``n_in -> hidden -> 2`` network with a ReLU hidden layer (or tanh, the lab's:
``tanh_hidden``, ``[learn] activation``) and a tanh output "to simulate motor
saturation", compiled, for a team at a time (:func:`forward_team`, which the whole-episode
rollout calls every step) or a batch of teams (:func:`policy_forward`, the per-step path).

Arithmetic is float32 with the sums in a fixed order: each hidden unit adds ``b1`` then the
inputs in order (the loop over units vectorises, the inputs unrolled); each output adds its
hidden units in four interleaved partial sums (units ``u = 0, 1, 2, 3 (mod 4)``, the units
past the last multiple of 4 in the first, then ``(s0 + s1) + (s2 + s3)``), then ``b2``.

The output's tanh is :func:`tanh32`, our own: libm's float32 tanh costs ~20 ns a call and
does not vectorise, and numpy's (4x faster) cannot be called from compiled code and differs
between CPUs (its AVX2/AVX-512 code and its libm fallback round differently). :func:`tanh32`
is computed in float64 and rounded once, so it is the correctly rounded tanh of its float32
argument (checked on 6 million arguments; the float64 error ~1e-15 could only misround an
argument whose tanh lies within 1e-15 relative of a rounding boundary), on every machine.
"""

from __future__ import annotations

import math

import numpy as np

from physrover.core.compiled import jit


@jit
def tanh32(x):
    """tanh of a float32 ``x``, correctly rounded to float32 (module docstring).

    ``tanh|x| = expm1(2|x|) / (expm1(2|x|) + 2)`` in float64, the sign copied from ``x``
    (so ``tanh(-0) = -0``), NaN kept. ``expm1(y)``, ``0 <= y <= 20`` (|x| is capped at 10,
    where tanh rounds to 1), reduces ``y = k ln2 + r`` with ``|r| <= ln2 / 2`` and sums
    ``expm1(r)``'s Taylor series to ``r^12 / 12!`` (truncation below 5e-16 relative):
    ``expm1(y) = 2^k expm1(r) + (2^k - 1)``. Float operations only, no branches: loops of it
    vectorise.
    """
    a = min(abs(np.float64(x)), 10.0)
    y = 2.0 * a
    k = np.floor(y * 1.4426950408889634 + 0.5)  # round(y / ln2), 0 .. 29
    r = (y - k * 0.6931471803691238) - k * 1.9082149292705877e-10  # ln2 split hi + lo
    q = r * (1.0 + r * (1.0 / 2 + r * (1.0 / 6 + r * (1.0 / 24 + r * (1.0 / 120 + r * (
        1.0 / 720 + r * (1.0 / 5040 + r * (1.0 / 40320 + r * (1.0 / 362880 + r * (
            1.0 / 3628800 + r * (1.0 / 39916800 + r * (1.0 / 479001600))))))))))))  # fmt: skip
    # 2^k from k's binary digits, in float arithmetic (integer conversions do not vectorise)
    p = 1.0
    for bit in (16.0, 8.0, 4.0, 2.0, 1.0):
        if k >= bit:
            p *= 2.0**bit
            k -= bit
    em1 = p * q + (p - 1.0)
    t = em1 / (em1 + 2.0)
    return np.float32(math.copysign(t, x)) if a == a else np.float32(x)


@jit
def forward_team(genomes, hidden, obs, out, dims, h, tanh_hidden=False):
    """Actions ``out`` (R, 2) float32 of one team's R rovers: rover r plays genome
    ``genomes[r]`` (P,) on ``obs[r]`` (n_in,), laid out as :class:`PolicyLayout` says
    (``W1 (n_in x H) | b1 | W2 (H x 2) | b2``). ``dims``: n_in zeros
    (:func:`physrover.core.compiled.dims`); ``h`` (H,) float32 scratch for the hidden layer,
    ReLU, or :func:`tanh32` if ``tanh_hidden``.
    """
    n_in = len(dims)
    n_rovers = genomes.shape[0]
    b1_at = n_in * hidden
    w2_at = b1_at + hidden
    b2_at = w2_at + hidden * 2
    whole = hidden - hidden % 4  # units in the interleaved sums; the rest are added after
    for r in range(n_rovers):
        g = genomes[r]
        x = obs[r]
        for u in range(hidden):  # vectorised over units, the inputs unrolled
            a = g[b1_at + u]
            for i in range(n_in):
                a += x[i] * g[i * hidden + u]
            h[u] = tanh32(a) if tanh_hidden else max(a, np.float32(0.0))
        p0 = p1 = p2 = p3 = q0 = q1 = q2 = q3 = np.float32(0.0)
        for u in range(0, whole, 4):
            w = w2_at + 2 * u
            p0 += h[u] * g[w]
            q0 += h[u] * g[w + 1]
            p1 += h[u + 1] * g[w + 2]
            q1 += h[u + 1] * g[w + 3]
            p2 += h[u + 2] * g[w + 4]
            q2 += h[u + 2] * g[w + 5]
            p3 += h[u + 3] * g[w + 6]
            q3 += h[u + 3] * g[w + 7]
        for u in range(whole, hidden):
            p0 += h[u] * g[w2_at + 2 * u]
            q0 += h[u] * g[w2_at + 2 * u + 1]
        out[r, 0] = g[b2_at] + ((p0 + p1) + (p2 + p3))
        out[r, 1] = g[b2_at + 1] + ((q0 + q1) + (q2 + q3))
    flat = out.reshape(2 * n_rovers)  # the 2R values in one contiguous loop: it vectorises
    for j in range(2 * n_rovers):
        flat[j] = tanh32(flat[j])


@jit
def pick_forward(genomes, hidden, n_choices, obs, out, tanh_hidden=False):
    """The commands ``out`` (E, R, 2) float32 of picking agents (``action = "pick"``): agent
    r of team e plays genome ``genomes[e, r]`` (``W1 (n_in x H) | b1 | W2 (H x n_choices) |
    b2``) on ``obs[e, r]`` (n_in,) float32, a ReLU (or tanh) hidden layer, then ``n_choices`` linear
    outputs (each ``b2`` plus its hidden units in order); the largest (the first of ties; the
    lab's softmax and argmax) picks j, written as the centre of pick bin j of [-1, 1],
    ``-1 + (2 j + 1) / n_choices`` (:func:`physrover.domain.agents.roles.pick_moves`), and 0."""
    n_in = obs.shape[2]
    b1_at = n_in * hidden
    w2_at = b1_at + hidden
    b2_at = w2_at + hidden * n_choices
    h = np.empty(hidden, np.float32)
    for e in range(genomes.shape[0]):
        for r in range(genomes.shape[1]):
            g = genomes[e, r]
            for u in range(hidden):
                a = g[b1_at + u]
                for i in range(n_in):
                    a += obs[e, r, i] * g[i * hidden + u]
                h[u] = tanh32(a) if tanh_hidden else max(a, np.float32(0.0))
            best, choice = np.float32(-np.inf), 0
            for j in range(n_choices):
                z = g[b2_at + j]
                for u in range(hidden):
                    z += h[u] * g[w2_at + u * n_choices + j]
                if z > best:
                    best, choice = z, j
            out[e, r, 0] = np.float32(-1.0 + (2.0 * choice + 1.0) / n_choices)
            out[e, r, 1] = np.float32(0.0)


class PickPolicy:
    """Fixed genomes of picking agents as a policy ``obs (E, R, n_in) -> commands (E, R,
    2)`` (:func:`pick_forward`)."""

    def __init__(self, genomes: np.ndarray, hidden: int, n_in: int, n_choices: int,
                 tanh_hidden: bool = False):  # fmt: skip
        self.genomes = np.ascontiguousarray(genomes, dtype=np.float32)
        self.hidden, self.n_in, self.n_choices = int(hidden), int(n_in), int(n_choices)
        self.tanh_hidden = bool(tanh_hidden)

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        obs = np.ascontiguousarray(obs, dtype=np.float32)
        if obs.shape[-1] != self.n_in:
            raise ValueError(f"observations must have {self.n_in} inputs, got {obs.shape}")
        out = np.empty((*self.genomes.shape[:-1], 2), dtype=np.float32)
        pick_forward(self.genomes, self.hidden, self.n_choices, obs, out, self.tanh_hidden)
        return out


@jit
def policy_forward(genomes, hidden, obs, out, dims, tanh_hidden=False):
    """Actions of every rover of every team: genomes (E, R, P) float32, obs (E, R, n_in)
    float32, out (E, R, 2) float32 written with :func:`forward_team`, team by team."""
    h = np.empty(hidden, np.float32)
    for e in range(genomes.shape[0]):
        forward_team(genomes[e], hidden, obs[e], out[e], dims, h, tanh_hidden)
