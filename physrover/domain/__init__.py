"""The tightly coupled multi-rover domain, batched over teams, organised by concept:

- ``state``: the one :class:`~physrover.domain.state.WorldState` of E teams;
- ``scenarios``: the start state of every episode (POI layouts, spawns, obstacles);
- ``layouts``: the scenarios' random POI layouts, compiled, from each team's generator;
- ``agents/``: agent classes and a class's motion rule (gate, speed, frame, bounds);
- ``motion/``: the motion models (the paper's idealised kinematics, physical bodies);
- ``sensing/``: what agents observe (the paper's density sensor, the lidar, class views);
- ``scoring/``: captures and G (Eqs. 11-13), POI rules, credit (D, D++, influence);
- ``broadphase``, ``obstacles``: the geometry that motion and sensing share;
- ``plan``: a world's step plan, built once from the config;
- ``step``: the one composition of the step (check and clip, move, sense, score, record);
- ``world``: :class:`~physrover.domain.world.RoverWorld`, which resets and steps the state.

Nothing in this package imports from the gymnasium envs, the learners or the CLI; inside
it, ``tests/test_layers.py`` keeps each folder to the ones its docstring names.

May import: :mod:`physrover.core`, :mod:`physrover.config`.
"""
