"""The tightly coupled multi-rover domain: geometry, sensing, scoring, motion, the world.

Nothing in this package imports from the gymnasium envs, the learners or the CLI.
"""
