"""Scoring: what an episode's states are worth, and each agent's share of it.

Owns: captures and the team score, compiled (:mod:`~physrover.domain.scoring.captures`,
Eqs. 11-13 and D's counterfactual captures, which the step calls), the POIs' rules as the
kernels read them (:mod:`~physrover.domain.scoring.rules`), the credits read from an
episode (:mod:`~physrover.domain.scoring.difference`: G, D of Eq. 1, D++;
:mod:`~physrover.domain.scoring.influence`: IndirectDifference;
:mod:`~physrover.domain.scoring.proximity`: MERL's dense proximity reward) and the credit
seam with its registry entries (:mod:`~physrover.domain.scoring.credit`).

May import: :mod:`physrover.core`, :mod:`physrover.config`, :mod:`physrover.domain.state`,
:mod:`physrover.domain.agents`.
"""

import importlib as _importlib
import warnings as _warnings

_MOVED = {  # physrover 0.5's physrover.domain.scoring module, now a package
    "team_score": "physrover.domain.scoring.difference",
    "difference": "physrover.domain.scoring.difference",
    "d_plus_plus": "physrover.domain.scoring.difference",
    "start_episode": "physrover.domain.state",
}


def __getattr__(name: str):
    if name in _MOVED:
        new = f"{_MOVED[name]}.{name}"
        _warnings.warn(f"physrover.domain.scoring.{name} is now {new}; the old path goes in "
                       "the next release", DeprecationWarning, stacklevel=2)  # fmt: skip
        return getattr(_importlib.import_module(_MOVED[name]), name)
    raise AttributeError(f"module 'physrover.domain.scoring' has no attribute {name!r}")
