"""The README's Python examples run as printed (in a scratch directory)."""

import re
from pathlib import Path

import pytest

README = (Path(__file__).parent.parent / "README.md").read_text()


def _python_block(after: str) -> str:
    """The first ```python block after the heading ``after``."""
    start = README.index(after)
    return re.search(r"```python\n(.*?)```", README[start:], re.S).group(1)


@pytest.mark.parametrize(
    "heading", ["## Extending physrover", "### A learning algorithm of your own", "## Python API"]
)
def test_readme_example_runs(heading, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    namespace: dict = {}
    exec(compile(_python_block(heading), f"README {heading}", "exec"), namespace)  # noqa: S102
    if heading == "## Extending physrover":
        metrics = (tmp_path / "runs" / "extending" / "metrics.csv").read_text().splitlines()
        assert len(metrics) == 1 + 20
        config = (tmp_path / "runs" / "extending" / "config.toml").read_text()
        assert '[scenario]\nkind = "line"' in config and 'kind = "poi-distances"' in config
    if heading == "### A learning algorithm of your own":
        run = tmp_path / "runs" / "random-search"
        metrics = (run / "metrics.csv").read_text().splitlines()
        assert len(metrics) == 1 + 20 and metrics[-1].split(",")[-2:] == ["200", "10000"]
        assert "[random-search]\nnum_envs = 10\ntotal_episodes = 200\n" in (
            (run / "config.toml").read_text()
        )
        assert "sigma = 0.2" in (run / "config.toml").read_text()
