"""Compiled kernels of the physical model's controller (see
:mod:`physrover.domain.motion.physics`).

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
from physrover.domain.agents.roles import class_command, gate_free, pick_moves
from physrover.domain.motion.contacts import contact_sweeps, speculative_contacts
from physrover.domain.motion.ideal import ideal_move


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
def setpoints(actions, positions, headings, cos_h, sin_h, max_speed, roles, target_v,
              target_heading):  # fmt: skip
    """The step's setpoints from (E, R, 2) clipped commands and (E, R) headings (their
    cosines and sines ``cos_h``, ``sin_h``): the world velocity (E, R, 2), the idealised
    model's move (world units per step; an agent class's move under ``roles``, a
    :class:`~physrover.domain.agents.roles.Roles` or None, its gate judged from the (E, R,
    2) ``positions`` before the step) scaled down to each rover's ``max_speed`` (R,; None:
    no limit) if longer, and the heading (E, R), its direction (the current heading for a
    zero command): the same arithmetic as the idealised step
    (:mod:`physrover.domain.motion.ideal`)."""
    free = np.ones(headings.shape[1], dtype=np.bool_)
    for e in range(headings.shape[0]):
        if roles is not None:
            gate_free(e, positions, roles, free)
            pick_moves(e, positions, actions, roles)
        for i in range(headings.shape[1]):
            fwd, left = actions[e, i, 0], actions[e, i, 1]
            c, s = cos_h[e, i], sin_h[e, i]
            if roles is not None:
                fwd, left, c, s = class_command(i, fwd, left, free, roles, c, s)
            mx, my, new_heading = ideal_move(c, s, headings[e, i], fwd, left, True)
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
    :mod:`physrover.domain.motion.physics` gives the control law).

    Args:
        state: (E, R, 6) x, y, angle, vx, vy, w of the bodies now.
        target_v: (E, R, 2), target_heading: (E, R): the step's setpoints.
        max_dv, max_dw, alpha_max, mass, moment: (R,) each rover's limits per physics step
            and body (:class:`physrover.domain.motion.physics.PhysicsMotion`).
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
