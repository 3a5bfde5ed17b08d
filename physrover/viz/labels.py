"""Where a frame's POI labels go, and what the one under a POI says.

:func:`label_at` puts a label at the first of a few candidate spots around its POI that
covers the fewest pixels of what is already there (rover bodies, labels drawn before), so
labels keep off the rovers; :func:`poi_status` is the label under a POI: the agents in
range now against its coupling, or once captured, when.
"""

from __future__ import annotations

import cv2

BACKGROUND = (246, 246, 246)  # BGR, as OpenCV draws
POI_CAPTURED = (60, 170, 60)  # a captured POI and its label
TEXT = (40, 40, 40)


def text_at(img, text: str, org, scale: float, colour, thickness: int = 1, halo=False) -> None:
    """Draw ``text`` at pixel ``org`` (bottom left); ``halo``: on a background-coloured rim,
    legible over trails and bodies."""
    font, aa = cv2.FONT_HERSHEY_SIMPLEX, cv2.LINE_AA
    if halo:
        cv2.putText(img, text, org, font, scale, BACKGROUND, thickness + 3, aa)
    cv2.putText(img, text, org, font, scale, colour, thickness, aa)


def label_box(centre, half: int) -> tuple[int, int, int, int]:
    """The pixel box ``(x0, y0, x1, y1)`` of half-size ``half`` around ``centre``."""
    return centre[0] - half, centre[1] - half, centre[0] + half, centre[1] + half


def overlap(a, b) -> int:
    """Pixels two boxes share."""
    w = min(a[2], b[2]) - max(a[0], b[0])
    h = min(a[3], b[3]) - max(a[1], b[1])
    return max(0, w) * max(0, h)


def label_at(img, text, spots, scale, colour, thickness, avoid, placed) -> None:
    """Draw ``text`` at the first of the candidate ``spots`` that covers the fewest pixels
    of the ``avoid`` boxes (rover bodies, labels drawn so far) and loses the fewest past the
    frame's edge (each counted 4 times), and add its box to ``placed``. A spot is ``(x, y,
    align)``: the text's baseline at row y, starting at x (align "left"), ending there
    ("right") or centred on it ("centre")."""
    (w, h), _ = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, scale, thickness)
    shift = {"left": 0, "right": w, "centre": w // 2}
    boxes = [(x - shift[align], y - h, x - shift[align] + w, y + 3) for x, y, align in spots]
    frame = (0, 0, img.shape[1], img.shape[0])

    def cost(j):  # the pixels it covers, and those it would lose past the frame's edge
        box = boxes[j]
        cut = (box[2] - box[0]) * (box[3] - box[1]) - overlap(box, frame)
        return sum(overlap(box, b) for b in avoid) + 4 * cut

    best = min(range(len(boxes)), key=cost)
    text_at(img, text, (boxes[best][0], boxes[best][3] - 3), scale, colour, thickness, halo=True)
    placed.append(boxes[best])


def poi_status(state, domain, k: int) -> tuple[str, tuple, int]:
    """The label under POI k of a frame's ``state`` in ``domain`` (a DomainConfig): (text,
    BGR colour, thickness): ``captured tN`` in green once it
    was captured (at step N), else ``c/n``, the agents in range now against its coupling
    (green, bold, when met now)."""
    step = int(state.capture_step[k])
    if 0 <= step <= state.step:
        return f"captured t{step}", POI_CAPTURED, 1
    n_req, count = domain.n_req_per_poi[k], int(state.poi_counts[k])
    met = count >= n_req
    return f"{count}/{n_req}", POI_CAPTURED if met else TEXT, 2 if met else 1


__all__ = ["label_at", "label_box", "overlap", "poi_status", "text_at"]
