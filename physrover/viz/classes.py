"""What a video shows of agent classes and POIs with rules (``[[agents]]``, ``[[pois]]``).

- Agents of a class that counts toward captures are drawn as the paper's rovers (filled
  discs); agents of a class that does not (the lab's UAVs) get a diamond around the disc,
  in their colour.
- The HUD's third line is a legend: each class's name, count and whether it captures.
- A failed agent (``[failures]``) is drawn grey with a cross over it, where it stopped; the
  HUD counts the failed.
- A POI's capture ring has its own ``capture_radius``.
- A POI hidden from some classes is labelled with the classes that see it (``sees: uav``);
  an ordered POI with the POIs it waits for (``after 0``).
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from physrover.config.pois import capture_radii


def mark_classes(img, tf, now: np.ndarray, domain, radius_px: int, colour) -> None:
    """Diamonds around the agents (pixels ``now``, (R, 2) world positions) of classes that
    do not capture; ``colour(i)`` is agent i's colour."""
    start = 0
    for agent_class in domain.agents:
        rows = range(start, start + agent_class.count)
        start += agent_class.count
        if agent_class.captures:
            continue
        size = 2 * radius_px
        for i in rows:
            x, y = tf(now[i : i + 1])[0]
            diamond = np.array([[x, y - size], [x + size, y], [x, y + size], [x - size, y]])
            cv2.polylines(img, [np.round(diamond).astype(np.int32)], True, colour(i), 2,
                          cv2.LINE_AA)  # fmt: skip


FAILED = (105, 105, 105)
"""A failed agent's body (BGR): a darker grey than a free POI's, no rover's colour."""
CROSS = (30, 30, 30)


def mark_failed(img, tf, now: np.ndarray, alive, radius_px: int) -> None:
    """A grey body with a dark cross over each agent not ``alive`` ((R,) bool, or None: every
    agent alive) at its (R, 2) world position ``now``."""
    if alive is None:
        return
    for i in np.flatnonzero(~np.asarray(alive)):
        x, y = np.round(tf(now[i : i + 1])[0]).astype(int)
        cv2.circle(img, (x, y), radius_px, FAILED, -1, cv2.LINE_AA)
        r = radius_px + 2
        cv2.line(img, (x - r, y - r), (x + r, y + r), CROSS, 2, cv2.LINE_AA)
        cv2.line(img, (x - r, y + r), (x + r, y - r), CROSS, 2, cv2.LINE_AA)


def failure_legend(alive) -> list[tuple[str, float]]:
    """The HUD's line on failed agents (text, size): none without ``[failures]``."""
    if alive is None:
        return []
    alive = np.asarray(alive)
    return [(f"failed (grey, crossed): {int((~alive).sum())} of {alive.size}", 0.4)]


def class_legend(domain) -> list[tuple[str, float]]:
    """The HUD's third line (text, size): the classes' legend, or for the paper's team how
    to read a POI."""
    if not domain.agents:
        return [("POI: value above; below: rovers in reach/needed, green once captured", 0.4)]
    parts = [f"{c.name} x{c.count} ({'captures, disc' if c.captures else 'diamond'})"
             for c in domain.agents]  # fmt: skip
    return [("classes: " + "   ".join(parts), 0.4)]


def poi_rule_label(domain, k: int) -> str:
    """A short label of POI k's rules (who sees it, what it waits for), or ''."""
    if not domain.pois:
        return ""
    rule = domain.pois[k]
    parts = []
    if rule.visible_to:
        parts.append("sees: " + ",".join(rule.visible_to))
    if rule.after:
        parts.append("after " + ",".join(map(str, rule.after)))
    if rule.capture_by != "radius":
        parts.append(f"by {rule.capture_by}")
    return "  ".join(parts)


def ring_pixels(tf, domain, k: int) -> int:
    """The radius in pixels of POI k's capture ring: its own ``capture_radius`` or
    ``d_cap``; under ``capture_by = "sight"`` its ``sense_radius``, the farthest any agent
    captures from (each agent's own sensing radius may be less), or none if that is inf."""
    radius = capture_radii(domain)[k]
    if domain.pois and domain.pois[k].capture_by == "sight":
        sight = domain.pois[k].sense_radius
        radius = sight if math.isfinite(sight) else 0.0
    return max(1, int(tf.scale * radius))


__all__ = ["class_legend", "failure_legend", "mark_classes", "mark_failed", "poi_rule_label",
           "ring_pixels"]  # fmt: skip
