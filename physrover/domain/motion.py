"""The paper's idealised rover kinematics (Section 4.1.2, Fig. 3).

The action ``(a_x, a_y)`` in ``[-1, 1]^2`` is a displacement in the rover's own frame
(``a_x`` forward, ``a_y`` to the left), in world units per step. The rover moves by that
vector rotated into the world frame, and its heading becomes the direction of the move
(unchanged when the move is zero). No collisions, no walls.
"""

from __future__ import annotations

import numpy as np


def body_to_world(vectors: np.ndarray, headings: np.ndarray) -> np.ndarray:
    """Rotate (E, R, 2) vectors from each rover's frame into the world frame."""
    cos_h, sin_h = np.cos(headings), np.sin(headings)
    fwd, left = vectors[..., 0], vectors[..., 1]
    out = np.empty(vectors.shape)
    out[..., 0] = cos_h * fwd - sin_h * left
    out[..., 1] = sin_h * fwd + cos_h * left
    return out


def commanded_move(actions: np.ndarray, headings: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The world-frame vector of (E, R, 2) rover-frame commands and its direction.

    Returns the (E, R, 2) vector and the (E, R) heading it points to, the current heading
    where the command is zero. Shared by the idealised move and the physical setpoints.
    """
    move = body_to_world(actions, headings)
    moved = (actions[..., 0] != 0) | (actions[..., 1] != 0)
    return move, np.where(moved, np.arctan2(move[..., 1], move[..., 0]), headings)


class IdealMotion:
    """Stateless idealised kinematics; see the module docstring.

    This is the numpy reference. Under the compiled engine ``RoverWorld`` does not call
    :meth:`step`: its one-call step (``domain.kernels.ideal_step``) moves the rovers itself.
    """

    name = "ideal"

    def reset(self, positions: np.ndarray, headings: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Nothing to rebuild: the idealised model has no state of its own."""
        return positions, headings

    def step(
        self, positions: np.ndarray, headings: np.ndarray, actions: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Move every rover of every team.

        Args:
            positions: (E, R, 2) world positions.
            headings: (E, R) radians.
            actions: (E, R, 2) clipped displacements in the rover's frame, world units.

        Returns:
            New positions (E, R, 2) and headings (E, R) in (-pi, pi].
        """
        move, new_headings = commanded_move(actions, headings)
        return positions + move, new_headings
