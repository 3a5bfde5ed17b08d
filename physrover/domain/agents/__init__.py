"""Agent classes (``[[agents]]``, :mod:`physrover.config.agents`) as the domain reads them.

Owns: each agent's class and per-agent constants (:mod:`~physrover.domain.agents.classes`:
rows, names, gate radii, spawn rules) and the compiled form of a class's motion rule
(:mod:`~physrover.domain.agents.roles`: the gate, the speed, the frame, the bounds), which
both motion models read; and agents that fail mid-episode
(:mod:`~physrover.domain.agents.failures`, ``[failures]``). Without ``[[agents]]`` the team
is the paper's one class of rovers and every array here is the paper's constant.

May import: :mod:`physrover.core`, :mod:`physrover.config`, :mod:`physrover.domain.state`.
"""
