"""Is numba the limit of the policies' forward pass? (issue 17; a benchmark, not a test)

Compiles, with the machine's gcc, a C copy of :func:`physrover.learn.forward.forward_team`
(the same float32 operations in the same order, ``tanh32`` included; ``-O3 -march=native
-ffp-contract=off``, so no fused multiply-adds, as numba's IEEE code) and a variant free to
reorder the output layer (W2 read per output as 16-lane blocks, summed by a halving tree),
checks that the first gives numba's actions bit for bit, and times all three on 60 teams of
15 rovers (8 inputs, 32 hidden units), ns per rover, ``ROUNDS`` rounds of ``REPS`` calls.

    taskset -c 1 python benchmarks/forward_c.py

Needs gcc; nothing of it is part of the package.
"""

from __future__ import annotations

import ctypes
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

from physrover.core.compiled import dims
from physrover.learn.forward import policy_forward

TEAMS, ROVERS, N_IN, HIDDEN = 60, 15, 8, 32
REPS, ROUNDS = 200, 15

SOURCE = r"""
#include <math.h>
#include <stddef.h>
#define NIN 8
#define H 32
static inline float tanh32(float x) {  /* physrover.learn.forward.tanh32, term by term */
    double a = fabs((double)x); if (a > 10.0) a = 10.0;
    double y = 2.0 * a;
    double k = floor(y * 1.4426950408889634 + 0.5);
    double r = (y - k * 0.6931471803691238) - k * 1.9082149292705877e-10;
    double q = r * (1.0 + r * (1.0 / 2 + r * (1.0 / 6 + r * (1.0 / 24 + r * (1.0 / 120 + r * (
        1.0 / 720 + r * (1.0 / 5040 + r * (1.0 / 40320 + r * (1.0 / 362880 + r * (
            1.0 / 3628800 + r * (1.0 / 39916800 + r * (1.0 / 479001600))))))))))));
    double p = 1.0;
    const double bits[5] = {16.0, 8.0, 4.0, 2.0, 1.0};
    const double pw[5] = {65536.0, 256.0, 16.0, 4.0, 2.0};
    for (int j = 0; j < 5; j++) { if (k >= bits[j]) { p *= pw[j]; k -= bits[j]; } }
    double em1 = p * q + (p - 1.0);
    double t = em1 / (em1 + 2.0);
    return (a == a) ? (float)copysign(t, (double)x) : x;
}
static inline void hidden_layer(const float *g, const float *x, float *h) {
    for (int u = 0; u < H; u++) {
        float a = g[NIN * H + u];
        for (int i = 0; i < NIN; i++) a += x[i] * g[i * H + u];
        h[u] = a > 0.0f ? a : 0.0f;
    }
}
#define P (NIN * H + H + 2 * H + 2)
#define W2_AT (NIN * H + H)
#define B2_AT (W2_AT + 2 * H)
static inline void same_order(const float *g, const float *h, float *o) {
    float p0 = 0, p1 = 0, p2 = 0, p3 = 0, q0 = 0, q1 = 0, q2 = 0, q3 = 0;
    for (int u = 0; u < H; u += 4) {
        int w = W2_AT + 2 * u;
        p0 += h[u] * g[w];         q0 += h[u] * g[w + 1];
        p1 += h[u + 1] * g[w + 2]; q1 += h[u + 1] * g[w + 3];
        p2 += h[u + 2] * g[w + 4]; q2 += h[u + 2] * g[w + 5];
        p3 += h[u + 3] * g[w + 6]; q3 += h[u + 3] * g[w + 7];
    }
    o[0] = g[B2_AT] + ((p0 + p1) + (p2 + p3));
    o[1] = g[B2_AT + 1] + ((q0 + q1) + (q2 + q3));
}
static inline void free_order(const float *g, const float *h, float *o) {
    for (int k = 0; k < 2; k++) {  /* W2 read as (2, H): other sums, other actions */
        const float *w = g + W2_AT + k * H;
        float acc[16];
        for (int j = 0; j < 16; j++) acc[j] = h[j] * w[j] + h[j + 16] * w[j + 16];
        for (int j = 0; j < 8; j++) acc[j] += acc[j + 8];
        for (int j = 0; j < 4; j++) acc[j] += acc[j + 4];
        for (int j = 0; j < 2; j++) acc[j] += acc[j + 2];
        o[k] = g[B2_AT + k] + (acc[0] + acc[1]);
    }
}
void forward(const float *genomes, const float *obs, float *out, int teams, int rovers,
             int reps, int free) {
    float h[H];
    for (int rep = 0; rep < reps; rep++)
    for (int e = 0; e < teams; e++) {
        float *o = out + (size_t)e * rovers * 2;
        for (int r = 0; r < rovers; r++) {
            const float *g = genomes + ((size_t)e * rovers + r) * P;
            hidden_layer(g, obs + ((size_t)e * rovers + r) * NIN, h);
            if (free) free_order(g, h, o + 2 * r); else same_order(g, h, o + 2 * r);
        }
        for (int j = 0; j < 2 * rovers; j++) o[j] = tanh32(o[j]);
    }
}
"""


def build(tmp: Path) -> ctypes.CDLL:
    (tmp / "forward.c").write_text(SOURCE)
    lib = tmp / "libforward.so"
    subprocess.run(
        ["gcc", "-O3", "-march=native", "-ffp-contract=off", "-fno-math-errno", "-shared",
         "-fPIC", str(tmp / "forward.c"), "-o", str(lib)],
        check=True,
    )  # fmt: skip
    return ctypes.CDLL(str(lib))


def main() -> None:
    rng = np.random.default_rng(0)
    n_params = N_IN * HIDDEN + HIDDEN + 2 * HIDDEN + 2
    genomes = rng.normal(0.0, 1.0, (TEAMS, ROVERS, n_params)).astype(np.float32)
    obs = rng.uniform(0.0, 3.0, (TEAMS, ROVERS, N_IN)).astype(np.float32)
    ours = np.empty((TEAMS, ROVERS, 2), np.float32)
    theirs = np.empty_like(ours)
    in_dims = dims(N_IN)
    ptr = ctypes.POINTER(ctypes.c_float)
    with tempfile.TemporaryDirectory() as tmp:
        lib = build(Path(tmp))
        args = (genomes.ctypes.data_as(ptr), obs.ctypes.data_as(ptr), theirs.ctypes.data_as(ptr),
                TEAMS, ROVERS)  # fmt: skip
        policy_forward(genomes, HIDDEN, obs, ours, in_dims)
        lib.forward(*args, 1, 0)
        same = np.array_equal(ours.view(np.int32), theirs.view(np.int32))
        print("C same order == numba, bit for bit:", same)
        per_rover = 1e9 / (REPS * TEAMS * ROVERS)
        times: dict[str, list[float]] = {"numba": [], "C same order": [], "C free order": []}
        for _ in range(ROUNDS):
            start = time.perf_counter()
            for _ in range(REPS):
                policy_forward(genomes, HIDDEN, obs, ours, in_dims)
            times["numba"].append((time.perf_counter() - start) * per_rover)
            for name, free in (("C same order", 0), ("C free order", 1)):
                start = time.perf_counter()
                lib.forward(*args, REPS, free)
                times[name].append((time.perf_counter() - start) * per_rover)
    for name, values in times.items():
        print(f"{name:14s} median {np.median(values):6.1f} ns a rover (min {min(values):.1f})")


if __name__ == "__main__":
    main()
