"""The team the learning curve plays (``[learn] eval_team``).

- ``"champion"`` (the default, the paper's): every population's best policy by the latest
  fitness (the lab's ``test_adhoc_team_switch: true``);
- ``"best-team"``: the team of the previous generation with the highest G, its policies as
  they played, among the elite teams and then the training teams (ties: the first, the
  lab's ``max`` over its team packs, elites first). The lab's default test team
  (AADILab/influence-shaping ``ccea_lib.py evaluate_populations``, at 8a71aa8), which it
  replays on fresh rollouts in the same generation; here it plays in the next
  generation's batch, as the champion does (:mod:`physrover.learn.ccea`), so the curve of
  generation g is the best team of generation g - 1. Generation 1, before any team has
  played, evaluates the untrained champion.

The best team is copied before evolution changes the populations, and kept in checkpoints.
"""

from __future__ import annotations

import numpy as np


class BestTeam:
    """The genomes of the best team of the last generation (None before one has played)."""

    def __init__(self):
        self.genomes: np.ndarray | None = None
        """(R, P) its policies as they played."""

    def pick(self, G: np.ndarray, n_train: int, n_elites: int, genomes: np.ndarray,
             team_index: np.ndarray, elites: np.ndarray | None) -> None:  # fmt: skip
        """Keep the best of a generation's teams (module docstring).

        Args:
            G: (E,) G of the generation's episodes: training teams, then elite teams.
            n_train, n_elites: how many of each.
            genomes: (R, k, P) the populations as they played.
            team_index: (n_train, R) each training team's policies.
            elites: (n_elites, R, P) the elite teams' genomes, or None.
        """
        candidates = np.concatenate([G[n_train : n_train + n_elites], G[:n_train]])
        best = int(np.argmax(candidates))  # the first of equals
        if best < n_elites:
            self.genomes = elites[best].copy()
        else:
            rovers = np.arange(genomes.shape[0])
            self.genomes = genomes[rovers, team_index[best - n_elites]].copy()

    def state(self) -> dict[str, np.ndarray]:
        return {} if self.genomes is None else {"best_team": self.genomes}

    def load(self, arrays: dict[str, np.ndarray]) -> None:
        self.genomes = np.array(arrays["best_team"]) if "best_team" in arrays else None


__all__ = ["BestTeam"]
