"""Compiled kernels of the learner (see :mod:`physrover.engine`): the policy forward pass
(reference: ``PolicyLayout.forward``) and the intermediate critics' values and SGD updates,
regular and inexact (reference: ``IntermediateCritics`` and ``FitnessCritic`` in
:mod:`physrover.learn.critics`).

The input and output sizes are the domain's and compile-time constants (8 observations, 2
actions, 10 = 8 + 2 critic inputs), so the compiler unrolls those loops; hidden sizes are
free. Arithmetic is float32 like the reference. Loops run over whole rows of contiguous
arrays so that the compiler vectorises them; the critics keep pairs in the innermost loop
(a transposed copy of the pairs, ``(10, N)``). Sums are accumulated in a fixed order, so a
kernel gives the same result on every run; it differs from the reference (whose order is
BLAS's) by float32 rounding.
"""

from __future__ import annotations

import numpy as np

from physrover.domain.sensing import OBS_DIM
from physrover.domain.world import ACTION_DIM
from physrover.engine import jit, jit_reassoc
from physrover.learn.critics import PAIR_DIM

# Mini-batches are padded to a multiple of this many pairs (16 float32 lanes of AVX-512 x 4
# interleaved, as LLVM vectorises): measured, 64 pairs take less time than 50.
PAD_PAIRS = 64


@jit
def policy_forward(genomes, hidden, obs, out):
    """Actions of every rover of every team, as ``PolicyLayout.forward``.

    Args:
        genomes: (E, R, P) float32 genomes laid out ``W1 (8 x H) | b1 | W2 (H x 2) | b2``.
        hidden: H.
        obs: (E, R, 8) float32 observations.
        out: (E, R, 2) float32, written with the pre-activations ``relu(obs W1 + b1) W2 + b2``;
            the caller applies ``np.tanh`` (numpy's vectorised tanh is several times faster
            than calling libm's per element here).
    """
    n_teams, n_rovers, _ = genomes.shape
    b1_at = OBS_DIM * hidden
    w2_at = b1_at + hidden
    b2_at = w2_at + hidden * ACTION_DIM
    whole = hidden - hidden % 4
    h = np.empty(hidden, np.float32)
    for e in range(n_teams):
        for r in range(n_rovers):
            g = genomes[e, r]
            x = obs[e, r]
            for u in range(hidden):
                a = g[b1_at + u]
                for i in range(OBS_DIM):
                    a += x[i] * g[i * hidden + u]
                h[u] = max(a, np.float32(0.0))
            # Output sums in four interleaved partial sums (independent chains), then the rest.
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
            out[e, r, 0] = g[b2_at] + ((p0 + p1) + (p2 + p3))
            out[e, r, 1] = g[b2_at + 1] + ((q0 + q1) + (q2 + q3))


@jit
def gather_trajectories(obs, act, where, out):
    """``out[r, p, t] = (obs[t, e, r], act[t, e, r])`` with ``e = where[r, p]``: the (s, a)
    pairs of policy p of rover r, which played in team e (obs (T, E, R, 8), act (T, E, R, 2),
    where (R, k), out (R, k, T, 10))."""
    n_rovers, k = where.shape
    steps = obs.shape[0]
    for r in range(n_rovers):
        for p in range(k):
            e = where[r, p]
            for t in range(steps):
                row = out[r, p, t]
                for i in range(OBS_DIM):
                    row[i] = obs[t, e, r, i]
                for i in range(ACTION_DIM):
                    row[OBS_DIM + i] = act[t, e, r, i]


@jit
def _critic_forward(W1T, b1, slope, xT, z, value):
    """Sums ``value[n] = sum_h lrelu(z[h, n])`` (N,) of one critic (W1T (H, 10), b1 (H,)) on
    pairs xT (10, N); the pre-activations go to the rows of ``z``: (H, N) to keep them, or
    (1, N) as scratch."""
    hidden = W1T.shape[0]
    n_pairs = xT.shape[1]
    x0, x1, x2, x3, x4 = xT[0], xT[1], xT[2], xT[3], xT[4]
    x5, x6, x7, x8, x9 = xT[5], xT[6], xT[7], xT[8], xT[9]
    for n in range(n_pairs):
        value[n] = np.float32(0.0)
    for u in range(hidden):
        w = W1T[u]
        w0, w1, w2, w3, w4 = w[0], w[1], w[2], w[3], w[4]
        w5, w6, w7, w8, w9 = w[5], w[6], w[7], w[8], w[9]
        bu = b1[u]
        zu = z[u] if z.shape[0] == hidden else z[0]
        for n in range(n_pairs):  # the 10 inputs written out: kept in registers
            zn = (
                bu
                + x0[n] * w0
                + x1[n] * w1
                + x2[n] * w2
                + x3[n] * w3
                + x4[n] * w4
                + x5[n] * w5
                + x6[n] * w6
                + x7[n] * w7
                + x8[n] * w8
                + x9[n] * w9
            )
            zu[n] = zn
            value[n] += zn if zn > 0 else slope * zn


@jit
def critic_values(W1T, b1, b2, slope, xT, out):
    """``C(x) = sum_h lrelu(x W1 + b1)_h + b2`` of R critics (W1T (R, H, 10), b1 (R, H),
    b2 (R,)) on pairs xT (R, 10, N), into (R, N) ``out``."""
    scratch = np.empty((1, xT.shape[2]), np.float32)
    for r in range(xT.shape[0]):
        value = out[r]
        _critic_forward(W1T[r], b1[r], slope, xT[r], scratch, value)
        for n in range(value.shape[0]):
            value[n] += b2[r]


@jit_reassoc
def _weighted_grad(W1T, slope, xT, z, u_weights, dW1T, db1):
    """``sum_n u_n grad C(x_n)`` of one critic for the W1 and b1 blocks, from the pairs xT
    (10, N), their pre-activations z (H, N) and weights (N,), into dW1T (H, 10), db1 (H,).

    Each entry is a sum over the N pairs; this is the one place where the compiler may
    reorder additions (vectorised partial sums), so the sums are reproducible on a machine
    but their last bits depend on its vector width.
    """
    hidden = W1T.shape[0]
    n_pairs = xT.shape[1]
    one_minus = np.float32(1.0) - slope
    x0, x1, x2, x3, x4 = xT[0], xT[1], xT[2], xT[3], xT[4]
    x5, x6, x7, x8, x9 = xT[5], xT[6], xT[7], xT[8], xT[9]
    for u in range(hidden):
        zu = z[u]
        s0 = s1 = s2 = s3 = s4 = s5 = s6 = s7 = s8 = s9 = sb = np.float32(0.0)
        for n in range(n_pairs):
            # lrelu'(z) = slope + (1 - slope) [z > 0], times the pair's weight
            g = ((one_minus if zu[n] > 0 else np.float32(0.0)) + slope) * u_weights[n]
            sb += g
            s0 += x0[n] * g
            s1 += x1[n] * g
            s2 += x2[n] * g
            s3 += x3[n] * g
            s4 += x4[n] * g
            s5 += x5[n] * g
            s6 += x6[n] * g
            s7 += x7[n] * g
            s8 += x8[n] * g
            s9 += x9[n] * g
        db1[u] = sb
        d = dW1T[u]
        d[0], d[1], d[2], d[3], d[4] = s0, s1, s2, s3, s4
        d[5], d[6], d[7], d[8], d[9] = s5, s6, s7, s8, s9


@jit
def critic_sgd(W1T, b1, b2, slope, lr, items, feedback, index, batch, use_max):
    """One generation of mini-batch gradient steps of R critics, in place; both update kinds.

    Critic r's mini-batches are the replay entries ``items[r, index[r]]`` (items
    (R, C, T, 10): entries of T state-action pairs, feedback (R, C), index (R, M)),
    ``M // batch`` of them one after the other. Per entry the critic's values of its T pairs
    are aggregated, by their mean or (``use_max``) their maximum (the first, as
    ``np.argmax``): ``F = agg_t C(x_t)``; with ``delta = f - F`` (Eq. 8, or Eq. 10 for T = 1)
    the critic takes the step ``w += lr * sum_entries delta * dF/dw`` after the whole
    mini-batch, as ``FitnessCritic.update`` does with SGD:

    - regular updates (Eqs. 6-8): entries are trajectories (T = steps);
    - inexact updates (Eqs. 9-10): entries are single pairs (T = 1, where both
      aggregations are the value itself and the arithmetic is exactly the per-pair rule).

    Critics are independent, so each runs all its mini-batches in turn. Returns the mean of
    ``delta**2`` over all critics and entries (float64).
    """
    n_critics, n_items = index.shape
    steps = items.shape[2]
    hidden = W1T.shape[1]
    n_batches = n_items // batch
    n_pairs = batch * steps
    # Pairs are padded to a multiple of PAD_PAIRS with zero inputs and zero weight: they add
    # exact zeros to the gradient sums, and the pair loops get whole vector iterations.
    padded = -(-n_pairs // PAD_PAIRS) * PAD_PAIRS
    xT = np.zeros((PAIR_DIM, padded), np.float32)
    drawn = np.empty((n_items, steps, PAIR_DIM), np.float32)  # one critic's draws at once
    drawn_feedback = np.empty(n_items, np.float32)
    z = np.empty((hidden, padded), np.float32)
    value = np.empty(padded, np.float32)
    weight = np.zeros(padded, np.float32)  # dF/dC(x_n) * delta of the pair's entry
    dW1T = np.empty((hidden, PAIR_DIM), np.float32)
    db1 = np.empty(hidden, np.float32)
    inv_steps = np.float32(1.0 / steps)  # the mean's dF/dC, as the reference's float32 1/T
    sq_sum = 0.0
    for r in range(n_critics):
        W, b = W1T[r], b1[r]
        for m in range(n_items):  # random reads, many in flight
            slot = index[r, m]
            drawn_feedback[m] = feedback[r, slot]
            for t in range(steps):
                for i in range(PAIR_DIM):
                    drawn[m, t, i] = items[r, slot, t, i]
        for first in range(0, n_batches * batch, batch):
            for j in range(batch):
                for t in range(steps):
                    for i in range(PAIR_DIM):
                        xT[i, j * steps + t] = drawn[first + j, t, i]
            _critic_forward(W, b, slope, xT, z, value)
            db2 = np.float32(0.0)
            for j in range(batch):
                at = j * steps
                if use_max:  # Eq. 3: the first maximum of C = value + b2
                    arg = 0
                    F = value[at] + b2[r]
                    for t in range(1, steps):
                        if value[at + t] + b2[r] > F:
                            arg = t
                            F = value[at + t] + b2[r]
                else:  # Eq. 4
                    F = np.float32(0.0)
                    for t in range(steps):
                        F += value[at + t] + b2[r]
                    F /= np.float32(steps)
                delta = drawn_feedback[first + j] - F  # Eq. 8 / Eq. 10
                sq_sum += np.float64(delta) * np.float64(delta)
                for t in range(steps):
                    if use_max:
                        weight[at + t] = delta if t == arg else np.float32(0.0)
                    else:
                        weight[at + t] = delta * inv_steps
                    db2 += weight[at + t]
            _weighted_grad(W, slope, xT, z, weight, dW1T, db1)
            for u in range(hidden):  # Eq. 7 / Eq. 9: the step, after the whole mini-batch
                for i in range(PAIR_DIM):
                    W[u, i] += lr * dW1T[u, i]
                b[u] += lr * db1[u]
            b2[r] += lr * db2
    return sq_sum / max(n_critics * n_batches * batch, 1)
