"""The physical model's one contact solver: speculative contacts between the rovers of a
team and against static capsules, resolved before every physics step
(:func:`speculative_contacts`, called by :func:`physrover.domain.motion.integrator.substep`).

The pairs it visits come from the broad phase (:mod:`physrover.domain.broadphase`); the
sweeps it may take grow with the team (:func:`contact_sweeps`).
"""

from __future__ import annotations

import math

import numpy as np

from physrover.core.compiled import jit, jit_inline
from physrover.domain.broadphase import GRID_MIN_POINTS, near_pairs

CONTACT_SWEEPS = 20
"""Most sweeps of the contact pass per physics step in a team of up to 15 rovers (it stops
at the first sweep that changes nothing); larger teams get more (:func:`contact_sweeps`).
A column of 10 rovers driven into a box at 1 substep ends steps 16% overlapped with 10
sweeps, 5.7% with 20, 1.3% with 40; at the default 4 substeps 0.5-1% from 10 on
(``benchmarks/contacts.py``)."""


@jit
def contact_sweeps(n_rovers):
    """Most sweeps of the contact pass for a team of ``n_rovers``: :data:`CONTACT_SWEEPS`
    up to 15 rovers, growing with the team's width, ``ceil(20 sqrt(R / 15))`` (a push
    travels about a pair a sweep, and a jam is as deep as the team is wide): 52 at 100
    rovers, 164 at 1000. With 20 at 1000 rovers a team driven into its centre ended steps
    up to 8.9% overlapped (median 1.5% of the pairs in contact), with 200 0.7% (0.5%), as
    at 15 rovers (``benchmarks/contacts.py``, "converge"). A converged pass stops early,
    and revisits only the pairs whose velocities changed, so the cap costs only where a
    jam needs it."""
    return np.int64(math.ceil(CONTACT_SWEEPS * math.sqrt(max(n_rovers, 15) / 15.0)))


@jit
def speculative_contacts(positions, velocities, contact, mass, radius, capsules, dt, allowance,
                         iterations):  # fmt: skip
    """Stop rovers from passing into each other and into static obstacles within one physics
    step, in place: the physical model's one contact solver (frictionless, inelastic).

    Chipmunk detects contacts between discrete positions: two rovers closing at more than a
    diameter per physics step can pass straight through each other, and slower impacts end a
    step deeply overlapped. Before each physics step, for every pair (i, j) of a team with
    centre distance d, normal n = (p_j - p_i) / d, closing speed u = (v_i - v_j) . n (world
    units per step) and contact distance c = r_i + r_j, the gap left after the step is
    ``d - c - u dt``. Where that is below ``-allowance``, the excess closing speed
    ``u - (d - c + allowance) / dt`` is removed along n, shared as momentum conservation
    shares it (rover i takes m_j / (m_i + m_j) of it: half each for equal masses): an
    inelastic speculative contact. Against a static capsule o (a segment A-B thickened by
    r_o; :mod:`physrover.domain.obstacles`), with C the point of A-B nearest the rover, d its
    distance and n the normal towards C, the rover alone loses the excess
    ``u - (d - r_i - r_o + allowance) / dt`` of its approach speed u = v_i . n.

    Each sweep visits the rover pairs in index order, then every rover against every
    capsule; up to ``iterations`` sweeps, until one changes nothing (a column of rovers
    driven into a wall passes the wall's push back along the column about a pair per
    sweep; sweeping in alternate directions did not converge faster). The pairs visited
    are those that could meet within the step, listed once per team (positions do not
    change during the pass) by :func:`physrover.domain.broadphase.near_pairs`: every pair
    is tested in small teams, a uniform grid finds them in large ones. Coincident centres
    (no normal) are skipped: the spawn separation keeps rovers apart.

    Args:
        positions: (E, R, 2) centres at the start of the physics step.
        velocities: (E, R, 2) the velocities the step will move them with, updated.
        contact: (R, R) contact distances r_i + r_j, or None: rovers do not collide.
        mass: (R,) the rovers' masses; radius: (R,) their radii.
        capsules: (E, M, 5) static capsules in the positions' frame, or None.
        dt: the physics step, in environment steps;
        allowance: the overlap a step may end with (Chipmunk's collision slop: walls and
            obstacles are also Chipmunk shapes, whose own contacts then hold).
    """
    n_teams, n_rovers = positions.shape[0], positions.shape[1]
    # The pairs within reach, in index order (the broad phase: every pair below
    # GRID_MIN_POINTS rovers, a grid from there; the same list either way).
    rows = n_rovers * (n_rovers - 1) // 2 if n_rovers < GRID_MIN_POINTS else 8 * n_rovers
    near = np.empty((max(rows, 1), 2), np.int64)
    widest = 0.0  # the widest contact distance, max r_i + r_j = 2 max r_i
    if contact is not None:
        for i in range(n_rovers):
            widest = max(widest, contact[i, i])
    # Positions do not move during the pass: each pair's normal and speed limit are worked
    # out once, and a pair is visited again only if one of its rovers' velocities changed
    # since its last visit: a skipped visit would have computed the same approach speed
    # and changed nothing, so the pass is the same, bit for bit, as visiting every pair
    # every sweep. Small teams check a pair's last visit against its rovers' last change
    # (_sweep_stamped); large ones (from GRID_MIN_POINTS), whose jams take up to
    # contact_sweeps sweeps, keep a bit per pair to visit (_sweep_marked), so a sweep
    # costs the pairs it visits, not every pair.
    track = n_rovers >= GRID_MIN_POINTS
    geometry = np.empty((near.shape[0], 3))  # each pair's nx, ny, limit
    changed_at = np.empty(n_rovers, np.int64)  # _sweep_stamped's clock times
    visited_at = np.empty(near.shape[0], np.int64)
    pair_start = np.empty(n_rovers + 1, np.int64)  # each rover's pairs (_pairs_by_rover)
    pair_of = np.empty(2 * near.shape[0] if track else 0, np.int64)
    dirty = np.empty(near.shape[0] // 64 + 1 if track else 0, np.uint64)  # pairs to visit
    for e in range(n_teams):
        n_near = 0  # the only pairs the sweeps visit
        if contact is not None:
            # Pairs farther apart than this cannot meet within the step.
            v_max_sq = 0.0
            for i in range(n_rovers):
                v_sq = velocities[e, i, 0] ** 2 + velocities[e, i, 1] ** 2
                v_max_sq = max(v_max_sq, v_sq)
            reach = widest + 2.0 * math.sqrt(v_max_sq) * dt
            n_near, near = near_pairs(positions[e], reach * reach, near)
        if near.shape[0] > geometry.shape[0]:  # the grid grew the list
            geometry = np.empty((near.shape[0], 3))
            visited_at = np.empty(near.shape[0], np.int64)
            pair_of = np.empty(2 * near.shape[0], np.int64)
            dirty = np.empty(near.shape[0] // 64 + 1, np.uint64)
        if contact is not None:
            for k in range(n_near):
                i, j = near[k, 0], near[k, 1]
                dx = positions[e, j, 0] - positions[e, i, 0]
                dy = positions[e, j, 1] - positions[e, i, 1]
                d = math.sqrt(dx * dx + dy * dy)
                geometry[k, 0], geometry[k, 1] = dx / d, dy / d
                geometry[k, 2] = (d - contact[i, j] + allowance) / dt
        if track:
            _pairs_by_rover(near, n_near, pair_start, pair_of)
            dirty[:] = 0
            for k in range(n_near):  # the first sweep visits every pair
                dirty[k >> 6] |= _ONE << np.uint64(k & 63)
        else:
            changed_at[:] = -1
            visited_at[:n_near] = -1
        clock = 0
        for _ in range(iterations):
            changed = False
            if contact is not None:  # compiled out without collisions
                if track:
                    changed = _sweep_marked(velocities, e, near, geometry, mass, dirty,
                                            pair_start, pair_of)  # fmt: skip
                else:
                    changed, clock = _sweep_stamped(velocities, e, near, n_near, geometry, mass,
                                                    changed_at, visited_at, clock)  # fmt: skip
            if capsules is not None:
                for i in range(n_rovers):
                    if _capsule_contact(positions, velocities, e, i, radius[i], capsules, dt,
                                        allowance):  # fmt: skip
                        if track:
                            _mark(i, dirty, pair_start, pair_of)
                        else:
                            clock += 1
                            changed_at[i] = clock
                        changed = True
            if not changed:
                break


_ONE = np.uint64(1)
_DE_BRUIJN = np.uint64(0x03F79D71B4CB0A89)


def _bit_table() -> np.ndarray:
    """The index of a lone set bit b, at ``(2^b * _DE_BRUIJN mod 2^64) >> 58``."""
    table = np.zeros(64, np.int64)
    for bit in range(64):
        table[((1 << bit) * int(_DE_BRUIJN) % 2**64) >> 58] = bit
    return table


_BIT_OF = _bit_table()


@jit
def _pairs_by_rover(near, n_near, pair_start, pair_of):
    """Each rover's pairs among the first ``n_near`` rows of ``near``, ascending, written
    as ``pair_of[pair_start[i]:pair_start[i + 1]]`` (``pair_start`` (R + 1,), ``pair_of``
    at least 2 ``n_near`` long)."""
    pair_start[:] = 0
    for k in range(n_near):
        pair_start[near[k, 0] + 1] += 1
        pair_start[near[k, 1] + 1] += 1
    for i in range(pair_start.shape[0] - 1):
        pair_start[i + 1] += pair_start[i]
    for k in range(n_near):  # pair_start[i] runs ahead as i's pairs are written ...
        for i in (near[k, 0], near[k, 1]):
            pair_of[pair_start[i]] = k
            pair_start[i] += 1
    for i in range(pair_start.shape[0] - 1, 0, -1):  # ... and is moved back
        pair_start[i] = pair_start[i - 1]
    pair_start[0] = 0


@jit_inline
def _mark(i, dirty, pair_start, pair_of):
    """Rover i's velocity changed: each of its pairs is to be visited again."""
    for slot in range(pair_start[i], pair_start[i + 1]):
        k = pair_of[slot]
        dirty[k >> 6] |= _ONE << np.uint64(k & 63)


@jit_inline
def _resolve(velocities, e, k, near, geometry, mass):
    """Pair k of team e (:func:`speculative_contacts`): the excess of its approach speed
    over its limit removed, shared by mass; returns whether there was any."""
    i, j = near[k, 0], near[k, 1]
    nx, ny, limit = geometry[k, 0], geometry[k, 1], geometry[k, 2]
    u = (velocities[e, i, 0] - velocities[e, j, 0]) * nx + (
        velocities[e, i, 1] - velocities[e, j, 1]
    ) * ny
    if u <= limit:
        return False
    excess = u - limit
    share_i = excess * (mass[j] / (mass[i] + mass[j]))
    share_j = excess * (mass[i] / (mass[i] + mass[j]))
    velocities[e, i, 0] -= share_i * nx
    velocities[e, i, 1] -= share_i * ny
    velocities[e, j, 0] += share_j * nx
    velocities[e, j, 1] += share_j * ny
    return True


@jit_inline
def _sweep_stamped(velocities, e, near, n_near, geometry, mass, changed_at, visited_at, clock):
    """One sweep of :func:`speculative_contacts` over team e's first ``n_near`` pairs, in
    index order, skipping each pair whose rovers' velocities last changed
    (``changed_at``) before its last visit (``visited_at``), both on one ``clock`` that
    ticks at every visit; returns (whether any approach speed was removed, the clock)."""
    changed = False
    for k in range(n_near):
        i, j = near[k, 0], near[k, 1]
        if max(changed_at[i], changed_at[j]) < visited_at[k]:
            continue  # neither velocity changed since this pair's last visit
        clock += 1
        visited_at[k] = clock
        if _resolve(velocities, e, k, near, geometry, mass):
            changed_at[i] = changed_at[j] = clock
            changed = True
    return changed, clock


@jit_inline
def _sweep_marked(velocities, e, near, geometry, mass, dirty, pair_start, pair_of):
    """One sweep of :func:`speculative_contacts` over team e's pairs whose bit is set in
    ``dirty``, in index order; returns whether any approach speed was removed. A pair that
    acts marks its rovers' pairs (:func:`_mark`): those after it are visited in this
    sweep, those before it (and itself) in the next, as a sweep over every pair would
    meet them."""
    changed = False
    for w in range(dirty.shape[0]):
        done = np.uint64(0)  # this word's bits up to the last visited one
        while True:
            word = dirty[w] & ~done
            if word == 0:
                break
            low = word & (~word + _ONE)  # the lowest set bit
            done |= (low - _ONE) | low
            dirty[w] &= ~low
            k = w * 64 + _BIT_OF[(low * _DE_BRUIJN) >> np.uint64(58)]
            if _resolve(velocities, e, k, near, geometry, mass):
                _mark(near[k, 0], dirty, pair_start, pair_of)
                _mark(near[k, 1], dirty, pair_start, pair_of)
                changed = True
    return changed


@jit
def _capsule_contact(positions, velocities, e, i, radius, capsules, dt, allowance):
    """Rover i of team e against every capsule of ``capsules[e]`` (see
    :func:`speculative_contacts`), in place; whether any approach speed was removed."""
    changed = False
    px, py = positions[e, i, 0], positions[e, i, 1]
    for o in range(capsules.shape[1]):
        ax, ay = capsules[e, o, 0], capsules[e, o, 1]
        abx, aby = capsules[e, o, 2] - ax, capsules[e, o, 3] - ay
        length_sq = abx * abx + aby * aby
        t = 0.0
        if length_sq > 0.0:
            t = min(max(((px - ax) * abx + (py - ay) * aby) / length_sq, 0.0), 1.0)
        dx = (ax + t * abx) - px
        dy = (ay + t * aby) - py
        d = math.sqrt(dx * dx + dy * dy)
        if d < 1e-12:
            continue
        nx, ny = dx / d, dy / d
        u = velocities[e, i, 0] * nx + velocities[e, i, 1] * ny
        limit = (d - radius - capsules[e, o, 4] + allowance) / dt
        if u > limit:
            velocities[e, i, 0] -= (u - limit) * nx
            velocities[e, i, 1] -= (u - limit) * ny
            changed = True
    return changed
