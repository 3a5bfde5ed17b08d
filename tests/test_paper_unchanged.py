"""The paper's 2020 domain computes today what it computed when the digests were recorded
(``tests/paper_digests.py``), bit for bit: the guard for issue 33's additions, which must
leave the default domain and its speed as they are. Skipped on another platform (CPU
target, numpy, numba), where libm and the compiler may round differently."""

import json

import pytest
from paper_digests import DIGESTS, WORLDS, ccea_digest, platform, world_digest

RECORDED = json.loads(DIGESTS.read_text())


@pytest.fixture(scope="module", autouse=True)
def _same_platform():
    if platform() != RECORDED["platform"]:
        pytest.skip(f"digests recorded on {RECORDED['platform']}, this is {platform()}")


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
