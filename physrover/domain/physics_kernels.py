"""Compiled kernels of the physical model's controller (see :mod:`physrover.domain.physics`).

Everything the physical model computes around pymunk, in one call per physics step
(:func:`substep`): the drive and steering controller (velocity and heading setpoints
tracked with clipped force and torque) and the contacts between rovers and against the
static obstacles; and the angle wrapping. With walls or obstacles pymunk keeps the bodies,
integrates them and resolves the rovers' contacts with the static shapes, its state moving in
and out as one (E, R, 6) array per physics step; in open space the same integration runs
here too (:func:`integrate`, :func:`advance_compiled`: a whole environment step in one call).
"""

from __future__ import annotations

import math

import numpy as np

from physrover.core.compiled import jit
from physrover.domain.broadphase import GRID_MIN_POINTS, near_pairs
from physrover.domain.kernels import _move

CONTACT_SWEEPS = 20
"""Most sweeps of the contact pass per physics step in a team of up to 15 rovers (it stops
at the first sweep that changes nothing); larger teams get more (:func:`contact_sweeps`).
A column of 10 rovers driven into a box at 1 substep ends steps 16% overlapped with 10
sweeps, 5.7% with 20, 1.3% with 40; at the default 4 substeps 0.5-1% from 10 on
(``experiments/contacts.py``)."""


@jit
def contact_sweeps(n_rovers):
    """Most sweeps of the contact pass for a team of ``n_rovers``: :data:`CONTACT_SWEEPS`
    up to 15 rovers, growing with the team's width, ``ceil(20 sqrt(R / 15))`` (a push
    travels about a pair a sweep, and a jam is as deep as the team is wide): 52 at 100
    rovers, 164 at 1000. With 20 at 1000 rovers a team driven into its centre ended steps
    up to 8.9% overlapped (median 1.5% of the pairs in contact), with 200 0.7% (0.5%), as
    at 15 rovers (``experiments/contacts.py``, "converge"). A converged pass stops early,
    and revisits only the pairs whose velocities changed, so the cap costs only where a
    jam needs it."""
    return np.int64(math.ceil(CONTACT_SWEEPS * math.sqrt(max(n_rovers, 15) / 15.0)))


@jit
def wrap(angle):
    """An angle wrapped to [-pi, pi), as ``(angle + pi) % (2 pi) - pi``."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


@jit
def wrap_angles(angles, out):
    """``out = wrap(angles)`` elementwise for (E, R) arrays."""
    for e in range(angles.shape[0]):
        for i in range(angles.shape[1]):
            out[e, i] = wrap(angles[e, i])


@jit
def setpoints(actions, headings, cos_h, sin_h, max_speed, target_v, target_heading):
    """The step's setpoints from (E, R, 2) clipped commands and (E, R) headings (their
    cosines and sines ``cos_h``, ``sin_h``): the world velocity (E, R, 2), the idealised
    model's move (world units per step) scaled down to each rover's ``max_speed`` (R,; None:
    no limit) if longer, and the heading (E, R), its direction (the current heading for a
    zero command); the same arithmetic as the idealised step (``kernels._move``)."""
    for e in range(headings.shape[0]):
        for i in range(headings.shape[1]):
            mx, my, new_heading = _move(cos_h[e, i], sin_h[e, i], headings[e, i],
                                        actions[e, i, 0], actions[e, i, 1], True)  # fmt: skip
            if max_speed is not None:  # compiled out without a speed limit
                speed = math.hypot(mx, my)
                if speed > max_speed[i]:
                    mx, my = mx * (max_speed[i] / speed), my * (max_speed[i] / speed)
            target_v[e, i, 0] = mx
            target_v[e, i, 1] = my
            target_heading[e, i] = new_heading


@jit
def control(
    state, target_v, target_heading, first, dt, max_dv, max_dw, alpha_max, mass, moment, out
):
    """The controller of one physics step, for every rover (the module docstring of
    :mod:`physrover.domain.physics` gives the control law).

    Args:
        state: (E, R, 6) x, y, angle, vx, vy, w of the bodies now.
        target_v: (E, R, 2), target_heading: (E, R): the step's setpoints.
        max_dv, max_dw, alpha_max, mass, moment: (R,) each rover's limits per physics step
            and body (:class:`physrover.domain.physics.PhysicsMotion`).
        first: whether this is the step's first physics step: the drive acts as an impulse
            (written into the velocity, it moves the body within this physics step);
            afterwards as a force and torque (which Chipmunk applies after moving the body,
            so the next physics step's contact pass sees them before they move it).
        out: (E, R, 6) written: vx, vy, w, fx, fy, torque to set before ``Space.step``.
    """
    for e in range(state.shape[0]):
        for i in range(state.shape[1]):
            vx, vy, w = state[e, i, 3], state[e, i, 4], state[e, i, 5]
            dvx, dvy = target_v[e, i, 0] - vx, target_v[e, i, 1] - vy
            scale = min(1.0, max_dv[i] / max(math.hypot(dvx, dvy), 1e-300))
            dvx, dvy = dvx * scale, dvy * scale
            error = wrap(target_heading[e, i] - state[e, i, 2])
            sign = (error > 0.0) - (error < 0.0)
            magnitude = abs(error)
            target_w = sign * min(magnitude / dt, math.sqrt(2.0 * alpha_max[i] * magnitude))
            dw = min(max(target_w - w, -max_dw[i]), max_dw[i])
            if first:
                out[e, i, 0], out[e, i, 1], out[e, i, 2] = vx + dvx, vy + dvy, w + dw
                out[e, i, 3], out[e, i, 4], out[e, i, 5] = 0.0, 0.0, 0.0
            else:
                out[e, i, 0], out[e, i, 1], out[e, i, 2] = vx, vy, w
                out[e, i, 3] = dvx * (mass[i] / dt)
                out[e, i, 4] = dvy * (mass[i] / dt)
                out[e, i, 5] = dw * (moment[i] / dt)


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
    # out once. A pair is visited again only if one of its rovers' velocities changed since
    # its last visit (visit and change times on one clock): a skipped visit would have
    # computed the same approach speed and changed nothing, so the pass is the same, bit
    # for bit, as visiting every pair every sweep.
    changed_at = np.empty(n_rovers, np.int64)
    geometry = np.empty((near.shape[0], 3))  # each pair's nx, ny, limit
    visited_at = np.empty(near.shape[0], np.int64)
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
        visited_at[:n_near] = -1
        if contact is not None:
            for k in range(n_near):
                i, j = near[k, 0], near[k, 1]
                dx = positions[e, j, 0] - positions[e, i, 0]
                dy = positions[e, j, 1] - positions[e, i, 1]
                d = math.sqrt(dx * dx + dy * dy)
                geometry[k, 0], geometry[k, 1] = dx / d, dy / d
                geometry[k, 2] = (d - contact[i, j] + allowance) / dt
        changed_at[:] = -1
        clock = 0
        for _ in range(iterations):
            changed = False
            if contact is not None:  # compiled out without collisions
                for k in range(n_near):
                    i, j = near[k, 0], near[k, 1]
                    if max(changed_at[i], changed_at[j]) < visited_at[k]:
                        continue  # neither velocity changed since this pair's last visit
                    clock += 1
                    visited_at[k] = clock
                    nx, ny, limit = geometry[k, 0], geometry[k, 1], geometry[k, 2]
                    u = (velocities[e, i, 0] - velocities[e, j, 0]) * nx + (
                        velocities[e, i, 1] - velocities[e, j, 1]
                    ) * ny
                    if u > limit:
                        excess = u - limit
                        share_i = excess * (mass[j] / (mass[i] + mass[j]))
                        share_j = excess * (mass[i] / (mass[i] + mass[j]))
                        velocities[e, i, 0] -= share_i * nx
                        velocities[e, i, 1] -= share_i * ny
                        velocities[e, j, 0] += share_j * nx
                        velocities[e, j, 1] += share_j * ny
                        changed_at[i] = changed_at[j] = clock
                        changed = True
            if capsules is not None:
                for i in range(n_rovers):
                    if _capsule_contact(positions, velocities, e, i, radius[i], capsules, dt,
                                        allowance):  # fmt: skip
                        clock += 1
                        changed_at[i] = clock
                        changed = True
            if not changed:
                break


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


@jit
def substep(state, target_v, target_heading, first, dt, limits, contact, capsules, allowance,
            out):  # fmt: skip
    """Everything before one ``Space.step``, in one call: :func:`control`, then the
    contacts (:func:`speculative_contacts`, up to :func:`contact_sweeps` sweeps): between
    rovers unless ``contact`` is None (collisions off), against static capsules unless
    ``capsules`` is None. Both None arguments compile their branch out.

    Args:
        state: (E, R, 6) x, y, angle, vx, vy, w of the bodies now.
        target_v: (E, R, 2), target_heading: (E, R): the step's setpoints.
        first: whether this is the step's first physics step (see :func:`control`).
        dt: the physics step, in environment steps.
        limits: (6, R) per rover: max_dv, max_dw, alpha_max, mass, moment, radius.
        contact: (R, R) contact distances r_i + r_j, or None.
        capsules: (E, M, 5) walls' and obstacles' capsules in the space's frame, or None.
        allowance: the overlap a physics step may end with (Chipmunk's collision slop).
        out: (E, R, 6) written: vx, vy, w, fx, fy, torque to set before ``Space.step``.
    """
    max_dv, max_dw, alpha_max = limits[0], limits[1], limits[2]
    mass, moment, radius = limits[3], limits[4], limits[5]
    control(state, target_v, target_heading, first, dt, max_dv, max_dw, alpha_max, mass,
            moment, out)  # fmt: skip
    if contact is not None or capsules is not None:
        speculative_contacts(state[..., 0:2], out[..., 0:2], contact, mass, radius, capsules,
                             dt, allowance, contact_sweeps(state.shape[1]))  # fmt: skip


@jit
def integrate(state, out, dt, inv_mass, inv_moment):
    """Chipmunk's step of free bodies, in place: ``cpSpaceStep`` of a space with nothing to
    collide, no gravity and no damping, as Chipmunk writes it (``cpBodyUpdatePosition``,
    then ``cpBodyUpdateVelocity``; term by term, hence the ``+ 0.0`` of the zero bias
    velocities and gravity), so that it agrees with pymunk to the last bit (tested).

    Args:
        state: (E, R, 6) x, y, angle, vx, vy, w of the bodies, advanced by ``dt``.
        out: (E, R, 6) what :func:`substep` wrote: vx, vy, w, fx, fy, torque. Positions
            move with the written velocities (semi-implicit Euler: p + (v + v_bias) dt),
            then the velocities take the force's change (v + (g + f / m) dt).
        dt: the physics step, in environment steps.
        inv_mass, inv_moment: (R,) ``1 / mass`` and ``1 / moment`` (Chipmunk's m_inv, i_inv).
    """
    for e in range(state.shape[0]):
        for i in range(state.shape[1]):
            vx, vy, w = out[e, i, 0], out[e, i, 1], out[e, i, 2]
            state[e, i, 0] = state[e, i, 0] + (vx + 0.0) * dt
            state[e, i, 1] = state[e, i, 1] + (vy + 0.0) * dt
            state[e, i, 2] = state[e, i, 2] + (w + 0.0) * dt
            state[e, i, 3] = vx * 1.0 + (0.0 + out[e, i, 3] * inv_mass[i]) * dt
            state[e, i, 4] = vy * 1.0 + (0.0 + out[e, i, 4] * inv_mass[i]) * dt
            state[e, i, 5] = w * 1.0 + out[e, i, 5] * inv_moment[i] * dt


@jit
def advance_compiled(state, target_v, target_heading, substeps, dt, limits, contact, capsules,
                     allowance, out):  # fmt: skip
    """One environment step of the rovers in one call, pymunk nowhere: ``substeps`` times
    :func:`substep` (contacts with the static ``capsules`` too, unless None) then
    :func:`integrate`, in place on ``state`` (E, R, 6: x, y, angle, vx, vy, w); ``out``
    (E, R, 6) is scratch. The other arguments are :func:`substep`'s."""
    inv_mass, inv_moment = 1.0 / limits[3], 1.0 / limits[4]
    for k in range(substeps):
        substep(state, target_v, target_heading, k == 0, dt, limits, contact, capsules,
                allowance, out)  # fmt: skip
        integrate(state, out, dt, inv_mass, inv_moment)
