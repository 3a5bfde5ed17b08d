"""Compiled kernels of the learner: the one implementation of the intermediate critics'
values (Eq. 2) and of their updates, regular (Eqs. 6-8) and inexact (Eqs. 9-10), by SGD or
Adam, and the gathering of their training pairs. (The policies' forward pass is
:mod:`physrover.learn.forward`.)

Sizes are the arrays' own: observations (n_in, from the sensor), actions (2, the domain's),
critic inputs (n_in + 2) and hidden units. Arithmetic is float32. Loops run over whole rows
of contiguous arrays so that the compiler vectorises them; the critics keep pairs in the
innermost loop (a transposed copy of the pairs, ``(n_in + 2, N)``). Sums are accumulated in
a fixed order, so a kernel gives the same result on every run. The tests compare the
kernels with plain numpy versions (``tests/oracles.py``) and with finite differences.
"""

from __future__ import annotations

import numpy as np

from physrover.core.compiled import jit, jit_reassoc

# Mini-batches are padded to a multiple of this many pairs (16 float32 lanes of AVX-512 x 4
# interleaved, as LLVM vectorises): measured, 64 pairs take less time than 50.
PAD_PAIRS = 64
TILE = 16
"""Inputs per register tile of the critics' loops (see :func:`_critic_forward`)."""
ADAM_BETA1, ADAM_BETA2, ADAM_EPS = 0.9, 0.999, 1e-8
"""Adam's constants (Kingma and Ba's defaults, as torch.optim.Adam)."""


@jit
def gather_trajectories(obs, act, where, out, dims):
    """``out[r, p, t] = (obs[t, e, r], act[t, e, r])`` with ``e = where[r, p]``: the (s, a)
    pairs of policy p of rover r, which played in team e (obs (T, E, R, n_in), act
    (T, E, R, 2), where (R, k), out (R, k, T, n_in + 2)); ``dims``: n_in zeros (``compiled.dims``).
    """
    n_rovers, k = where.shape
    steps, n_in, n_act = obs.shape[0], len(dims), 2
    for r in range(n_rovers):
        for p in range(k):
            e = where[r, p]
            for t in range(steps):
                row = out[r, p, t]
                for i in range(n_in):
                    row[i] = obs[t, e, r, i]
                for i in range(n_act):
                    row[n_in + i] = act[t, e, r, i]


@jit
def _critic_forward(W1T, b1, out_w, slope, xT, z, value, dims):
    """Sums ``value[n] = sum_h lrelu(z[h, n])`` (N,) of one critic (W1T (H, D), b1 (H,)) on
    pairs xT (D, N), or ``sum_h out_w[h] lrelu(z[h, n])`` with trained output weights
    ``out_w`` (H,) (None: the paper's fixed unit weights, compiled as if absent); the
    pre-activations ``z[h, n] = b1[h] + sum_i xT[i, n] W1T[h, i]``
    (added in the order of i) go to the rows of ``z``: (H, N) to keep them, or (1, N) as
    scratch. ``dims``: D zeros (``compiled.dims``).

    Register tiling: the inputs are taken 16 at a time (one pass over the pairs per tile),
    their weights held in scalars; D is a compile-time constant, so the compiler drops the
    terms past D (the paper's D = 10 runs as one pass of 10 terms).
    """
    n_in = len(dims)
    hidden = W1T.shape[0]
    n_pairs = xT.shape[1]
    for n in range(n_pairs):
        value[n] = np.float32(0.0)
    for u in range(hidden):
        w = W1T[u]
        bu = b1[u]
        zu = z[u] if z.shape[0] == hidden else z[0]
        for i0 in range(0, n_in, TILE):
            first, last = i0 == 0, i0 + TILE >= n_in
            w0 = w[i0 + 0] if i0 + 0 < n_in else np.float32(0.0)
            w1 = w[i0 + 1] if i0 + 1 < n_in else np.float32(0.0)
            w2 = w[i0 + 2] if i0 + 2 < n_in else np.float32(0.0)
            w3 = w[i0 + 3] if i0 + 3 < n_in else np.float32(0.0)
            w4 = w[i0 + 4] if i0 + 4 < n_in else np.float32(0.0)
            w5 = w[i0 + 5] if i0 + 5 < n_in else np.float32(0.0)
            w6 = w[i0 + 6] if i0 + 6 < n_in else np.float32(0.0)
            w7 = w[i0 + 7] if i0 + 7 < n_in else np.float32(0.0)
            w8 = w[i0 + 8] if i0 + 8 < n_in else np.float32(0.0)
            w9 = w[i0 + 9] if i0 + 9 < n_in else np.float32(0.0)
            w10 = w[i0 + 10] if i0 + 10 < n_in else np.float32(0.0)
            w11 = w[i0 + 11] if i0 + 11 < n_in else np.float32(0.0)
            w12 = w[i0 + 12] if i0 + 12 < n_in else np.float32(0.0)
            w13 = w[i0 + 13] if i0 + 13 < n_in else np.float32(0.0)
            w14 = w[i0 + 14] if i0 + 14 < n_in else np.float32(0.0)
            w15 = w[i0 + 15] if i0 + 15 < n_in else np.float32(0.0)
            for n in range(n_pairs):
                zn = bu if first else zu[n]
                if i0 + 0 < n_in:
                    zn += xT[i0 + 0, n] * w0
                if i0 + 1 < n_in:
                    zn += xT[i0 + 1, n] * w1
                if i0 + 2 < n_in:
                    zn += xT[i0 + 2, n] * w2
                if i0 + 3 < n_in:
                    zn += xT[i0 + 3, n] * w3
                if i0 + 4 < n_in:
                    zn += xT[i0 + 4, n] * w4
                if i0 + 5 < n_in:
                    zn += xT[i0 + 5, n] * w5
                if i0 + 6 < n_in:
                    zn += xT[i0 + 6, n] * w6
                if i0 + 7 < n_in:
                    zn += xT[i0 + 7, n] * w7
                if i0 + 8 < n_in:
                    zn += xT[i0 + 8, n] * w8
                if i0 + 9 < n_in:
                    zn += xT[i0 + 9, n] * w9
                if i0 + 10 < n_in:
                    zn += xT[i0 + 10, n] * w10
                if i0 + 11 < n_in:
                    zn += xT[i0 + 11, n] * w11
                if i0 + 12 < n_in:
                    zn += xT[i0 + 12, n] * w12
                if i0 + 13 < n_in:
                    zn += xT[i0 + 13, n] * w13
                if i0 + 14 < n_in:
                    zn += xT[i0 + 14, n] * w14
                if i0 + 15 < n_in:
                    zn += xT[i0 + 15, n] * w15
                zu[n] = zn
                if last:
                    if out_w is None:
                        value[n] += zn if zn > 0 else slope * zn
                    else:
                        value[n] += out_w[u] * (zn if zn > 0 else slope * zn)


@jit
def critic_values(W1T, b1, b2, W2, slope, x, out, dims):
    """``C(x) = sum_h lrelu(x W1 + b1)_h + b2`` (Eq. 2) of R critics (W1T (R, H, D), b1
    (R, H), b2 (R,)) on pairs x (R, N, D), into (R, N) ``out``, or with trained output
    weights W2 (R, H) ``sum_h W2_h lrelu(...)_h + b2`` (None: fixed to 1); ``dims``: D
    zeros (``compiled.dims``). Each critic's pairs are transposed to (D, N), the layout of
    :func:`_critic_forward`, in one scratch block reused by every critic (a transposed
    copy of the whole (R, N, D) array, ~2 MB for the mixed team, was a fresh allocation
    that page-faulted every generation)."""
    n_in = len(dims)
    n_pairs = x.shape[1]
    xT = np.empty((n_in, n_pairs), np.float32)
    scratch = np.empty((1, n_pairs), np.float32)
    for r in range(x.shape[0]):
        for n in range(n_pairs):
            for i in range(n_in):
                xT[i, n] = x[r, n, i]
        value = out[r]
        w2 = None if W2 is None else W2[r]
        _critic_forward(W1T[r], b1[r], w2, slope, xT, scratch, value, dims)
        for n in range(n_pairs):
            value[n] += b2[r]


@jit_reassoc
def _weighted_grad(W1T, w2, slope, xT, z, u_weights, dW1T, db1, dw2, dims):
    """``sum_n u_n grad C(x_n)`` of one critic for the W1 and b1 blocks, from the pairs xT
    (D, N), their pre-activations z (H, N) and weights (N,), into dW1T (H, D), db1 (H,);
    with trained output weights ``w2`` (H,) (None: fixed to 1) the W1 and b1 terms carry
    their unit's w2 and ``dw2`` (H,) gets ``sum_n u_n lrelu(z[h, n])``; ``dims``: D zeros
    (``compiled.dims``). Register tiling as in :func:`_critic_forward`.

    Each entry is a sum over the N pairs; this is the one place where the compiler may
    reorder additions (vectorised partial sums), so the sums are reproducible on a machine
    but their last bits depend on its vector width.
    """
    n_in = len(dims)
    hidden = W1T.shape[0]
    n_pairs = xT.shape[1]
    one_minus = np.float32(1.0) - slope
    for u in range(hidden):
        zu = z[u]
        for i0 in range(0, n_in, TILE):
            s0 = s1 = s2 = s3 = s4 = s5 = s6 = s7 = s8 = s9 = s10 = s11 = s12 = s13 = s14 = s15 = (
                sb
            ) = sw = np.float32(0.0)
            for n in range(n_pairs):
                # lrelu'(z) = slope + (1 - slope) [z > 0], times the pair's weight
                g = ((one_minus if zu[n] > 0 else np.float32(0.0)) + slope) * u_weights[n]
                if w2 is not None:  # trained output weights: dC/dz carries the unit's w2
                    if i0 == 0:
                        sw += u_weights[n] * (zu[n] if zu[n] > 0 else slope * zu[n])
                    g *= w2[u]
                sb += g
                if i0 + 0 < n_in:
                    s0 += xT[i0 + 0, n] * g
                if i0 + 1 < n_in:
                    s1 += xT[i0 + 1, n] * g
                if i0 + 2 < n_in:
                    s2 += xT[i0 + 2, n] * g
                if i0 + 3 < n_in:
                    s3 += xT[i0 + 3, n] * g
                if i0 + 4 < n_in:
                    s4 += xT[i0 + 4, n] * g
                if i0 + 5 < n_in:
                    s5 += xT[i0 + 5, n] * g
                if i0 + 6 < n_in:
                    s6 += xT[i0 + 6, n] * g
                if i0 + 7 < n_in:
                    s7 += xT[i0 + 7, n] * g
                if i0 + 8 < n_in:
                    s8 += xT[i0 + 8, n] * g
                if i0 + 9 < n_in:
                    s9 += xT[i0 + 9, n] * g
                if i0 + 10 < n_in:
                    s10 += xT[i0 + 10, n] * g
                if i0 + 11 < n_in:
                    s11 += xT[i0 + 11, n] * g
                if i0 + 12 < n_in:
                    s12 += xT[i0 + 12, n] * g
                if i0 + 13 < n_in:
                    s13 += xT[i0 + 13, n] * g
                if i0 + 14 < n_in:
                    s14 += xT[i0 + 14, n] * g
                if i0 + 15 < n_in:
                    s15 += xT[i0 + 15, n] * g
            if i0 == 0:
                db1[u] = sb
                if w2 is not None:
                    dw2[u] = sw
            if i0 + 0 < n_in:
                dW1T[u, i0 + 0] = s0
            if i0 + 1 < n_in:
                dW1T[u, i0 + 1] = s1
            if i0 + 2 < n_in:
                dW1T[u, i0 + 2] = s2
            if i0 + 3 < n_in:
                dW1T[u, i0 + 3] = s3
            if i0 + 4 < n_in:
                dW1T[u, i0 + 4] = s4
            if i0 + 5 < n_in:
                dW1T[u, i0 + 5] = s5
            if i0 + 6 < n_in:
                dW1T[u, i0 + 6] = s6
            if i0 + 7 < n_in:
                dW1T[u, i0 + 7] = s7
            if i0 + 8 < n_in:
                dW1T[u, i0 + 8] = s8
            if i0 + 9 < n_in:
                dW1T[u, i0 + 9] = s9
            if i0 + 10 < n_in:
                dW1T[u, i0 + 10] = s10
            if i0 + 11 < n_in:
                dW1T[u, i0 + 11] = s11
            if i0 + 12 < n_in:
                dW1T[u, i0 + 12] = s12
            if i0 + 13 < n_in:
                dW1T[u, i0 + 13] = s13
            if i0 + 14 < n_in:
                dW1T[u, i0 + 14] = s14
            if i0 + 15 < n_in:
                dW1T[u, i0 + 15] = s15


@jit
def _apply(param, direction, lr, adam, m, v, c1, c2):
    """``param += lr * direction`` (SGD, Eqs. 7 / 9), or Adam's step on it with moments
    ``m``, ``v`` and bias corrections ``c1 = 1 - beta1^t``, ``c2 = 1 - beta2^t``; flat
    float32 arrays of one size (m, v unused for SGD)."""
    if not adam:
        for j in range(param.shape[0]):
            param[j] += lr * direction[j]
        return
    b1, b2 = np.float32(ADAM_BETA1), np.float32(ADAM_BETA2)
    for j in range(param.shape[0]):
        d = direction[j]
        m[j] = m[j] * b1 + (np.float32(1.0) - b1) * d
        v[j] = v[j] * b2 + (np.float32(1.0) - b2) * d * d
        param[j] += lr * (m[j] / c1) / (np.sqrt(v[j] / c2) + np.float32(ADAM_EPS))


@jit
def critic_update(
    W1T, b1, b2, W2, slope, lr, items, feedback, buffer_of, index, batch, use_max, adam,
    moments, step, dims,
):  # fmt: skip
    """One generation of mini-batch updates of N critics, in place; both update kinds.

    Critic c's mini-batches are the replay entries ``items[b, index[c]]`` of its buffer
    ``b = buffer_of[c]`` (items (R, C, T, D): entries of T state-action pairs, feedback
    (R, C), buffer_of (N,), index (N, M)),
    ``M // batch`` of them one after the other. Per entry the critic's values of its T pairs
    are aggregated, by their mean or (``use_max``) their maximum (the first, as
    ``np.argmax``): ``F = agg_t C(x_t)``; with ``delta = f - F`` (Eq. 8, or Eq. 10 for T = 1)
    the critic takes the step along ``sum_entries delta * dF/dw`` after the whole mini-batch
    (with the max, ``dF/dw`` is the maximising pair's gradient alone, so only those pairs
    enter the gradient sums):

    - regular updates (Eqs. 6-8): entries are trajectories (T = steps);
    - inexact updates (Eqs. 9-10): entries are single pairs (T = 1, where both
      aggregations are the value itself and the arithmetic is exactly the per-pair rule).

    The step is plain (``w += lr * direction``, the paper's) or, with ``adam``, Adam's on the
    same gradient. ``W2`` (N, H): trained output weights, updated too (None: the paper's
    fixed unit weights). ``moments`` (N, 2, H * (D + 1) + 1 [+ H]) holds Adam's m and v of
    each critic's parameters flattened as ``W1T | b1 | b2 [| W2]``, and ``step`` the steps
    taken before this call (Adam's t, shared by all critics); ``dims``: D zeros
    (``compiled.dims``). Critics are independent, so each runs all its mini-batches in turn.
    Returns the mean of ``delta**2`` over all critics and entries (float64).
    """
    n_in = len(dims)
    n_critics, n_items = index.shape
    steps = items.shape[2]
    hidden = W1T.shape[1]
    n_batches = n_items // batch
    n_pairs = batch * steps
    # Pairs are padded to a multiple of PAD_PAIRS with zero inputs and zero weight: they add
    # exact zeros to the gradient sums, and the pair loops get whole vector iterations.
    padded = -(-n_pairs // PAD_PAIRS) * PAD_PAIRS
    xT = np.zeros((n_in, padded), np.float32)
    drawn = np.empty((n_items, steps, n_in), np.float32)  # one critic's draws at once
    drawn_feedback = np.empty(n_items, np.float32)
    z = np.empty((hidden, padded), np.float32)
    value = np.empty(padded, np.float32)
    weight = np.zeros(padded, np.float32)  # dF/dC(x_n) * delta of the pair's entry
    # With the max over T > 1 pairs, only each entry's maximising pair has a gradient: those
    # pairs alone (inputs, pre-activations, delta) go to the gradient sums, padded with
    # zero weights.
    compact = use_max and steps > 1
    padded_max = -(-batch // PAD_PAIRS) * PAD_PAIRS
    x_max = np.zeros((n_in, padded_max), np.float32)
    z_max = np.zeros((hidden, padded_max), np.float32)
    weight_max = np.zeros(padded_max, np.float32)
    n_w = hidden * n_in
    n_out = 0 if W2 is None else hidden
    grad = np.empty(n_w + hidden + 1 + n_out, np.float32)  # dW1T | db1 | db2 [| dW2], flat
    dW1T = grad[:n_w].reshape(hidden, n_in)
    db1 = grad[n_w : n_w + hidden]
    dw2 = grad[n_w + hidden + 1 :]
    inv_steps = np.float32(1.0 / steps)  # the mean's dF/dC, float32 1/T
    sq_sum = 0.0
    for r in range(n_critics):
        W, b = W1T[r], b1[r]
        w2 = None if W2 is None else W2[r]
        rover = buffer_of[r]
        for m in range(n_items):  # random reads, many in flight
            slot = index[r, m]
            drawn_feedback[m] = feedback[rover, slot]
            for t in range(steps):
                for i in range(n_in):
                    drawn[m, t, i] = items[rover, slot, t, i]
        for number, first in enumerate(range(0, n_batches * batch, batch)):
            for j in range(batch):
                for t in range(steps):
                    for i in range(n_in):
                        xT[i, j * steps + t] = drawn[first + j, t, i]
            _critic_forward(W, b, w2, slope, xT, z, value, dims)
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
                if compact:
                    for i in range(n_in):
                        x_max[i, j] = xT[i, at + arg]
                    for u in range(hidden):
                        z_max[u, j] = z[u, at + arg]
                    weight_max[j] = delta
                    db2 += delta
                else:
                    for t in range(steps):
                        if use_max:
                            weight[at + t] = delta if t == arg else np.float32(0.0)
                        else:
                            weight[at + t] = delta * inv_steps
                        db2 += weight[at + t]
            if compact:
                _weighted_grad(W, w2, slope, x_max, z_max, weight_max, dW1T, db1, dw2, dims)
            else:
                _weighted_grad(W, w2, slope, xT, z, weight, dW1T, db1, dw2, dims)
            grad[n_w + hidden] = db2
            # Eq. 7 / Eq. 9: the step, after the whole mini-batch
            t_adam = step + number + 1
            c1 = np.float32(1.0 - ADAM_BETA1**t_adam)
            c2 = np.float32(1.0 - ADAM_BETA2**t_adam)
            m_r, v_r = moments[r, 0], moments[r, 1]
            _apply(W.reshape(-1), dW1T.reshape(-1), lr, adam, m_r[:n_w], v_r[:n_w], c1, c2)
            _apply(b, db1, lr, adam, m_r[n_w : n_w + hidden], v_r[n_w : n_w + hidden], c1, c2)
            end = n_w + hidden + 1
            _apply(b2[r : r + 1], grad[n_w + hidden : end], lr, adam, m_r[n_w + hidden : end],
                   v_r[n_w + hidden : end], c1, c2)  # fmt: skip
            if w2 is not None:
                _apply(w2, dw2, lr, adam, m_r[end:], v_r[end:], c1, c2)
    return sq_sum / max(n_critics * n_batches * batch, 1)
