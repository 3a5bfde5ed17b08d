"""Motion models: how commands move the agents (``[domain] motion``).

Owns: the dynamics seam and its registry entries (:mod:`~physrover.domain.motion.dynamics`),
the paper's idealised kinematics compiled (:mod:`~physrover.domain.motion.ideal`: the move,
the command's check and clip, a class's move), and the physical model
(:mod:`~physrover.domain.motion.physics`: rigid bodies under finite force, stepped by pymunk
or by :mod:`~physrover.domain.motion.integrator`, contacts in
:mod:`~physrover.domain.motion.contacts`, overlapping spawns pushed apart by
:mod:`~physrover.domain.motion.separation`).

May import: :mod:`physrover.core`, :mod:`physrover.config`, :mod:`physrover.domain.state`,
:mod:`physrover.domain.broadphase`, :mod:`physrover.domain.obstacles`,
:mod:`physrover.domain.agents`.
"""
