"""``physrover import-lab``: one of the paper's lab's YAML configs as physrover TOML.

The conversion is :func:`physrover.config.lab_run.lab_run`; this command reads the YAML (with
PyYAML, the ``lab`` extra), writes the run's TOML with the differences that stay as
comments at its top, and prints those notes, or refuses in one line what physrover cannot
express.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from physrover.cli.commands import UsageError
from physrover.config.lab_run import lab_run


def cmd_import_lab(args: argparse.Namespace) -> int:
    try:
        import yaml
    except ImportError:
        raise UsageError("import-lab reads YAML: pip install 'physrover[lab]' (PyYAML)") from None
    source = Path(args.lab_config)
    try:
        lab = yaml.safe_load(source.read_text())
    except OSError as exc:
        raise UsageError(f"{source}: {exc.strerror or exc}") from None
    except yaml.YAMLError as exc:
        raise UsageError(f"{source}: not YAML ({str(exc).splitlines()[0]})") from None
    if not isinstance(lab, dict):
        raise UsageError(f"{source}: not a lab config (expected a mapping with env and ccea)")
    run, notes = lab_run(lab)
    header = [f"# {source.name}, a config of the paper's lab (AADILab/influence-shaping),",
              "# as physrover import-lab wrote it. Where physrover runs it otherwise:"]  # fmt: skip
    header += [f"# - {note}" for note in notes]
    text = "\n".join(header) + "\n\n" + run.to_toml()
    if args.out:
        Path(args.out).write_text(text)
        print(f"wrote {args.out}", file=sys.stderr)
    else:
        print(text, end="")
    for note in notes:
        print(f"physrover: note: {note}", file=sys.stderr)
    return 0


def add_import_lab(sub) -> None:
    """The ``import-lab`` command's parser, under ``sub``."""
    p = sub.add_parser(
        "import-lab",
        help="write a config of the paper's lab (its YAML) as physrover TOML",
        description="Reads one of AADILab/influence-shaping's experiment configs and writes "
        "the equivalent physrover run config (TOML), with what physrover does otherwise as "
        "comments; refuses in one line what physrover cannot express (docs: From the lab's "
        "code).",
    )
    p.add_argument("lab_config", help="the lab's config.yaml")
    p.add_argument("-o", "--out", help="TOML file to write (default: standard output)")
    p.set_defaults(func=cmd_import_lab)


__all__ = ["add_import_lab", "cmd_import_lab"]
