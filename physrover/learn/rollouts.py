"""Several episodes per team and generation (``[learn] rollouts``, the lab's
``num_rollouts``).

With ``rollouts = n`` every team that a generation plays (its training teams and elite
teams; not the evaluated team, which plays ``eval_episodes``) plays n episodes; its G and
each agent's feedback are their means, which fitness, elite teams and the best team then
read as one episode's. The n episodes of a team are consecutive teams of the batch, and
team e of the batch plays rollout e % n, whose start state, under the scenario's
``redraw = "generation"``, every team shares (the world's ``start_groups``,
:class:`~physrover.domain.start.StartDraws`): as the lab's CCEA gives every team the same
n seeds (AADILab/influence-shaping ``ccea_lib.py build_rollout_pack_ins``, at 8a71aa8),
whose fitness is the mean over a team's rollouts (its ``collapsed`` fitness).
"""

from __future__ import annotations

import numpy as np


def repeat_teams(index: np.ndarray, rollouts: int) -> np.ndarray:
    """(M, R) teams' genome indices -> (M * rollouts, R), each team's rows consecutive."""
    return np.repeat(index, rollouts, axis=0)


def mean_over_rollouts(values: np.ndarray, n_teams: int, rollouts: int) -> np.ndarray:
    """``values`` (n_teams * rollouts + rest, ...) of a batch -> (n_teams + rest, ...): the
    first teams' rows averaged over their rollouts, the rest (the evaluated team's
    episodes) as they are."""
    played = n_teams * rollouts
    if rollouts == 1:
        return values
    mean = values[:played].reshape(n_teams, rollouts, *values.shape[1:]).mean(axis=1)
    return np.concatenate([mean, values[played:]])


__all__ = ["mean_over_rollouts", "repeat_teams"]
