"""Oracles: the domain's equations as short numpy array code, written from the paper.

This was physrover 0.1's "numpy reference engine". The package now has one implementation of
each equation (the compiled kernels); this module is what the tests compare it with, so a
change to a kernel is checked against code that reads like the paper and does not share it.

- relations (Eq. 14 and quadrants), sensing (Eqs. 15-16), idealised motion (Section 4.1.2),
  scoring (Eqs. 11-13) and D (Eq. 1), each as in the sections below.

The quadrant convention is the package's (``physrover/domain/sensing.py``): 0 behind-right
[-180, -90) deg, 1 front-right [-90, 0), 2 front-left [0, 90), 3 behind-left [90, 180), a
bearing on a boundary in the quadrant that starts there. Relations here are float32 (the
kernels compute in float64), so observations agree to float32 rounding.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

OBS_DIM = 8

# ----------------------------------------------------------------------------------------------
# Relations: Eq. 14 and quadrants
# ----------------------------------------------------------------------------------------------

DTYPE = np.float32


@dataclass(frozen=True)
class Relations:
    """Relations of every rover to every object of its team at one step.

    Attributes:
        delta_sq: (E, R, N) float32 squared bounded distance ``max(||p_i - p_j||, d_min)^2``
            (Eq. 14), world units squared; objects are the R rovers, then the K POIs.
        quadrant: (E, R, N) uint8 quadrant of each object in the rover's frame (module doc).
    """

    delta_sq: np.ndarray
    quadrant: np.ndarray


def quadrants(forward: np.ndarray, left: np.ndarray) -> np.ndarray:
    """Quadrant index (uint8) of offsets given in the rover's frame; see the module docstring."""
    upper = left > 0  # bearing in [0, pi) ...
    upper |= (left == 0) & (forward >= 0)  # ... including dead ahead and the rover's own spot
    behind = forward < 0  # in the upper half: bearing in [pi/2, pi) ...
    behind |= (forward == 0) & (left > 0)  # ... including dead left
    # Bit 1 is the half, bit 0 the quadrant within it; boolean algebra instead of np.where,
    # which branches per element and costs ten times more on mixed signs.
    low = (upper & behind) | (~upper & (forward >= 0))
    return (upper.view(np.uint8) << 1) | low.view(np.uint8)


def relate(
    rover_positions: np.ndarray,
    rover_headings: np.ndarray,
    poi_positions: np.ndarray,
    d_min: float,
) -> Relations:
    """Relations of each rover to all rovers and POIs of its team.

    Args:
        rover_positions: (E, R, 2) world positions.
        rover_headings: (E, R) headings, radians counter-clockwise from the world x axis.
        poi_positions: (E, K, 2) world positions.
        d_min: lower bound of the distance metric (Eq. 14), world units.
    """
    objects = np.concatenate([rover_positions, poi_positions], axis=1).astype(DTYPE)
    # Coordinates as contiguous (E, R) / (E, N) arrays: broadcasting over a trailing axis of
    # size 2 is several times slower than these plain outer differences.
    ox, oy = np.ascontiguousarray(objects[..., 0]), np.ascontiguousarray(objects[..., 1])
    n_rovers = rover_positions.shape[1]
    rx, ry = ox[:, :n_rovers], oy[:, :n_rovers]
    dx = ox[:, None, :] - rx[:, :, None]  # (E, R, N)
    dy = oy[:, None, :] - ry[:, :, None]
    headings = rover_headings.astype(DTYPE)[..., None]
    cos_h, sin_h = np.cos(headings), np.sin(headings)
    forward = cos_h * dx
    forward += sin_h * dy
    left = cos_h * dy
    left -= sin_h * dx
    delta_sq = dx * dx
    delta_sq += dy * dy
    np.maximum(delta_sq, DTYPE(d_min * d_min), out=delta_sq)
    return Relations(delta_sq=delta_sq, quadrant=quadrants(forward, left))


# ----------------------------------------------------------------------------------------------
# Sensing: Eqs. 15-16
# ----------------------------------------------------------------------------------------------


def numerators(n_rovers: int, poi_values: np.ndarray) -> np.ndarray:
    """(E, R, N) numerator of each object's sensing term; fixed for an episode.

    1 for the other rovers (Eq. 15), 0 for the rover itself, V_k for POI k (Eq. 16).

    Args:
        n_rovers: R.
        poi_values: (E, K) POI values.
    """
    n_teams, n_pois = poi_values.shape
    out = np.empty((n_teams, n_rovers, n_rovers + n_pois))
    out[:, :, :n_rovers] = 1.0 - np.eye(n_rovers)
    out[:, :, n_rovers:] = poi_values[:, None, :]
    return out


@functools.lru_cache(maxsize=16)
def _cell_base(n_teams: int, n_rovers: int, n_objects: int) -> np.ndarray:
    """(E, R, N) index of channel 0 of each rover's observation, +4 for POI objects."""
    row = np.arange(n_teams * n_rovers).reshape(n_teams, n_rovers, 1) * OBS_DIM
    poi_offset = np.where(np.arange(n_objects) < n_rovers, 0, 4)
    base = row + poi_offset
    base.flags.writeable = False
    return base


def sense(relations: Relations, numerator: np.ndarray) -> np.ndarray:
    """Observations of all rovers of all teams (Eqs. 15-16).

    Args:
        relations: rover-to-object relations, N = R + K objects (rovers first).
        numerator: (E, R, N) from :func:`numerators`.

    Returns:
        (E, R, 8) float64 observations.
    """
    n_teams, n_rovers, n_objects = relations.delta_sq.shape
    term = numerator / relations.delta_sq
    # Scatter-add every term into its (team, rover, channel) cell with one bincount; the
    # channel is the quadrant, plus 4 for POIs.
    cell = _cell_base(n_teams, n_rovers, n_objects) + relations.quadrant
    obs = np.bincount(cell.ravel(), weights=term.ravel(), minlength=n_teams * n_rovers * OBS_DIM)
    return obs.reshape(n_teams, n_rovers, OBS_DIM)


def observe(
    rover_positions: np.ndarray,
    rover_headings: np.ndarray,
    poi_positions: np.ndarray,
    poi_values: np.ndarray,
    d_min: float,
) -> np.ndarray:
    """(E, R, 8) observations straight from positions (E, R, 2), headings (E, R), POI
    positions (E, K, 2) and values (E, K); see :func:`sense`."""
    relations = relate(rover_positions, rover_headings, poi_positions, d_min)
    return sense(relations, numerators(rover_positions.shape[1], poi_values))


# ----------------------------------------------------------------------------------------------
# Idealised motion (Section 4.1.2)
# ----------------------------------------------------------------------------------------------


def commanded_move(actions: np.ndarray, headings: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The paper's move (Fig. 3): (E, R, 2) rover-frame commands (forward, left) rotated into
    the world by the heading; the new heading is the move's direction, unchanged for a zero
    command. Returns the (E, R, 2) move and the (E, R) new headings. A plain loop."""
    move = np.empty(actions.shape)
    new_headings = np.array(headings, dtype=np.float64)
    for index in np.ndindex(headings.shape):
        fwd, left = (float(a) for a in actions[index])
        c, s = math.cos(headings[index]), math.sin(headings[index])
        move[index] = (c * fwd - s * left, s * fwd + c * left)
        if fwd != 0.0 or left != 0.0:
            new_headings[index] = math.atan2(move[index][1], move[index][0])
    return move, new_headings


class IdealMotion:
    """The idealised kinematics as a stateless model: ``step`` moves every rover."""

    def step(
        self, positions: np.ndarray, headings: np.ndarray, actions: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """New (E, R, 2) positions and (E, R) headings after clipped (E, R, 2) commands."""
        move, new_headings = commanded_move(actions, headings)
        return positions + move, new_headings


# ----------------------------------------------------------------------------------------------
# Scoring: Eqs. 11-13 and D (Eq. 1)
# ----------------------------------------------------------------------------------------------


def in_range(delta_sq_poi: np.ndarray, d_cap: float) -> np.ndarray:
    """Eq. 13: (E, R, K) bounded squared rover-POI distances -> (E, R, K) bool."""
    return delta_sq_poi <= d_cap * d_cap


def score_history(in_range_history: np.ndarray, poi_values: np.ndarray, n_req: int) -> dict:
    """Scores of whole episodes from a (T, E, R, K) in-range history (Eqs. 11-12, 1).

    POI k counts for G if at some step at least ``n_req`` rovers were in range of it; for
    G(z_-i), the same with rover i removed from every step. Returns G (E,), D (E, R),
    capture_step (E, K) (first step of capture, -1 if none) and captured_without (E, R, K).
    """
    history = np.asarray(in_range_history, dtype=np.int64)
    n_steps, n_teams, n_rovers, n_pois = history.shape
    values = np.broadcast_to(np.asarray(poi_values, dtype=np.float64), (n_teams, n_pois))
    count = history.sum(axis=2)  # (T, E, K)
    captured_at = count >= n_req
    captured = captured_at.any(axis=0)
    capture_step = np.where(captured, captured_at.argmax(axis=0), -1)
    without = ((count[:, :, None, :] - history) >= n_req).any(axis=0)  # (E, R, K)
    G = (values * captured).sum(-1)
    D = G[:, None] - (values[:, None, :] * without).sum(-1)
    return {"G": G, "D": D, "capture_step": capture_step, "captured_without": without}


def score_episode(
    in_range_history: np.ndarray, poi_values: np.ndarray, n_req: int
) -> tuple[np.ndarray, np.ndarray]:
    """G (E,) and D (E, R) of whole episodes from a (T, E, R, K) in-range history."""
    scores = score_history(in_range_history, poi_values, n_req)
    return scores["G"], scores["D"]


# ----------------------------------------------------------------------------------------------
# Policies (Section 4.2): n_in -> hidden -> 2, ReLU then tanh
# ----------------------------------------------------------------------------------------------


def policy_actions(genomes: np.ndarray, hidden: int, obs: np.ndarray,
                   activation: str = "relu") -> np.ndarray:  # fmt: skip
    """(E, R, 2) float32 actions of (E, R, P) genomes (layout ``W1 (n_in x H) | b1 | W2 |
    b2``) on (E, R, n_in) observations, by matrix products; a ReLU or tanh hidden layer."""
    layout = _PolicyWeights(hidden, obs.shape[-1])
    return layout.forward(layout.split(genomes), obs, activation)


class _PolicyWeights:
    def __init__(self, hidden, n_in, n_out=2):
        self.n_in, self.hidden, self.n_out = n_in, hidden, n_out
        sizes = [n_in * hidden, hidden, hidden * n_out, n_out]
        self.bounds = np.concatenate([[0], np.cumsum(sizes)])

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

    def forward(self, weights: tuple[np.ndarray, ...], obs: np.ndarray,
                activation: str = "relu") -> np.ndarray:  # fmt: skip
        """Actions from :meth:`split` weights of shape (E, R, ...) and (E, R, 8) observations:
        (E, R, 2) float32 in (-1, 1)."""
        w1, b1, w2, b2 = weights
        h = (obs[..., None, :].astype(np.float32) @ w1)[..., 0, :]
        h += b1
        if activation == "tanh":
            np.tanh(h, out=h)
        else:
            np.maximum(h, 0.0, out=h)
        out = (h[..., None, :] @ w2)[..., 0, :]
        out += b2
        return np.tanh(out, out=out)


# ----------------------------------------------------------------------------------------------
# Critics (Section 3): values (Eq. 2), aggregation (Eqs. 3-4), updates (Eqs. 6-10)
# ----------------------------------------------------------------------------------------------


def aggregate(values: np.ndarray, how: str) -> tuple[np.ndarray, np.ndarray]:
    """Eq. 3 (max) or Eq. 4 (mean) over the last axis, and its derivative by each value:
    ``1/T`` for the mean, 1 at the first maximum and 0 elsewhere for the max."""
    flat = values.reshape(-1, values.shape[-1])
    agg = np.empty(flat.shape[0], dtype=values.dtype)
    grad = np.zeros(flat.shape, dtype=values.dtype)
    for row in range(flat.shape[0]):
        if how == "mean":
            agg[row] = flat[row].mean()
            grad[row] = 1.0 / flat.shape[1]
        else:
            best = 0
            for t in range(1, flat.shape[1]):
                if flat[row, t] > flat[row, best]:
                    best = t
            agg[row], grad[row, best] = flat[row, best], 1.0
    return agg.reshape(values.shape[:-1]), grad.reshape(values.shape)


class CriticOracle:
    """The critics of :class:`physrover.learn.critics.FitnessCritic` in numpy: same
    parameters (copied from ``fc``), values by matrix products, gradients by the formula of
    the critics module, mini-batch steps one after another (SGD or Adam)."""

    def __init__(self, fc):
        self.settings = fc.settings
        self.W1, self.b1, self.b2 = (p.copy() for p in fc.critics.params())
        self.slope = np.float32(fc.settings.slope)
        self.optimizer = Optimizer(
            [self.W1, self.b1, self.b2], fc.settings.lr, fc.settings.optimizer
        )

    def __call__(self, x):
        """C for (R, N, D) pairs -> (R, N)."""
        return self._output(x, self._hidden(x))

    def _hidden(self, x: np.ndarray) -> np.ndarray:
        z = x @ self.W1  # (R, N, H) pre-activations
        z += self.b1[:, None, :]
        return z

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

    def errors_and_directions(
        self, items: np.ndarray, feedback: np.ndarray
    ) -> tuple[np.ndarray, list[np.ndarray]]:
        """delta (R, B) and the update direction ``sum_k delta_k grad`` (Eq. 7 or Eq. 9)."""
        if self.settings.update == "inexact":
            values, g = self.values_and_slopes(items)
            delta = feedback - values  # Eq. 10
            return delta, self.weighted_grad(items, delta, g)
        n_rovers, batch, steps, _ = items.shape
        pairs = items.reshape(n_rovers, batch * steps, items.shape[-1])
        values, g = self.values_and_slopes(pairs)
        F, dF = aggregate(values.reshape(n_rovers, batch, steps), self.settings.aggregation)
        delta = feedback - F  # Eq. 8
        u = (delta[..., None] * dF).reshape(n_rovers, batch * steps)
        return delta, self.weighted_grad(pairs, u, g)

    def update_with(self, all_items, all_feedback):
        """The mini-batches of (R, M, ...) items and (R, M) feedback, in order; mean delta^2."""
        s = self.settings
        losses = []
        for b in range(s.batches):
            part = slice(b * s.batch, (b + 1) * s.batch)
            items, feedback = all_items[:, part], all_feedback[:, part]
            delta, directions = self.errors_and_directions(items, feedback)
            self.optimizer.step(directions)
            losses.append(np.mean(delta**2))
        return float(np.mean(losses))


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


# ----------------------------------------------------------------------------------------------
# A whole episode, recomputed from a world's records
# ----------------------------------------------------------------------------------------------


def replay(world, commands):
    """Recompute an episode of a compiled ``RoverWorld`` from its records with the oracles.

    Starting from the world's state after reset (``position_history[0]``), the idealised
    motion is replayed from the (T, E, R, 2) ``commands`` given to the world (clipped as
    the world clips them; the world records them as float32); observations and scores are
    recomputed from the world's own position and heading histories (so a physical episode,
    moved by pymunk, is checked too). Returns a dict of positions (T + 1, E, R, 2),
    headings, observations (T, E, R, 8), G (E,), D (E, R), capture_step (E, K) and
    captured_without (E, R, K).
    """
    cfg, t = world.config, world.t
    positions = [world.position_history[0]]
    headings = [world.heading_history[0]]
    motion = IdealMotion()
    for step in range(t):
        action = np.clip(commands[step], -1.0, 1.0, dtype=np.float64)
        p, h = motion.step(positions[-1], headings[-1], action)
        positions.append(p)
        headings.append(h)
    numerator = numerators(world.n_rovers, world.poi_values)
    observations, ranges = [], []
    for step in range(t + 1):
        rel = relate(world.position_history[step], world.heading_history[step],
                     world.poi_positions, cfg.d_min)  # fmt: skip
        ranges.append(in_range(rel.delta_sq[:, :, world.n_rovers :], cfg.d_cap))
        observations.append(sense(rel, numerator).astype(np.float32))
    scores = score_history(np.stack(ranges), world.poi_values, cfg.n_req)
    return {
        "positions": np.stack(positions),
        "headings": np.stack(headings),
        "observations": np.stack(observations[: cfg.steps]),
        **scores,
    }


# -- the lab's CCEA options (issue 33), as plain loops ------------------------------------------


def plackett_luce_probability(order, fitness, temperature=1.0) -> float:
    """Probability that drawing without replacement with p proportional to exp(f / tau) among
    those left yields ``order`` (the lab's ``form_softmax_teams`` for one population)."""
    left = list(range(len(fitness)))
    p = 1.0
    for chosen in order:
        weights = [math.exp(fitness[i] / temperature) for i in left]
        p *= math.exp(fitness[chosen] / temperature) / sum(weights)
        left.remove(chosen)
    return p


def lab_softmax_order(fitness, rng) -> list:
    """One population's order as the lab draws it: team after team, ``choice`` among those
    left with p = softmax(fitness of those left)."""
    left = list(range(len(fitness)))
    order = []
    while left:
        f = np.array([fitness[i] for i in left])
        p = np.exp(f - f.max())
        j = rng.choice(len(left), p=p / p.sum())
        order.append(left.pop(j))
    return order


def evolve_elites_loops(pool, pool_fitness, k, n_elites, a, b, coin, hit, noise, scale,
                        pool_team_G=None, n_team_fitness=0):  # fmt: skip
    """:func:`physrover.learn.evolution.evolve_elites` with the same draws given as arrays:
    member indices ``a``, ``b`` (already distinct), ``coin`` (R, n_tour) uniforms, ``hit``
    (R, n_tour, P) mutation mask and ``noise`` the draws for the hit weights in C order;
    after the fitness elites, the ``n_team_fitness`` best by ``pool_team_G``."""
    n_pop, n = pool_fitness.shape
    out = np.empty((n_pop, k, pool.shape[2]), dtype=pool.dtype)
    carried = np.full((n_pop, k), np.nan)
    used = 0
    for r in range(n_pop):
        fit = [(-math.inf if math.isnan(f) else f) for f in pool_fitness[r]]
        ranked = sorted(range(n), key=lambda i: (-fit[i], i))
        if n_team_fitness:
            team = [(-math.inf if math.isnan(g) else g) for g in pool_team_G[r]]
            ranked = ranked[:n_elites] + sorted(range(n), key=lambda i: (-team[i], i))
        n_kept = n_elites + n_team_fitness
        for e in range(n_kept):
            out[r, e] = pool[r, ranked[e]]
            carried[r, e] = pool_fitness[r, ranked[e]]
        for t in range(k - n_kept):
            i, j = a[r, t], b[r, t]
            win = i if fit[i] > fit[j] or (fit[i] == fit[j] and coin[r, t] < 0.5) else j
            child = pool[r, win].copy()
            for p in range(child.shape[0]):
                if hit[r, t, p]:
                    child[p] += np.float32(scale * noise[used])
                    used += 1
            out[r, n_kept + t] = child
    return out, carried


def select_team_elites_loops(elite_genomes, elite_fitness, elite_G, population, team_index,
                             team_G, fitness, elite_team_G):  # fmt: skip
    """The n best teams by G among [elites | training teams], ties to the earlier one; each
    kept with its members' fitness and the G it had when it became an elite
    (``elite_team_G`` for an elite that stays)."""
    n = len(elite_G)
    candidates = [(elite_G[j], j, elite_genomes[j], elite_fitness[j], elite_team_G[j])
                  for j in range(n)]  # fmt: skip
    for m in range(len(team_G)):
        genomes = np.stack([population[r, team_index[m, r]] for r in range(population.shape[0])])
        member = np.array([fitness[r, team_index[m, r]] for r in range(population.shape[0])])
        candidates.append((team_G[m], n + m, genomes, member, team_G[m]))
    candidates.sort(key=lambda c: (-c[0], c[1]))
    best = candidates[:n]
    return tuple(np.stack([c[i] for c in best]) for i in (2, 3, 4))


# -- POI rules (issue 33, [[pois]]), as plain loops ---------------------------------------------


def score_rules_loops(positions, poi_positions, poi_values, radius, n_req, after, final,
                      scored_steps, removed=None, counted=None, require=None,
                      classes=None):  # fmt: skip
    """G of one team's episode under POI rules, rescored from positions with plain loops.

    ``positions`` (T + 1, R, 2) at every step, ``poi_positions`` (K, 2), ``poi_values``
    (K,), per POI its ``radius`` (a number, or a list of one per agent), coupling
    ``n_req``, predecessors ``after`` (lists of indices) and ``final`` (counts only at the
    last scored step); ``scored_steps`` the steps
    that count, in order; rover ``removed`` left out of every count (D's counterfactual),
    or a set of (t, i) left out of step t's; only the agents ``counted`` (default all) count;
    a POI with ``require[k]`` ({class index: count}) needs that many of each class (agent
    i's class ``classes[i]``), whoever counts otherwise.
    Returns (G, first capture step per POI, -1 if none).
    """
    n_pois = len(poi_values)
    first = [-1] * n_pois
    for t in scored_steps:
        for k in range(n_pois):
            if first[k] >= 0 or (final[k] and t != scored_steps[-1]):
                continue
            typed = require is not None and require[k]
            n, by_class = 0, {}
            for i in range(len(positions[t])):
                dx = poi_positions[k][0] - positions[t][i][0]
                dy = poi_positions[k][1] - positions[t][i][1]
                gone = (t, i) in removed if isinstance(removed, set) else i == removed
                if counted is not None and not counted[i] and not typed:
                    gone = True
                r = radius[k][i] if isinstance(radius[k], (list, tuple)) else radius[k]
                if not gone and dx * dx + dy * dy <= r * r:  # Eq. 13
                    n += 1
                    if typed:
                        by_class[classes[i]] = by_class.get(classes[i], 0) + 1
            ready = all(0 <= first[j] < t for j in after[k])
            if typed:
                met = all(by_class.get(c, 0) >= need for c, need in require[k].items())
            else:
                met = n >= n_req[k]
            if met and ready:
                first[k] = t
    G = sum(poi_values[k] for k in range(n_pois) if first[k] >= 0)
    return G, first


# -- agent classes (issue 33, [[agents]]): one idealised step, as plain loops -------------------


def classes_step(positions, headings, actions, classes, names):
    """One step of agents in classes (``classes[i]``: agent i's AgentClass; ``names`` the
    class names in order) from (R, 2) positions, (R,) headings and (R, 2) commands: the
    gate judged on the positions before the step, then clip, speed, frame, bounds. Returns
    new positions and headings (lists)."""
    free = []
    for i, own in enumerate(classes):
        near = [j for j in range(len(classes)) if j != i and classes[j].name in own.moves_with
                and math.dist(positions[i], positions[j]) <= own.moves_with_radius]  # fmt: skip
        free.append(not own.moves_with or bool(near))
    new_positions, new_headings = [], []
    for i, own in enumerate(classes):
        a = [min(max(float(v), -1.0), 1.0) * own.max_speed * free[i] for v in actions[i]]
        if own.action == "world":
            mx, my = a
        else:
            c, s = math.cos(headings[i]), math.sin(headings[i])
            mx, my = c * a[0] - s * a[1], s * a[0] + c * a[1]
        x, y = positions[i][0] + mx, positions[i][1] + my
        if own.bounds:
            x = min(max(x, own.bounds[0]), own.bounds[1])
            y = min(max(y, own.bounds[2]), own.bounds[3])
        new_positions.append((x, y))
        new_headings.append(math.atan2(my, mx) if (mx, my) != (0.0, 0.0) else headings[i])
    return new_positions, new_headings


def indirect_difference_loops(positions, score_args, influence_radius, counted, timescale,
                              rule="all-or-nothing", **typed):  # fmt: skip
    """ID (``timescale`` "trajectory") or ID-step ("step", who owns a step by ``rule``:
    "all-or-nothing", "local", "system", "difference") of one team's agents by plain
    loops: influence from the (T + 1, R, 2) ``positions`` at the scored steps, then each
    agent's removal set rescored with :func:`score_rules_loops` (``score_args``: its
    arguments after ``positions``)."""
    steps = score_args[-1]
    n = len(influence_radius)

    def influences(t, u, k):
        return (
            u != k
            and influence_radius[u] > 0
            and counted[k]
            and math.dist(positions[t][u], positions[t][k]) <= influence_radius[u]
        )

    G = score_rules_loops(positions, *score_args, counted=counted, **typed)[0]
    credit = []
    for a in range(n):
        removed = {(t, a) for t in steps}
        for k in range(n):
            if timescale == "trajectory":
                times = [sum(influences(t, u, k) for t in steps) for u in range(n)]
                if max(times) > 0 and times.index(max(times)) == a:
                    removed |= {(t, k) for t in steps}
            else:
                for t in steps:
                    near = [u for u in range(n) if influences(t, u, k)]
                    owns = {
                        "all-or-nothing": near[:1] == [a],
                        "local": a in near,
                        "system": bool(near),
                        "difference": near == [a],
                    }[rule]
                    if owns:
                        removed.add((t, k))
        G_without = score_rules_loops(positions, *score_args, removed=removed, counted=counted,
                                      **typed)  # fmt: skip
        credit.append(G - G_without[0])
    return credit


# -- the lab's code as it is written (AADILab/influence-shaping 8a71aa8) -------------------


def lab_captured(dist, agent_radius, capture_radius, poi_radius):
    """The lab's rule as it is written (AADILab/influence-shaping, ``custom_env.py``,
    ``AbstractRoverConstraint.captured``; ``capture_radius`` -1: the POI has none)."""
    if capture_radius != -1.0 and dist <= capture_radius:
        return True
    elif dist <= agent_radius and dist <= poi_radius:
        return True
    else:
        return False


def lab_step_value(positions, poi, counting, in_reach, coupling, removed=-1):
    """The lab's distance value of one POI at one step, as it is written
    (AADILab/influence-shaping ``custom_env.py``, ``AbstractRoverConstraint.
    _step_is_satisfied``): ``positions`` (R, 2) of the step, ``counting`` the agents of its
    type ("rover"), ``in_reach(i, dist)`` its ``captured``; agent ``removed`` (or a set of
    agents) is the lab's counterfactually removed one (at [-1, -1], which the lab reads as
    an infinite distance)."""
    count = 0
    dists = []
    constraint_satisfied = False
    for i, position in enumerate(positions):
        if counting[i]:
            gone = i in removed if isinstance(removed, (set, frozenset)) else i == removed
            if gone:
                dist = np.inf
            else:
                dist = np.linalg.norm([position[0] - poi[0], position[1] - poi[1]])
            dists.append(dist)
            if not gone and in_reach(i, dist):
                count += 1
                if count >= coupling:
                    constraint_satisfied = True
    if constraint_satisfied:
        dists.sort()
        dists = [max(1.0, dist) for dist in dists]
        constraint_value = float(coupling)
        for dist in dists[:coupling]:
            constraint_value = constraint_value * 1.0 / dist
        return constraint_value
    return 0.0


def lab_influence_sets(complete, i, timescale, credit):
    """The (t, k) that the lab leaves out (besides agent ``i``'s own trajectory) for agent
    ``i``'s IndirectDifference, from its ``complete_influence_array`` ``complete[t][u][k]``
    (0/1), as ``RewardComputer`` writes it (``computer.hpp``: ``prep_all_or_nothing_influence``
    for the trajectory, ``create_{local,allornothing,system,difference}_influence_array``
    for steps). One change, physrover's rule: AllOrNothing credits nobody where nobody
    influences k (the lab's ``highest_influence = -1`` credits agent 0: ``credit``
    "AllOrNothing-lab", the compatibility option, is the lab's as it is)."""
    n_steps, n = len(complete), len(complete[0])
    if timescale == "trajectory":
        counters = [[sum(complete[t][u][k] for t in range(n_steps)) for u in range(n)]
                    for k in range(n)]  # fmt: skip
        owned = []
        for k in range(n):
            highest_ind, num_influence = -1, 0
            for u in range(n):
                if counters[k][u] > num_influence:
                    num_influence, highest_ind = counters[k][u], u
            if highest_ind == i:
                owned.append(k)
        return {(t, k) for t in range(n_steps) for k in owned}
    removed = set()
    for t in range(n_steps):
        for k in range(n):
            if credit == "Local":
                hit = complete[t][i][k] == 1
            elif credit in ("AllOrNothing", "AllOrNothing-lab"):
                # physrover: nobody credited where nobody influences; the lab's code starts
                # at -1, so the first agent takes a (t, k) that nobody influenced
                i_credit, highest_influence = -1, (-1 if credit == "AllOrNothing-lab" else 0)
                for u in range(n):
                    if complete[t][u][k] > highest_influence:
                        i_credit, highest_influence = u, complete[t][u][k]
                hit = i_credit == i
            else:
                system = any(complete[t][u][k] == 1 for u in range(n))
                without_i = any(complete[t][u][k] == 1 for u in range(n) if u != i)
                hit = system if credit == "System" else (system and not without_i)
            if hit:
                removed.add((t, k))
    return removed


def coupled_score_loops(world, e, steps, extra_rover=-1, copies=1, removed=-1) -> float:
    """G of team ``e`` (Eqs. 11-13) by plain loops over the recorded positions, over the
    scored steps ``steps``, with rover ``removed`` left out and rover ``extra_rover``
    counted ``copies`` times (D's and D++'s counterfactuals)."""
    cfg = world.config
    hist, pois, values = world.position_history, world.poi_positions, world.poi_values
    n_req = cfg.n_req_per_poi
    total = 0.0
    for k in range(world.n_pois):
        for t in steps:
            n = 0
            for i in range(world.n_rovers):
                d = hist[t, e, i] - pois[e, k]
                if i != removed and d @ d <= cfg.d_cap**2:
                    n += copies if i == extra_rover else 1
            if n >= n_req[k]:
                total += values[e, k]
                break
    return total


def wandering_world(n_req, scored_states: str, action_seed: int):
    """8 teams of 6 rovers near 3 POIs (values 1, 2, 4; ring radius 3, capture radius 2),
    12 steps of uniform random actions: episodes where couplings form and fail."""
    from physrover.config import DomainConfig
    from physrover.domain.world import RoverWorld

    config = DomainConfig(n_rovers=6, n_req=n_req, poi_values=(1.0, 2.0, 4.0), steps=12,
                          d_cap=2.0, scored_states=scored_states)  # fmt: skip
    config = config.replace(poi_ring_radius=3.0)
    world = RoverWorld(config, 8)
    world.reset([np.random.default_rng(s) for s in range(8)])
    rng = np.random.default_rng(action_seed)
    for _ in range(config.steps):
        world.step(rng.uniform(-1, 1, (8, 6, 2)))
    return world
