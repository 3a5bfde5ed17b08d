"""The paper's sensor (``[sensor] kind = "density"``): rover and POI densities by sector of
bearing, Eqs. 14-16, and its compiled kernels.

With the default four sectors (quadrants) each rover senses an 8-vector (the order of the
lab's rover-domain code):

- components 0-3: ``s_rover,q = sum_{j in J_q} 1 / delta_ij^2`` over the *other* rovers j of
  the team in quadrant q (Eq. 15);
- components 4-7: ``s_poi,q = sum_{k in K_q} V_k / delta_ik^2`` over the POIs k in quadrant
  q (Eq. 16);

with ``delta = max(||p_i - p_j||, d_min)`` the bounded distance of Eq. 14 and the quadrants
of :mod:`physrover.domain.sensing.sectors`. With ``sectors = n`` (the lab's
``n_observation_sections``) the same sums run over n equal sectors of bearing, 2n
observations, sector 0 starting dead behind and counting counter-clockwise; with a finite
``radius`` an object farther than it (its true distance, before the d_min bound) is left
out of every sum.

Each channel adds its terms object by object, rovers by index then POIs, in float64; an
object a rover does not see adds nothing. The paper's sensor sees every object: it is
all-pairs by definition, vectorised over the observing rovers (:func:`_sense_quadrants`,
R^2 distance terms a team). A sensor with a finite radius in a team of at least
:data:`physrover.domain.broadphase.SENSOR_GRID_MIN_POINTS` rovers finds the pairs of
rovers within the radius from a uniform grid instead (:func:`_sense_local`): the same
terms, added in the grid's order, so its sums equal the all-pairs loop's to float64
rounding. The paper's unbounded sensor costs R^2 distance terms a team whatever is done
(about 0.9 ms a step for 1000 rovers on one core): give large teams a radius.

Inside ``[[agents]]`` (or with POIs some agent may not sense) a class's density sensor is
read by the classes' lidar kernel (:mod:`physrover.domain.sensing.classes`), whose density
composition is this sensor bit for bit.
"""

from __future__ import annotations

import dataclasses
import math
from typing import ClassVar

import numpy as np

from physrover.config import check
from physrover.core.compiled import dims, jit
from physrover.core.registry import SENSORS
from physrover.domain.broadphase import SENSOR_GRID_MIN_POINTS, grid, stencil_runs
from physrover.domain.sensing.sectors import quadrant, sector
from physrover.domain.sensing.sensor import Sensor, register_sensor


@register_sensor
@dataclasses.dataclass(frozen=True)
class Density(Sensor):
    """The paper's sensor: rover and POI densities by sector of bearing (Eqs. 14-16), four
    quadrants by default (the lab's n_observation_sections), optionally blind beyond a radius
    (zerbeln/RoverDomain's observation radius)."""

    kind: ClassVar[str] = "density"

    sectors: int = 4
    """Sectors of bearing: observations per rover are 2 x sectors (rovers, then POIs)."""
    radius: float = math.inf
    """Objects farther than this (world units) are not sensed; inf (default) sees all."""

    def __post_init__(self) -> None:
        self._coerce_fields()
        self.check_at_least(1, "sectors")
        check(self.radius > 0, "radius", f"must be > 0 (inf: no limit), got {self.radius}")

    @property
    def dim(self) -> int:
        return 2 * self.sectors

    def kernel_arguments(self, d_min: float) -> tuple:
        """``(d_min^2, sectors, radius_sq)`` as :func:`sense_team` takes them (the sector
        count as a size tuple, no radius as None)."""
        radius_sq = self.radius * self.radius if math.isfinite(self.radius) else None
        return d_min * d_min, dims(self.sectors), radius_sq

    def observe(self, state, d_min: float, out: np.ndarray) -> None:
        d_min_sq, sectors, radius_sq = self.kernel_arguments(d_min)
        sense(state, d_min_sq, sectors, radius_sq, out)


# Run directories written while this sensor was named "quadrants" (before sector counts)
# still load: the name is an alias of the density sensor with its default four sectors.
SENSORS.register("quadrants", Density, alias=True)


PAD = 16
"""The quadrant sensor's loops over a team's rovers run over a multiple of this many lanes
(LLVM vectorises them 4 doubles x 4 interleaved; a remainder would run scalar)."""


@jit
def sense_scratch(n_rovers, sectors):
    """Scratch of :func:`sense_team`: (4 + 2 n_sectors, width) float64, rows the rovers' x, y,
    cos and sin (padded lanes: a rover at the origin facing +x, never read back) and the
    channels' sums, ``width`` >= R a multiple of :data:`PAD` (and >= 2 n_sectors)."""
    n_sectors = len(sectors)
    width = max(-(-n_rovers // PAD) * PAD, 2 * n_sectors)
    scratch = np.zeros((4 + 2 * n_sectors, width))
    scratch[2, :] = 1.0
    return scratch


@jit
def _sense_quadrants(e, state, d_min_sq, radius_sq, obs, scratch):
    """Eqs. 14-16 in four quadrants for the rovers of team ``e``, vectorised over the
    observing rovers: for each object (rovers by index, then POIs) every rover's four
    channel sums get the object's term or +0.0 (the same sums, in the same order, as adding
    it to its one channel; an unseen object or the rover itself adds +0.0 everywhere)."""
    positions, cos_h, sin_h = state.rover_positions, state.cos_h, state.sin_h
    poi_positions, poi_values = state.poi_positions, state.poi_values
    n_rovers = cos_h.shape[1]
    n_pois = poi_positions.shape[1]
    width = scratch.shape[1]
    px, py, cs, sn = scratch[0], scratch[1], scratch[2], scratch[3]
    r0, r1, r2, r3 = scratch[4], scratch[5], scratch[6], scratch[7]  # Eq. 15 by quadrant
    p0, p1, p2, p3 = scratch[8], scratch[9], scratch[10], scratch[11]  # Eq. 16 by quadrant
    for i in range(n_rovers):
        px[i] = positions[e, i, 0]
        py[i] = positions[e, i, 1]
        cs[i] = cos_h[e, i]
        sn[i] = sin_h[e, i]
    for i in range(width):
        r0[i] = r1[i] = r2[i] = r3[i] = p0[i] = p1[i] = p2[i] = p3[i] = 0.0
    # The two loops below differ only in the numerator, the self lane and the sums they add
    # to; one helper called for both halved their speed (37 -> 69 us per 50-team step: the
    # call kept LLVM from vectorising), so they stay written out.
    for j in range(n_rovers):  # the other rovers, numerator 1
        xj = positions[e, j, 0]
        yj = positions[e, j, 1]
        for i in range(width):
            dx = xj - px[i]
            dy = yj - py[i]
            dist_sq = dx * dx + dy * dy
            w = 1.0 / max(dist_sq, d_min_sq)  # Eq. 14
            if radius_sq is not None:
                w = w if dist_sq <= radius_sq else 0.0
            w = w if i != j else 0.0
            q = quadrant(cs[i] * dx + sn[i] * dy, cs[i] * dy - sn[i] * dx)
            r0[i] += w if q == 0 else 0.0
            r1[i] += w if q == 1 else 0.0
            r2[i] += w if q == 2 else 0.0
            r3[i] += w if q == 3 else 0.0
    for k in range(n_pois):  # the POIs, numerator V_k
        xk = poi_positions[e, k, 0]
        yk = poi_positions[e, k, 1]
        value = poi_values[e, k]
        for i in range(width):
            dx = xk - px[i]
            dy = yk - py[i]
            dist_sq = dx * dx + dy * dy
            w = value / max(dist_sq, d_min_sq)
            if radius_sq is not None:
                w = w if dist_sq <= radius_sq else 0.0
            q = quadrant(cs[i] * dx + sn[i] * dy, cs[i] * dy - sn[i] * dx)
            p0[i] += w if q == 0 else 0.0
            p1[i] += w if q == 1 else 0.0
            p2[i] += w if q == 2 else 0.0
            p3[i] += w if q == 3 else 0.0
    for i in range(n_rovers):
        obs[e, i, 0] = r0[i]
        obs[e, i, 1] = r1[i]
        obs[e, i, 2] = r2[i]
        obs[e, i, 3] = r3[i]
        obs[e, i, 4] = p0[i]
        obs[e, i, 5] = p1[i]
        obs[e, i, 6] = p2[i]
        obs[e, i, 7] = p3[i]


@jit
def _add_pois(e, i, state, c, s, d_min_sq, n_sectors, radius_sq, acc, obs):
    """Rover i of team e (heading cosine ``c``, sine ``s``): each POI's term of Eq. 16
    (numerator V_k) added to its sector of ``acc[n_sectors:]``, POIs beyond
    ``sqrt(radius_sq)`` left out (None: none), in POI order; then the 2 n_sectors channels
    of ``acc`` written to ``obs[e, i]``."""
    poi_positions, poi_values = state.poi_positions, state.poi_values
    xi, yi = state.rover_positions[e, i, 0], state.rover_positions[e, i, 1]
    for k in range(poi_positions.shape[1]):
        dx = poi_positions[e, k, 0] - xi
        dy = poi_positions[e, k, 1] - yi
        dist_sq = dx * dx + dy * dy
        if radius_sq is not None and dist_sq > radius_sq:
            continue
        dist_sq = max(dist_sq, d_min_sq)
        q = n_sectors + sector(c * dx + s * dy, c * dy - s * dx, n_sectors)
        acc[q] += poi_values[e, k] / dist_sq
    for q in range(2 * n_sectors):
        obs[e, i, q] = acc[q]


@jit
def sense_team(e, state, d_min_sq, sectors, radius_sq, obs, scratch):
    """Eqs. 14-16 for the rovers of team ``e`` in ``len(sectors)`` sectors: ``obs[e]``
    (R, 2 n_sectors) from ``state``, objects farther than ``sqrt(radius_sq)`` unseen (None:
    none); ``scratch`` from :func:`sense_scratch`. Each channel adds its terms object by
    object (rovers by index, then POIs).

    ``sectors`` is a tuple of n zeros (:func:`physrover.core.compiled.dims`) and ``radius_sq``
    may be None: the compiler then knows the sector count and whether there is a radius,
    and compiles the paper's sensor (4 sectors, no radius) as if it were written alone.
    Four sectors take the vectorised :func:`_sense_quadrants`; others the loop below.
    """
    n_sectors = len(sectors)
    if radius_sq is not None and state.cos_h.shape[1] >= SENSOR_GRID_MIN_POINTS:
        _sense_local(e, state, d_min_sq, n_sectors, radius_sq, obs)
        return
    if n_sectors == 4:
        _sense_quadrants(e, state, d_min_sq, radius_sq, obs, scratch)
        return
    positions, cos_h, sin_h = state.rover_positions, state.cos_h, state.sin_h
    n_rovers = cos_h.shape[1]
    acc = scratch[4]  # by sector: Eq. 15 in 0 .. n-1, Eq. 16 in n .. 2n-1
    for i in range(n_rovers):
        c = cos_h[e, i]
        s = sin_h[e, i]
        xi = positions[e, i, 0]
        yi = positions[e, i, 1]
        acc[:] = 0.0
        for j in range(n_rovers):  # the other rovers, numerator 1
            if j == i:
                continue
            dx = positions[e, j, 0] - xi
            dy = positions[e, j, 1] - yi
            dist_sq = dx * dx + dy * dy
            if radius_sq is not None and dist_sq > radius_sq:  # beyond the radius
                continue
            dist_sq = max(dist_sq, d_min_sq)  # Eq. 14
            acc[sector(c * dx + s * dy, c * dy - s * dx, n_sectors)] += 1.0 / dist_sq
        _add_pois(e, i, state, c, s, d_min_sq, n_sectors, radius_sq, acc, obs)


@jit
def _sense_local(e, state, d_min_sq, n_sectors, radius_sq, obs):
    """:func:`sense_team` with a finite radius from the cell list
    (:func:`physrover.domain.broadphase.grid`): each pair of rovers within the radius is
    found once, from the half stencil (:func:`~physrover.domain.broadphase.stencil_runs`)
    of its first rover in cell order, and adds its term to both rovers, i's view of j and
    j's of i (the offset negated: exact); then each rover adds the POIs within the radius.

    The rovers' terms arrive in cell order, not index order: each rover sees the same
    neighbours with the same terms as in the all-pairs loops, and its sums differ from
    theirs at most by float64 rounding (a few 1e-16, relative), which the float32
    observations almost never show (a test bounds both). Sorting the pairs into index
    order to make the sums bit for bit equal cost as much as the rest of the sensor.

    Speed (measured on layouts that change every step, as in a run: a fixed layout lets the
    branch predictor learn it): a rover's candidates are first compacted, branch-free, into
    the ones within the radius, and only those are sensed; headings and sums are kept in
    the cell order, so both rovers of a pair are near in memory. 1000 rovers: 115 us a step
    against 158 with a branch per candidate, 227 branch-free throughout."""
    positions, cos_h, sin_h = state.rover_positions, state.cos_h, state.sin_h
    n_rovers = cos_h.shape[1]
    cells, nx, ny, starts, members, ordered = grid(positions[e], math.sqrt(radius_sq))
    n_in = members.shape[0]
    trig = np.empty((n_in, 2))  # cos, sin of the heading, in cell order
    for slot in range(n_in):
        trig[slot, 0], trig[slot, 1] = cos_h[e, members[slot]], sin_h[e, members[slot]]
    acc = np.zeros((n_in, 2 * n_sectors))  # by slot and sector, as sense_team's acc
    near = np.empty(n_in, np.int64)  # one rover's neighbours ahead of it: slots, offsets
    near_dx, near_dy, near_sq = np.empty(n_in), np.empty(n_in), np.empty(n_in)
    for slot in range(n_in):
        xi, yi = ordered[slot, 0], ordered[slot, 1]
        ci, si = trig[slot, 0], trig[slot, 1]
        n_near = 0
        for run in stencil_runs(slot, cells[members[slot], 0], cells[members[slot], 1], nx,
                                ny, starts):  # fmt: skip
            for other in range(run[0], run[1]):  # written, kept if within the radius
                dx = ordered[other, 0] - xi
                dy = ordered[other, 1] - yi
                dist_sq = dx * dx + dy * dy
                near[n_near], near_dx[n_near], near_dy[n_near] = other, dx, dy
                near_sq[n_near] = dist_sq
                n_near += dist_sq <= radius_sq
        for k in range(n_near):
            other, dx, dy = near[k], near_dx[k], near_dy[k]
            term = 1.0 / max(near_sq[k], d_min_sq)  # Eq. 14
            cj, sj = trig[other, 0], trig[other, 1]
            acc[slot, sector(ci * dx + si * dy, ci * dy - si * dx, n_sectors)] += term
            acc[other, sector(cj * -dx + sj * -dy, cj * -dy - sj * -dx, n_sectors)] += term
    by_rover = np.zeros((n_rovers, 2 * n_sectors))  # a rover in no cell sees nothing
    for slot in range(n_in):
        by_rover[members[slot]] = acc[slot]
    for i in range(n_rovers):
        _add_pois(e, i, state, cos_h[e, i], sin_h[e, i], d_min_sq, n_sectors, radius_sq,
                  by_rover[i], obs)  # fmt: skip


@jit
def sense(state, d_min_sq, sectors, radius_sq, obs):
    """The density sensor (Eqs. 14-16) of every rover of every team in ``len(sectors)``
    sectors (a tuple of zeros, :func:`physrover.core.compiled.dims`), blind beyond
    ``sqrt(radius_sq)`` world units (None: sees everything), ``d_min_sq`` the bound of Eq.
    14 squared: ``obs`` (E, R, 2 n_sectors) float32, written."""
    scratch = sense_scratch(state.cos_h.shape[1], sectors)
    for e in range(state.cos_h.shape[0]):
        sense_team(e, state, d_min_sq, sectors, radius_sq, obs, scratch)


__all__ = ["PAD", "Density", "sense", "sense_scratch", "sense_team"]
