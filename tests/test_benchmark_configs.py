"""The benchmark configs (``benchmarks/configs/``) load, and say what
``docs/performance.md`` reads from them: the mixed team and its narrow twin differ only in
the lidar's channels, 12 observations against the paper's 8."""

from pathlib import Path

import pytest

from physrover.config import RunConfig
from physrover.domain.world import RoverWorld

CONFIGS = Path(__file__).resolve().parent.parent / "benchmarks" / "configs"


@pytest.mark.parametrize("path", sorted(CONFIGS.glob("*.toml")), ids=lambda p: p.name)
def test_each_benchmark_config_loads(path):
    config = RunConfig.load(path)
    assert config.domain.n_rovers >= 1


def _width(config: RunConfig) -> int:
    """Observations per agent of the world the config builds."""
    return RoverWorld(config.domain, n_teams=1).observations.shape[-1]


def test_the_narrow_mixed_team_reads_the_papers_width():
    # 3 blocks of 4 sectors (rovers, UAVs, POIs) against 2 (agents, POIs), as the paper's 8
    assert _width(RunConfig.load(CONFIGS / "mixed15.toml")) == 12
    assert _width(RunConfig.load(CONFIGS / "mixed15-narrow.toml")) == 8 == _width(RunConfig())
    # the same file past their header comments (4 and 5 lines), but for the two lidars
    wide = (CONFIGS / "mixed15.toml").read_text().split("\n")[4:]
    narrow = (CONFIGS / "mixed15-narrow.toml").read_text().split("\n")[5:]
    changed = [b for a, b in zip(wide, narrow, strict=True) if a != b]
    assert len(changed) == 2 and all('channels = "agents-pois"' in line for line in changed)
