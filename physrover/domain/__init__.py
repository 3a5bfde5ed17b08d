"""The tightly coupled multi-rover domain: state, scenarios, motion, sensors, scoring, credit,
the world.

Nothing in this package imports from the gymnasium envs, the learners or the CLI.

May import: :mod:`physrover.core`, :mod:`physrover.config`.
"""
