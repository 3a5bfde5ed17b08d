"""``[hybrid]``: a gradient learner beside the CCEA whose policies migrate into its
populations, in the manner of MERL (issue 46, lever 3; :mod:`physrover.learn.hybrid`)."""

from __future__ import annotations

import dataclasses
from typing import ClassVar

from physrover.config.base import ConfigBase, check
from physrover.core.registry import CREDITS

LEARNERS = ("mappo",)
"""The trainers a hybrid may run (their actor is a CCEA genome: n_obs -> hidden -> 2, ReLU
then tanh)."""


@dataclasses.dataclass(frozen=True)
class HybridConfig(ConfigBase):
    """MERL's hybrid (Majumdar, Khadka et al. 2020; read from ShawK91/MERL's code,
    ``experiments/notes/merl-algorithm.md``): every ``period`` generations the learner
    trains ``iterations`` iterations of ``episodes`` episodes on its own dense signal
    (``reward``; never G), then its deterministic actor, as one genome per rover, replaces
    one slot of each rover's population chosen at random among those that selection did
    not keep (the binary tournament's losers; under ``selection = "elites"`` the mutated
    offspring), and is mutated like the offspring (``mutate``). One way only: nothing of
    the populations reaches the learner. Evolution selects on the run's fitness method as
    without the hybrid. Present in a run's config.toml as a ``[hybrid]`` table; absent, no
    hybrid. The learner's other hyper-parameters are MAPPO's defaults (``[mappo]``,
    :class:`physrover.marl.configs.MAPPOConfig`), its hidden width the CCEA's
    (``[learn] hidden``)."""

    section: ClassVar[str] = "hybrid"

    learner: str = "mappo"
    """The gradient learner: "mappo" (parameters shared by the rovers, so every rover's
    migrant is the same actor; IPPO with ``centralised_critic = false``)."""
    period: int = 1
    """Generations between migrations (MERL's: 1, every generation); the learner trains
    only in migration generations, so its cost per generation falls as 1 / period."""
    iterations: int = 1
    """Learner iterations before each migration."""
    episodes: int = 50
    """Episodes of each learner iteration (MAPPO's ``num_envs``; MERL's ``rollsize``)."""
    reward: str = "proximity"
    """The learner's signal, a registered credit: "proximity" (MERL's dense reward,
    :mod:`physrover.domain.scoring.proximity`), or "G", "D", ... (``[mappo] reward``)."""
    mutate: bool = True
    """Mutate each migrant like an offspring ([learn] mutation_rate, mutation_scale,
    mutation; MERL mutates it); false keeps the learner's actor exact."""
    together: bool = False
    """In the generation after a migration, the migrants of every rover play together, as
    one team of the first training round (a swap inside the round's random teams; no extra
    episode). MERL's default evolves whole teams, so its migrant always plays as a team;
    with per-rover populations and random teams (false) each migrant plays among policies
    that are not the learner's."""
    lr: float = 3e-4
    """The learner's Adam learning rate."""
    centralised_critic: bool = True
    """MAPPO's centralised value (false: IPPO)."""

    def __post_init__(self) -> None:
        self._coerce_fields()
        check(self.learner in LEARNERS, "learner",
              f"must be one of {', '.join(LEARNERS)}, got {self.learner!r}")  # fmt: skip
        self.check_at_least(1, "period", "iterations", "episodes")
        self.check_positive("lr")
        check(self.reward in CREDITS, "reward", CREDITS.unknown_message(self.reward))
