"""The test suite's own setup under pytest-xdist (the README's ``-n auto --dist loadgroup``)."""

import pytest


def test_xdist_groups_a_modules_tests_on_one_worker(request):
    """conftest.py gives each module's tests a group (the Ray tests share one): xdist must
    apply it, which shows in the test's id (``...@test_workers``). pytest 9.2 with
    pytest-xdist 3.8 drops the groups silently (pytest-dev/pytest-xdist#1386): the suite
    then compiles kernel versions twice and may start Ray twice at once."""
    if not getattr(request.config.option, "loadgroup", False):
        pytest.skip("not run under pytest-xdist's --dist loadgroup")
    assert request.node.nodeid.endswith("@test_workers"), (
        f"pytest-xdist did not apply the test's group ({request.node.nodeid}): pytest "
        f"{pytest.__version__} needs a pytest-xdist that supports it (pyproject.toml)"
    )
