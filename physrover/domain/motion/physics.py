"""Physical rover motion: rigid bodies with mass, finite force and torque, optional collisions.

Every rover is a rigid disc body (radius ``rover_radius``, mass ``rover_mass``, the moment
of inertia of a disc); these, ``max_force``, ``max_torque`` and ``max_speed`` may differ
from rover to rover (a list per rover in [physics]: a heterogeneous team). All E teams live
in **one** frame, each team in its own cell of a grid whose spacing exceeds the distance
rovers can travel in an episode, so teams never touch.

Who integrates the bodies (``[physics] integrator``): with walls or obstacles, pymunk: every
rover is a dynamic ``pymunk.Body`` with a circle shape in one ``pymunk.Space``, and state
moves in and out of the space with ``pymunk.batch`` as arrays, never with a Python loop over
rovers or teams. In open space (the default scenario) a pymunk step of bodies that have
nothing to collide with is semi-implicit Euler and nothing else, so the same arithmetic
runs compiled (:func:`physrover.domain.motion.integrator.integrate`, a whole environment step
in one call) and gives pymunk's trajectories to the last bit (tested against pymunk, with
and without rover contacts, for equal and mixed bodies; pymunk's x86-64 wheels use no fused
multiply-adds, which a build for another CPU might, changing last bits) in half the time:
until physrover 0.4 more than half of the physical step was moving state in and out of
pymunk. ``integrator = "pymunk"`` steps pymunk in open space too; ``integrator =
"compiled"`` never uses pymunk, leaving the contacts with walls and obstacles to the
compiled pass alone (below), which holds them as well in ``benchmarks/contacts.py`` (a
column of rovers into a box or the walls: 0.6% and 0.5% worst overlap at 4 substeps either
way, 7.1% and 5.4% against 5.8% and 5.6% at 1; a rover against the walls stays within the
slop, 0.002 units, either way) in a third of the time (a walled 50-team episode 42 against
117 ms), but its trajectories with walls or obstacles are not pymunk's.

Units: lengths in world units, time in environment steps (one step = 1 time unit, split
into ``substeps`` physics steps of ``dt = 1 / substeps``), forces in mass x units / step^2.

The controller (the convention of this testbed, to compare against the paper's kinematics)
---------------------------------------------------------------------------------------
The action ``(a_x, a_y)`` is an **orientation-relative velocity command**: at the start of
the step it is rotated by the rover's heading into a world-frame velocity setpoint
``v* = R(heading) a`` (world units per step, so a command held for a step covers at most the
idealised rover's displacement; scaled down to ``max_speed`` if longer), and the heading
setpoint is the direction of ``v*`` (unchanged for a zero command), as in the idealised
model. Both setpoints are held for the
step. In every physics step:

- the drive force is ``F = m (v* - v) / dt`` with its norm clipped to ``max_force``;
- the steering torque is ``T = I (w* - w) / dt`` clipped to ``max_torque``, with the target
  spin ``w* = sign(e) min(|e| / dt, sqrt(2 alpha_max |e|))`` for the heading error ``e``
  (the fastest approach that can still brake without overshoot, ``alpha_max = max_torque / I``).

The force and torque are applied as the velocity change they cause over the physics step
(``dv = F dt / m``, written into the velocity) *before* the physics step, at its first
physics step: chipmunk integrates positions before velocities, so a force written to
``Body.force`` would move the body only one physics step later (later physics steps of the
environment step apply it as a force; :func:`physrover.domain.motion.integrator.control`).
Applied this way, the integration is semi-implicit Euler and, in the limit of unbounded
force with one substep, a physical rover follows the idealised trajectory exactly (tested).
With finite force a rover needs several steps to reach full speed, and its speed never
exceeds the command (the velocity moves along the segment towards ``v*``).

Contacts are resolved by one compiled pass before every physics step
(:func:`physrover.domain.motion.contacts.speculative_contacts`), between the rovers of a
team (switched by ``collisions``) and between rovers and the static obstacles and walls:
it removes the closing speed that would carry a pair into overlap within the step, shared
between two rovers as momentum conservation shares it, all from a static obstacle's side:
frictionless, inelastic contacts, resolved *before* the impact rather than after it (a
speculative contact in a sequential-impulse solver, sweeping rover pairs then rovers
against obstacles until nothing changes, at most 20 sweeps up to 15 rovers and more in
larger teams, ``contact_sweeps``; the pairs from a grid in large teams). Chipmunk, which
detects contacts between discrete positions, lets rovers closing at more than a
diameter per physics step pass through each other; the pass holds at any number of
substeps (``benchmarks/contacts.py``: no pass-through head-on at any impact phase, worst
overlap at a step end ~1% of a diameter in crowds, 0.0% in steady pushing, 0.6% for a
column of rovers driven into a box or a wall at the default 4 substeps, 5.8% at 1). Until
physrover 0.3, Chipmunk also collided the rovers' shapes with each other after the pass;
in open space that changed nothing measurable in contact accuracy and was most of
``Space.step``'s cost, so rovers are pymunk shapes now
only when there is something static to hit: the scenario's obstacles (static discs, boxes
and segments, :mod:`physrover.domain.obstacles`) and the walls (``walls``, static segments
of a square of half side ``wall_half_size``) are pymunk shapes too, and Chipmunk's
contacts with them hold what the pass leaves within its slop. POIs are not bodies. With
collisions on, spawn positions that overlap are pushed apart (deterministically) before
the episode starts.

Determinism: pymunk caches contact impulses between steps (warm starting). With walls or
obstacles, on every reset the rovers are first parked apart and the space is stepped
``collision_persistence`` times, which drops every cached contact, and the spatial hash
index (rebuilt from the current positions each step, unlike the default tree, whose shape
depends on history) makes the order of contacts a function of the positions alone. The
same seed thus gives bit-identical episodes whatever ran before (tested); building a fresh
space instead costs ~20 ms per reset.
"""

from __future__ import annotations

import math

import numpy as np
import pymunk
import pymunk.batch as pb

from physrover.config import DomainConfig
from physrover.config.domain import extent_of
from physrover.domain.agents.roles import Roles
from physrover.domain.motion.dynamics import Dynamics, register_dynamics
from physrover.domain.motion.ideal import heading_trig
from physrover.domain.motion.integrator import advance_compiled, setpoints, substep, wrap_angles
from physrover.domain.motion.separation import separate
from physrover.domain.obstacles import box_corners

_ROVER = 0b01
_WALL = 0b10
_STATE = pb.BodyFields.POSITION | pb.BodyFields.ANGLE  # 3 floats per body: x, y, angle
_MOTION = pb.BodyFields.VELOCITY | pb.BodyFields.ANGULAR_VELOCITY  # vx, vy, w
_ALL = _STATE | _MOTION  # x, y, angle, vx, vy, w
_FORCES = pb.BodyFields.FORCE | pb.BodyFields.TORQUE  # fx, fy, torque


_EVERY = slice(None)
"""Every team's rows (a basic slice: views, the arrays a step without a mask writes)."""


def _rows(teams: np.ndarray | None, uses_pymunk: bool):
    """The rows of the teams a reset or step moves: every team, or the (E,) bool mask
    ``teams``, which pymunk cannot honour (one space holds every team's bodies and their
    contacts' caches)."""
    if teams is None:
        return _EVERY
    if uses_pymunk:
        raise ValueError("the physical model with walls or obstacles (pymunk) resets and "
                         "steps all teams together, not some alone")  # fmt: skip
    return np.asarray(teams, dtype=bool)


@register_dynamics
class PhysicsMotion(Dynamics):
    """Physical motion for E teams of R rovers in one frame (one pymunk space when pymunk
    steps them); see the module docstring.

    Its parameters are the domain's [physics] table (:class:`~physrover.config.PhysicsConfig`).
    """

    name = "physics"
    obstacles = True

    def __init__(self, config: DomainConfig, n_teams: int):
        self.config = config
        self.n_teams, self.n_rovers = n_teams, config.n_rovers
        self.dt = 1.0 / config.physics.substeps
        # Per rover (R,): a heterogeneous team's bodies and limits (a scalar means all).
        p, n = config.physics, config.n_rovers
        self.radius = p.per_rover("rover_radius", n)
        self.mass = p.per_rover("rover_mass", n)
        self.moment = np.array([pymunk.moment_for_circle(m, 0.0, r)
                                for m, r in zip(self.mass, self.radius, strict=True)])  # fmt: skip
        self.max_dv = p.per_rover("max_force", n) * self.dt / self.mass  # per physics step
        self.max_dw = p.per_rover("max_torque", n) * self.dt / self.moment
        self.alpha_max = p.per_rover("max_torque", n) / self.moment
        max_speed = p.per_rover("max_speed", n)
        self.max_speed = max_speed if np.isfinite(max_speed).any() else None
        self.roles = Roles.build(config)  # agent classes' speeds, frames and gates
        self.contact = self.radius[:, None] + self.radius[None, :]  # (R, R) contact distances

        self.offsets = self._team_offsets()  # (E, 1, 2) world origin of each team's cell
        # Contacts may end a physics step overlapped by this much (Chipmunk's collision slop).
        self.slop = 0.01 * float(self.radius.min())
        # (E, M, 5) the obstacles' and walls' capsules in the space's frame, for the pass
        capsules = config.scenario.obstacle_capsules()
        if config.physics.walls:
            capsules = np.concatenate([capsules.reshape(-1, 5), self._wall_capsules()])
        self.capsules = None
        if len(capsules):
            self.capsules = np.repeat(capsules[None], n_teams, axis=0)
            self.capsules[..., 0:2] += self.offsets
            self.capsules[..., 2:4] += self.offsets
        # (6, R) what the compiled controller needs per rover; contacts only with collisions
        self.limits = np.stack([self.max_dv, self.max_dw, self.alpha_max, self.mass,
                                self.moment, self.radius])  # fmt: skip
        self.contact_distances = self.contact if config.physics.collisions else None
        # pymunk steps the bodies when there is something static to hit ("auto") or always
        # ("pymunk"); otherwise the compiled step does, on this (E, R, 6) array in the same
        # frame as the space's (team cells apart), so in open space the two agree to the
        # last bit.
        integrator = config.physics.integrator
        self.uses_pymunk = integrator == "pymunk" or (
            integrator == "auto" and self.capsules is not None
        )
        self._free = np.zeros((n_teams, config.n_rovers, 6))  # x, y, angle, vx, vy, w
        self._scratch = np.zeros((n_teams, config.n_rovers, 6))
        self.space = self._build_space() if self.uses_pymunk else None

    def _build_space(self) -> pymunk.Space:
        """The pymunk space of every team's bodies (and shapes when there are walls or
        obstacles), and the array pymunk.batch writes them from."""
        config, n = self.config, self.n_rovers
        space = pymunk.Space()
        space.iterations = config.physics.solver_iterations
        space.collision_slop = self.slop
        # Rebuilt from positions every step: pair order independent of history (see above).
        space.use_spatial_hash(4.0 * float(self.radius.max()), 4 * self.n_teams * n + 1)
        static = []
        if config.physics.walls:
            static += self._walls(space.static_body)
        static += self._obstacles(space.static_body)
        # Rovers are shapes only when there is something static to hit: rover-rover
        # contacts are the compiled pass's alone (see the module docstring).
        rover_filter = pymunk.ShapeFilter(categories=_ROVER, mask=_WALL)
        bodies, shapes = [], []
        origins = self.offsets.reshape(-1, 2).repeat(n, axis=0)
        for k, origin in enumerate(origins):
            i = k % n  # the rover's index in its team
            body = pymunk.Body(float(self.mass[i]), float(self.moment[i]))
            body.position = tuple(origin)
            bodies.append(body)
            if static:
                shape = pymunk.Circle(body, float(self.radius[i]))
                shape.filter = rover_filter
                shape.elasticity = 0.0
                shape.friction = 0.0
                shapes.append(shape)
        space.add(*bodies, *shapes, *static)
        self._static_shapes = bool(static)
        self._buffer = pb.Buffer()
        # Everything written to the space goes through one array, 6 floats per body of the
        # space as pymunk.batch counts them: the rovers, then the space's static body (at
        # rest at the origin), which pymunk adds to the space once anything has read
        # ``space.static_body``; set_space_bodies would otherwise read past the array.
        pb.get_space_bodies(space, pb.BodyFields.ANGLE, self._buffer)
        self._written = np.zeros(6 * (len(self._buffer.float_buf()) // 8))
        if len(self._written) < 6 * self.n_teams * n:
            raise RuntimeError("pymunk.batch does not see every rover body")
        self._set_buffer = pb.Buffer()
        self._set_buffer.set_float_buf(self._written)
        return space

    # -- layout ------------------------------------------------------------------------------

    def _team_offsets(self) -> np.ndarray:
        cfg = self.config
        if cfg.physics.walls:
            reach = cfg.physics.wall_half_size
        else:  # the farthest a rover can get: commanded speed <= sqrt(2) per step, margin 2x
            reach = extent_of(cfg.scenario, cfg.n_rovers) + 2.0 * math.sqrt(2) * cfg.steps
        spacing = 2.0 * reach + 4.0 * float(self.radius.max()) + 1.0
        cols = math.ceil(math.sqrt(self.n_teams))
        index = np.arange(self.n_teams)
        grid = np.stack([index % cols, index // cols], axis=-1).astype(np.float64)
        return (spacing * grid)[:, None, :]

    def _wall_capsules(self) -> np.ndarray:
        """(4, 5) the walls, world frame: the sides of the square of half side
        ``wall_half_size``, counter-clockwise, as segments of radius 0.05."""
        h = self.config.physics.wall_half_size
        corners = [(-h, -h), (h, -h), (h, h), (-h, h)]
        return np.array([[*corners[k], *corners[(k + 1) % 4], 0.05] for k in range(4)])

    def _walls(self, static_body: pymunk.Body) -> list[pymunk.Segment]:
        wall_filter = pymunk.ShapeFilter(categories=_WALL, mask=_ROVER)
        walls = []
        for ox, oy in self.offsets.reshape(-1, 2):
            for ax, ay, bx, by, r in self._wall_capsules():
                seg = pymunk.Segment(static_body, (ox + ax, oy + ay), (ox + bx, oy + by), r)
                seg.filter = wall_filter
                seg.elasticity = 0.0
                seg.friction = 0.0
                walls.append(seg)
        return walls

    def _obstacles(self, static_body: pymunk.Body) -> list[pymunk.Shape]:
        """The scenario's static discs, boxes and segments in every team's cell; rovers
        collide with them."""
        obstacle_filter = pymunk.ShapeFilter(categories=_WALL, mask=_ROVER)
        scenario = self.config.scenario
        shapes = []
        for ox, oy in self.offsets.reshape(-1, 2):
            for x, y, r in scenario.obstacles():
                shapes.append(pymunk.Circle(static_body, r, (ox + x, oy + y)))
            for box in scenario.boxes():
                corners = [(ox + x, oy + y) for x, y in box_corners(box)]
                shapes.append(pymunk.Poly(static_body, corners))
            for ax, ay, bx, by, r in scenario.segments():
                shapes.append(pymunk.Segment(static_body, (ox + ax, oy + ay),
                                             (ox + bx, oy + by), r))  # fmt: skip
        for shape in shapes:
            shape.filter = obstacle_filter
            shape.elasticity = 0.0
            shape.friction = 0.0
        return shapes

    # -- batch I/O ---------------------------------------------------------------------------

    # pymunk.batch reads and writes every body of the space: the rovers, then the space's
    # static body once any static shape (walls, obstacles) is attached to it. Reads drop the
    # static body; writes leave it at rest at the origin (the tail of ``_written``).

    def _get(self, fields: pb.BodyFields, width: int) -> np.ndarray:
        self._buffer.clear()
        pb.get_space_bodies(self.space, fields, self._buffer)
        n = self.n_teams * self.n_rovers * width
        return np.frombuffer(self._buffer.float_buf(), dtype=np.float64)[:n].reshape(
            self.n_teams, self.n_rovers, width
        )

    def _set(self, fields: pb.BodyFields, values: np.ndarray | None = None) -> None:
        """Write 6 floats per rover (``values`` (E, R, 6); None: already in ``_bodies()``)."""
        if values is not None:
            self._bodies()[:] = values
        pb.set_space_bodies(self.space, fields, self._set_buffer)

    def _bodies(self) -> np.ndarray:
        """(E, R, 6) the rovers' part of the array written to the space."""
        n = self.n_teams * self.n_rovers * 6
        return self._written[:n].reshape(self.n_teams, self.n_rovers, 6)

    def state(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """World positions (E, R, 2), headings (E, R), velocities (E, R, 2), spins (E, R)."""
        s = self._get(_ALL, 6) if self.uses_pymunk else self._free.copy()
        return (
            s[..., 0:2] - self.offsets,
            self._wrapped(s[..., 2]),
            s[..., 3:5].copy(),
            s[..., 5].copy(),
        )

    # -- motion model interface --------------------------------------------------------------

    def reset(self, state, teams: np.ndarray | None = None) -> None:
        """Place the rovers of ``state`` at rest (overlapping spawns pushed apart); of the
        ``teams`` (an (E,) bool mask) only, if given (compiled in open space only)."""
        rows = _rows(teams, self.uses_pymunk)
        state.rover_positions[rows] = self._place(state.rover_positions[rows],
                                                  state.rover_headings[rows], rows)  # fmt: skip
        state.rover_velocities[rows] = 0.0
        heading_trig(state.rover_headings, state.cos_h, state.sin_h)

    def step(self, state, actions: np.ndarray, teams: np.ndarray | None = None) -> None:
        """Advance one environment step under the (E, R, 2) clipped commands; the ``teams``
        (an (E,) bool mask) only, if given (compiled in open space only)."""
        rows = _rows(teams, self.uses_pymunk)
        positions, headings, velocities = self.advance(state, actions, rows)
        state.rover_positions[rows] = positions
        state.rover_headings[rows] = headings
        state.rover_velocities[rows] = velocities
        heading_trig(state.rover_headings, state.cos_h, state.sin_h)

    def _place(self, positions: np.ndarray, headings: np.ndarray, rows=_EVERY) -> np.ndarray:
        """Put the rovers of the teams ``rows`` at rest at ``positions`` (pushed apart if
        they overlap and collisions are on), facing ``headings``; returns the positions
        used."""
        cfg = self.config
        if cfg.physics.collisions:
            # r_i + r_j: symmetric by construction (floating-point addition commutes)
            positions = separate(positions, self.contact, self.slop, symmetric=True)
        start = np.zeros((len(positions), self.n_rovers, 6))
        start[..., :2] = positions + self.offsets[rows]
        start[..., 2] = headings
        if not self.uses_pymunk:
            self._free[rows] = start
            return positions
        if self._static_shapes:  # drop every cached contact: park apart, let them expire
            park = np.zeros((self.n_teams, self.n_rovers, 6))
            park[..., 0] = 4.0 * float(self.radius.max()) * np.arange(self.n_rovers)
            park[..., :2] += self.offsets
            self._set(_ALL, park)
            for _ in range(self.space.collision_persistence + 1):
                self.space.step(1e-6)
        self._set(_ALL, start)
        return positions

    def advance(self, state, actions: np.ndarray,
                rows=_EVERY) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # fmt: skip
        """Step the bodies of the teams ``rows`` (every team, or a mask where pymunk does
        not step them) through one environment step from ``state``'s headings (and their
        cosines and sines) under the clipped ``actions`` (E, R, 2); returns their new
        positions, headings and velocities (world units per step), new arrays."""
        cfg, dt = self.config, self.dt
        every = rows is _EVERY  # else a mask: a copy of those teams' rows, written back
        s = self._free if every else self._free[rows]
        shape = (len(s), self.n_rovers)
        target_v, target_heading = np.empty((*shape, 2)), np.empty(shape)
        setpoints(actions[rows], state.rover_positions[rows], state.rover_headings[rows],
                  state.cos_h[rows], state.sin_h[rows], self.max_speed, self.roles,
                  target_v, target_heading)  # fmt: skip
        if self.uses_pymunk:
            out = self._bodies()
            for k in range(cfg.physics.substeps):
                s = self._get(_ALL, 6)  # x, y, angle, vx, vy, w
                substep(s, target_v, target_heading, k == 0, dt, self.limits,
                        self.contact_distances, self.capsules, self.slop, out)  # fmt: skip
                self._set(_MOTION | _FORCES)
                self.space.step(dt)
            s = self._get(_ALL, 6)
        else:
            capsules = None if self.capsules is None else self.capsules[rows]
            advance_compiled(s, target_v, target_heading, cfg.physics.substeps, dt,
                             self.limits, self.contact_distances, capsules, self.slop,
                             self._scratch if every else np.zeros_like(s))  # fmt: skip
            if not every:
                self._free[rows] = s
        return s[..., 0:2] - self.offsets[rows], self._wrapped(s[..., 2]), s[..., 3:5].copy()

    def _wrapped(self, angles: np.ndarray) -> np.ndarray:
        out = np.empty(angles.shape)
        wrap_angles(angles, out)
        return out
