"""Sensing: what each agent observes after every step (Eqs. 14-16 and the lab's lidar).

Owns: the sensor seam (:mod:`~physrover.domain.sensing.sensor`), the sector convention every
sensor shares (:mod:`~physrover.domain.sensing.sectors`), the paper's density sensor and its
kernels (:mod:`~physrover.domain.sensing.density`), the lidar
(:mod:`~physrover.domain.sensing.lidar`, a team at once where it can:
:mod:`~physrover.domain.sensing.lanes`), the distances to agents
(:mod:`~physrover.domain.sensing.distances`) and the table of what each agent class senses
(:mod:`~physrover.domain.sensing.classes`), which the compiled step reads.

May import: :mod:`physrover.core`, :mod:`physrover.config`, :mod:`physrover.domain.state`,
:mod:`physrover.domain.broadphase`, :mod:`physrover.domain.agents`.
"""
