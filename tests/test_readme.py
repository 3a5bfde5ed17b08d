"""The README fits on a screen, its two set-up commands are what CI runs, and its links
point at files that exist. (Its examples live in docs/, run by tests/test_docs.py.)"""

import re
from pathlib import Path

ROOT = Path(__file__).parent.parent
README = (ROOT / "README.md").read_text()


def test_the_readme_fits_on_a_screen():
    assert len(README.splitlines()) <= 150


def test_the_two_commands_install_and_run_the_demo_and_the_tests():
    first, second = re.findall(r"```bash\n(.*?)\n```", README, re.S)[:2]
    assert first.endswith("pip install -e . && physrover demo")
    assert "torch==" in first  # the CPU build before anything pulls a CUDA one
    command = "python -m pytest -q -n auto --dist loadgroup"  # on every core (pytest-xdist)
    assert second.endswith(f'pip install -e ".[test]" && {command}')
    ci = (ROOT / ".ci" / "run").read_text()
    assert f"\n{command}\n" in ci and 'pip install --quiet -e ".[test' in ci


def test_links_point_at_files():
    for target in re.findall(r"\]\(([^)#]+)\)", README):
        if not re.match(r"[a-z]+://", target):
            assert (ROOT / target).exists(), target


def test_the_package_description_links_nothing_relative():
    """PyPI shows it without the repository beside it (issue 30): no relative links or
    images, and it is what pyproject.toml names."""
    text = (ROOT / "README.pypi.md").read_text()
    assert 'readme = {file = "README.pypi.md"' in (ROOT / "pyproject.toml").read_text()
    for target in re.findall(r"\]\(([^)]+)\)", text):
        assert re.match(r"https?://", target), target
