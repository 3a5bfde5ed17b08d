"""Per agent-step cost of world episodes of two team configs, interleaved in one process.

The one-engine issue's many-agent target: a 200-agent mixed team's cost per agent-step
against the 15-agent mixed team's. Each round plays one episode of each config in turn
(reset + steps of uniform random actions: ``physrover.experiment.bench.world_episodes``,
what ``physrover bench world`` times), so the host's drift hits both; prints the medians
in ns per agent-step and their ratio.

    python benchmarks/per_agent_step.py                      # mixed200 (4 teams) / mixed15 (50)
    python benchmarks/per_agent_step.py A.toml:TEAMS B.toml:TEAMS --rounds 30

Run it from outside the checkout to time an installed physrover (a script in a checkout
imports that checkout's package when run with ``python -m``; run as a file it imports the
installed one).
"""

from __future__ import annotations

import argparse
import statistics
from pathlib import Path

from physrover.config import RunConfig
from physrover.core.threads import pin_threads
from physrover.experiment.bench import world_episodes

CONFIGS = Path(__file__).parent / "configs"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("config", nargs="?", default=f"{CONFIGS / 'mixed200.toml'}:4",
                        help="FILE.toml:TEAMS timed (default mixed200.toml:4)")  # fmt: skip
    parser.add_argument("against", nargs="?", default=f"{CONFIGS / 'mixed15.toml'}:50",
                        help="FILE.toml:TEAMS compared with (default mixed15.toml:50)")  # fmt: skip
    parser.add_argument("--rounds", type=int, default=30, help="timed episodes of each")
    args = parser.parse_args()
    pin_threads(1)
    episodes = []
    for spec in (args.config, args.against):
        path, teams = spec.rsplit(":", 1)
        domain = RunConfig.load(path).domain
        _, play = world_episodes(domain, int(teams))
        episodes.append((Path(path).stem, play, int(teams) * domain.n_rovers * domain.steps))
    ns = {name: [] for name, *_ in episodes}
    for round_ in range(args.rounds + 2):  # two rounds of warm-up
        for name, play, agent_steps in episodes:
            seconds = play()
            if round_ >= 2:
                ns[name].append(seconds / agent_steps * 1e9)
    (a, ours), (b, theirs) = ((name, statistics.median(v)) for name, v in ns.items())
    print(f"{a}: {ours:.0f} ns per agent-step, {b}: {theirs:.0f}, ratio {ours / theirs:.2f}")


if __name__ == "__main__":
    main()
