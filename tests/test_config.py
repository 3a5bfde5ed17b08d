"""Domain config: validation names the field, TOML round trips, --set parsing."""

import pytest

from physrover.config import ConfigError, DomainConfig, dumps_toml, loads_toml, parse_override

INVALID = [
    ({"n_rovers": 0}, "n_rovers"),
    ({"n_rovers": 2.5}, "n_rovers"),
    ({"n_rovers": True}, "n_rovers"),
    ({"n_req": 16}, "n_req"),
    ({"n_req": 0}, "n_req"),
    ({"n_rovers": 2, "n_req": 3}, "n_req"),
    ({"poi_values": ()}, "poi_values"),
    ({"poi_values": (1.0, 1.0)}, "poi_values"),
    ({"poi_values": (1.0, -2.0)}, "poi_values"),
    ({"poi_values": (1.0, 0.0)}, "poi_values"),
    ({"poi_values": (1.0, float("inf"))}, "poi_values"),
    ({"poi_values": "1,2"}, "poi_values"),
    ({"d_cap": 0.0}, "d_cap"),
    ({"d_cap": -4.0}, "d_cap"),
    ({"d_cap": float("nan")}, "d_cap"),
    ({"d_min": 0.0}, "d_min"),
    ({"d_min": 5.0}, "d_min"),  # larger than d_cap: nothing could ever be captured
    ({"steps": 0}, "steps"),
    ({"poi_ring_radius": -1.0}, "poi_ring_radius"),
    ({"spawn_radius": 0.0}, "spawn_radius"),
    ({"motion": "teleport"}, "motion"),
    ({"motion": 3}, "motion"),
]


@pytest.mark.parametrize(("fields", "bad"), INVALID)
def test_invalid_values_name_the_field(fields, bad):
    with pytest.raises(ConfigError) as err:
        DomainConfig.from_dict(fields)  # bare names of any of the domain's tables
    assert err.value.field == bad
    assert str(err.value).startswith(f"{bad}: ")


def test_range_is_in_the_message():
    with pytest.raises(ConfigError, match=r"n_req: must be in \[1, n_rovers=15\], got 16"):
        DomainConfig(n_req=16)


def test_defaults_are_the_papers():
    cfg = DomainConfig()
    assert (cfg.n_rovers, cfg.n_req, cfg.d_cap, cfg.d_min, cfg.steps) == (15, 3, 4.0, 1.0, 50)
    assert cfg.poi_values == (1.0, 2.0, 3.0, 4.0) and sum(cfg.poi_values) == 10
    assert (cfg.scenario.kind, cfg.scenario.poi_ring_radius, cfg.scenario.spawn_radius) == (
        "ring",
        15.0,
        1.5,
    )
    assert (cfg.motion, cfg.sensor.kind, cfg.sensor.dim) == ("ideal", "density", 8)


def test_coercion_is_lossless_only():
    cfg = DomainConfig(poi_values=[1, 2], d_cap=4, n_rovers=4.0)
    assert cfg.poi_values == (1.0, 2.0) and isinstance(cfg.poi_values, tuple)
    assert isinstance(cfg.d_cap, float) and cfg.n_rovers == 4 and isinstance(cfg.n_rovers, int)


def test_frozen():
    with pytest.raises(AttributeError):
        DomainConfig().n_req = 4


def test_toml_round_trip():
    cfg = DomainConfig(n_rovers=6, poi_values=(1.5, 2.0), n_req=4, d_cap=3.25, motion="physics")
    text = cfg.to_toml()
    assert text.startswith("[domain]\n")
    assert DomainConfig.from_toml(text) == cfg


def test_toml_layout_and_escaping():
    """The text a run directory's config.toml holds: scalars and inline lists, one table after
    another; strings with quotes, backslashes or newlines, keys that need quoting and
    non-finite floats read back as written."""
    tables = {"domain": {"n_req": 3, "d_cap": 5e-06, "poi_values": [1.0, 2.5], "on": True},
              "odd": {"s": 'a "q" \\ b\nc\t', "key with space": float("inf")}}  # fmt: skip
    text = dumps_toml(tables)
    assert text.startswith(
        "[domain]\nn_req = 3\nd_cap = 5e-06\npoi_values = [1.0, 2.5]\non = true\n\n[odd]\n"
    )
    assert loads_toml(text) == tables


def test_toml_unknown_key_and_table():
    with pytest.raises(ConfigError, match="n_agents: unknown DomainConfig field"):
        DomainConfig.from_toml("[domain]\nn_agents = 3\n")
    with pytest.raises(ConfigError, match="unknown TOML table"):
        DomainConfig.from_toml("[domian]\nn_req = 3\n")
    with pytest.raises(ConfigError, match="cannot parse TOML"):
        DomainConfig.from_toml("[domain\n")


def test_replace_validates_and_rejects_unknown():
    assert DomainConfig().replace(n_req=5).n_req == 5
    with pytest.raises(ConfigError, match="n_req"):
        DomainConfig().replace(n_req=99)
    with pytest.raises(ConfigError, match="nreq"):
        DomainConfig().replace(nreq=5)


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("n_req=5", ("n_req", 5)),
        ("d_cap = 3.5", ("d_cap", 3.5)),
        ("poi_values=[1, 2.5]", ("poi_values", [1, 2.5])),
        ("motion=physics", ("motion", "physics")),
        ('motion="ideal"', ("motion", "ideal")),
        ("collisions=true", ("collisions", True)),
    ],
)
def test_parse_override(text, expected):
    assert parse_override(text) == expected


def test_parse_override_needs_equals():
    with pytest.raises(ConfigError, match="expected FIELD=VALUE"):
        parse_override("n_req")


def test_overrides_are_applied_as_a_whole_and_by_any_spelling():
    from physrover.config import RunConfig

    # A new scenario kind and fields that only fit together are checked together.
    base = RunConfig(DomainConfig(poi_values=[1, 2, 3]))
    c = base.with_overrides({"scenario": "explicit", "poi_positions": [[1, 0], [0, 1], [-1, 0]]})
    assert len(c.domain.scenario.poi_positions) == 3
    d = DomainConfig.from_dict({"poi_values": [1, 2, 3], "scenario": "explicit",
                                "poi_positions": [[1, 0], [0, 1], [-1, 0]]})  # fmt: skip
    assert d.scenario == c.domain.scenario
    # Naming the current kind keeps its parameters; the TOML spellings work.
    rr = DomainConfig(scenario={"kind": "ring-random", "ring_thickness": 0.5})
    assert rr.replace(scenario="ring-random").scenario.ring_thickness == 0.5
    assert DomainConfig().replace(**{"scenario.kind": "uniform"}).scenario.kind == "uniform"
    assert DomainConfig().replace(**{"domain.physics": {"substeps": 2}}).physics.substeps == 2
    # A trainer's table cannot take the run's seed.
    with pytest.raises(ConfigError, match=r"mappo.seed: set seed in \[learn\]"):
        RunConfig().with_overrides({"method": "mappo", "mappo.seed": 7})


def test_an_array_left_open_at_the_end_of_a_file_names_its_line(tmp_path):
    """tomllib says only "at end of document" there (issue 30)."""
    from physrover.config import RunConfig

    path = tmp_path / "bad.toml"
    path.write_text('[learn]\ngenerations = 3\n[domain]\nname = "a [b"  # [c\n'
                    "poi_values = [1, 2,\n")  # fmt: skip
    with pytest.raises(ConfigError, match=r"bad.toml: cannot parse TOML: .*end of document.*; "
                       r"the \[ of line 5 is never closed"):  # fmt: skip
        RunConfig.load(path)
