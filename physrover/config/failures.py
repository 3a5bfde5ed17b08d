"""Agents that fail mid-episode: ``[failures]`` (:mod:`physrover.domain.agents.failures`).

A robustness study of the kind the rover-domain literature runs (Agogino and Tumer,
"Distributed evaluation functions for fault tolerant multi-rover systems", GECCO 2006):
agents stop at given or drawn steps. An agent that fails at step ``s`` is out from state
``s`` on: it does not move into state ``s`` or after (its command is ignored and recorded
as 0), it is never in range of a POI (Eq. 13) and so captures nothing, and its observation
is 0 (it senses nothing). Its body stays where it stopped and its teammates still sense it
there (a failed rover does not vanish). ``s = 0`` is an agent out from the start; a step
past the episode's last is no failure.

Off by default (no agent fails, and the compiled step is the paper's).
"""

from __future__ import annotations

import dataclasses
from typing import Any, ClassVar

from physrover.config.base import ConfigBase, ConfigError, check, coerce


@dataclasses.dataclass(frozen=True)
class FailureConfig(ConfigBase):
    """Which agents fail, and when (module docstring). Steps are environment steps; agents
    are indices into the team (the order of ``[[agents]]`` tables, then rovers)."""

    section: ClassVar[str] = "failures"

    n_failing: int = 0
    """Agents drawn to fail in each episode of each team, uniformly without replacement
    from those ``given`` does not name, each from its team's generator."""
    between: tuple[int, ...] = ()
    """``[first, last]``: the steps a drawn failure falls on, uniformly, both included;
    empty: any step from 0 to the episode's last (``steps``)."""
    given: tuple[Any, ...] = ()
    """``[[agent, step], ...]``: agents that fail at a given step in every episode."""

    def __post_init__(self) -> None:
        self._coerce_fields()
        self.check_at_least(0, "n_failing")
        between = tuple(coerce("between", int, s) for s in self.between)
        check(len(between) in (0, 2), "between", f"must be [first, last], got {list(between)}")
        if between:
            check(0 <= between[0] <= between[1], "between",
                  f"must be [first, last], 0 <= first <= last, got {list(between)}")  # fmt: skip
        given = []
        for pair in self.given:
            if not isinstance(pair, (list, tuple)) or len(pair) != 2:
                raise ConfigError("given", f"each entry must be [agent, step], got {pair!r}")
            agent, step = coerce("given", int, pair[0]), coerce("given", int, pair[1])
            check(agent >= 0 and step >= 0, "given", f"agent and step must be >= 0, got {pair!r}")
            given.append((agent, step))
        agents = [a for a, _ in given]
        check(len(set(agents)) == len(agents), "given", f"an agent is named twice: {agents}")
        object.__setattr__(self, "between", between)
        object.__setattr__(self, "given", tuple(given))

    @property
    def on(self) -> bool:
        """Whether any agent may fail."""
        return self.n_failing > 0 or bool(self.given)

    def check_domain(self, n_rovers: int, steps: int) -> None:
        """ConfigError unless the agents and steps fit a team of ``n_rovers`` and an episode
        of ``steps``."""
        for agent, step in self.given:
            check(agent < n_rovers, "given", f"agent {agent} is not in a team of {n_rovers}")
            check(step <= steps, "given", f"step {step} is past the episode's {steps} steps")
        if self.between:
            check(self.between[1] <= steps, "between",
                  f"last step {self.between[1]} is past the episode's {steps} steps")  # fmt: skip
        free = n_rovers - len(self.given)
        check(self.n_failing <= free, "n_failing",
              f"must be at most {free} (the agents given does not name), got "
              f"{self.n_failing}")  # fmt: skip


__all__ = ["FailureConfig"]
