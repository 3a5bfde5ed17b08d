"""The paper's 2020 domain (and issue 33's mixed team and ordered POIs) computes today what
it computed when the digests were recorded (``tests/paper_digests.py``), bit for bit: the
guard for everything added since, which must leave the default domain as it is. Checked
on any x86-64 CPU (the kernels use no fast-math: the digests are the same on every CPU
they were verified on); skipped where numpy, numba or pymunk differ from the recorded
versions, whose random streams, code generation or Chipmunk may differ."""

import json
import platform as _platform

import pytest
from paper_digests import DIGESTS, WORLDS, ccea_digest, platform, world_digest

RECORDED = json.loads(DIGESTS.read_text())
LIBRARIES = ("numpy", "numba", "pymunk")


@pytest.fixture(scope="module", autouse=True)
def _same_libraries():
    if _platform.machine().lower() not in ("x86_64", "amd64"):
        pytest.skip(f"digests recorded on x86-64, this is {_platform.machine()}")
    here = platform()
    recorded = {name: RECORDED["platform"][name] for name in LIBRARIES}
    if {name: here[name] for name in LIBRARIES} != recorded:
        pytest.skip(f"digests recorded with {recorded}, this is {here}")


@pytest.mark.parametrize("name", list(WORLDS))
def test_the_worlds_episodes_are_unchanged(name):
    assert world_digest(WORLDS[name]) == RECORDED["digests"][f"world/{name}"]


@pytest.mark.parametrize("method", ["D", "average"])
def test_the_cceas_generations_are_unchanged(method):
    assert ccea_digest(method) == RECORDED["digests"][f"ccea/{method}"]


def test_the_default_config_is_unchanged():
    import hashlib

    from physrover import DomainConfig

    toml = DomainConfig().to_toml().encode()
    assert hashlib.sha256(toml).hexdigest() == RECORDED["digests"]["config"]


def test_a_changed_world_changes_its_digest():
    """The guard can fail: a millionth more of d_min (Eq. 14's floor) changes the float32
    observations of rovers closer than 1, and the digest; so does another method."""
    assert world_digest({"d_min": 1.0 + 1e-6}) != RECORDED["digests"]["world/ideal"]
    assert RECORDED["digests"]["ccea/D"] != RECORDED["digests"]["ccea/average"]
