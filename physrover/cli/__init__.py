"""``physrover ...``: the parser (:mod:`~physrover.cli.main`) and one thin function per
command (:mod:`~physrover.cli.commands`).

May import: every other wing (it is the top one).
"""

from __future__ import annotations

from physrover.cli.main import build_parser, main

__all__ = ["build_parser", "main"]
