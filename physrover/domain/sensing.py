"""Rover sensing, Eqs. 15-16 of the paper: what each rover observes.

Each rover senses an 8-vector (the order of the lab's rover-domain code):

- components 0-3: ``s_rover,q = sum_{j in J_q} 1 / delta_ij^2`` over the *other* rovers j of
  the team in quadrant q (Eq. 15);
- components 4-7: ``s_poi,q = sum_{k in K_q} V_k / delta_ik^2`` over the POIs k in quadrant
  q (Eq. 16);

with ``delta = max(||p_i - p_j||, d_min)`` the bounded distance of Eq. 14. The compiled
implementation is :func:`physrover.domain.kernels.observe_and_score` (sensing and scoring in
one pass over the rover-object pairs).

Quadrant convention (the one of the paper's lab's rover-domain code)
--------------------------------------------------------------------
The bearing ``b`` of an object is measured counter-clockwise from the rover's heading and
wrapped to ``[-pi, pi)``; the quadrant is ``q = floor((b + pi) / (pi / 2))``:

====  ==============  ====================
 q    name            bearings
====  ==============  ====================
 0    behind-right    [-180 deg, -90 deg)
 1    front-right     [-90 deg, 0)
 2    front-left      [0, 90 deg)
 3    behind-left     [90 deg, 180 deg)
====  ==============  ====================

A bearing on a boundary goes to the quadrant that starts there (dead ahead -> 2, dead
right -> 1, dead left -> 3, dead behind -> 0). The bearing is read from the object's offset
``(f, l)`` in the rover's frame (``f`` forward, ``l`` left) as ``atan2(l, f)``, so an object
at the rover's own position (offset 0) has bearing 0 and lies in quadrant 2. The code uses
the signs of ``f`` and ``l`` instead of ``atan2``: the same answer, exact on the boundaries.

The lab's code computes ``floor((atan2(l, f) + pi) / (2 pi) * 4)`` clipped to 0-3, which
agrees except for signed zeros: dead behind with ``l = +0`` (what its arithmetic gives for
heading 0) is its quadrant 3 (here 0), and a coincident object is its quadrant 3 when the
heading's cosine and sine are both negative (here always 2).
"""

from __future__ import annotations

OBS_DIM = 8
"""Observations per rover: 4 quadrants x (rovers, POIs)."""
