"""Learning: policy populations, the CCEA (Algorithm 1), fitness methods and fitness critics.

Reaches the world only through :class:`physrover.envs.RoverVectorEnv` (and the world it
wraps, for trajectories). A ``[hybrid]`` run's gradient learner (:mod:`physrover.marl`) is
loaded by name from the trainers' registry, never imported (:mod:`physrover.learn.hybrid`).

May import: :mod:`physrover.core`, :mod:`physrover.config`, :mod:`physrover.domain`,
:mod:`physrover.envs`.
"""
