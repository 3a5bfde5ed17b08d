"""Input no one wrote by hand (issue 45): hypothesis generates config TOMLs, ``--set``
values, sweep files and ``[[agents]]`` / ``[[pois]]`` tables, valid and invalid, and
every one must end one of two ways:

- refused: exit status 2, exactly one line on stderr, ``physrover: error: ...``, naming a
  field (or table) the input set, and no file written (no run directory, no sweep root);
- accepted: it trains a generation (a ``metrics.csv`` of one row; for a sweep, its first
  run), exit status 0.

A traceback, a second line, a half-written run directory or a value that is accepted and
then fails to train is a bug. Values are drawn from each field's own type (the defaults
``physrover info`` prints) and from what does not fit it (text for numbers, lists for
scalars, NaN, infinities, unknown names, misspelt fields). Sizes stay small so an accepted
input trains in well under a second (a billion rovers is a valid config that no machine
holds: a limit of memory, not of input checking). ``PHYSROVER_PROPERTY_EXAMPLES`` scales
the counts (1: 300 TOMLs, 300 ``--set`` lists, 150 class tables, 300 sweep files, sized
with the rest of the suite to keep it under 10 minutes on 2 cores from a cold kernel
cache, as CI runs it; set 4 or more for a deeper search before a release, as for issue
45, which ran them at 500, 500, 250 and 500).
"""

from __future__ import annotations

import contextlib
import io
import math
import os
import re
import tempfile
from pathlib import Path

import pytest
import tomlkit
import tomllib

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from physrover.cli.main import main  # noqa: E402
from physrover.experiment.store import read_metrics  # noqa: E402

SCALE = float(os.environ.get("PHYSROVER_PROPERTY_EXAMPLES", "1"))


def _settings(examples: int):
    slow = [HealthCheck.too_slow, HealthCheck.data_too_large]
    return settings(max_examples=max(1, int(examples * SCALE)), deadline=None, derandomize=True,
                    database=None,
                    suppress_health_check=slow)  # fmt: skip


def _cli(*args: str) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(list(args))
        except SystemExit as exit_:  # argparse's own errors
            code = exit_.code
    return code, out.getvalue(), err.getvalue()


def _defaults() -> dict:
    code, out, _ = _cli("info")
    assert code == 0
    return tomllib.loads(out)


DEFAULTS = _defaults()
TABLES = {name: table for name, table in DEFAULTS.items() if isinstance(table, dict)}
# Every word a string field takes somewhere, so choices are hit as well as missed.
WORDS = sorted({v for t in TABLES.values() for v in t.values() if isinstance(v, str)} | {
    "D", "G", "D++", "ID", "ID-step", "mean-critic", "average", "leniency", "hall-of-fame",
    "max-critic-regular", "mean-critic-inexact", "physics", "uniform", "lidar", "gauss",
    "softmax", "elites", "adam", "step", "trained", "before-steps", "generation", "final",
    "captured", "rover", "uav", "disc", "box", "circle", "by-class",
})  # fmt: skip
# The fields that make a run big or slow are kept small; a trainer (MAPPO, ...) is not
# drawn as a method: its budget is iterations of thousands of steps.
SMALL = {"n_rovers": 6, "population": 6, "steps": 8, "hidden": 8, "critic_hidden": 8,
         "n_samples": 3, "eval_episodes": 3, "sectors": 8, "substeps": 4,
         "solver_iterations": 10, "trajectory_hidden": 8, "critic_ensemble": 3}  # fmt: skip
TRAINERS = {"mappo", "ippo", "maddpg"}

BASE = {
    "domain": {"n_rovers": 3, "n_req": 1, "steps": 5, "poi_values": [1.0, 2.0]},
    "learn": {"method": "max-critic", "population": 4, "eval_episodes": 1, "generations": 1,
              "hidden": 4},
    "critic": {"critic_hidden": 8},
}  # fmt: skip

junk = st.one_of(
    st.text(st.characters(codec="ascii", exclude_categories=["Cc"]), max_size=4),
    st.lists(st.integers(-1, 3), max_size=2),
    st.sampled_from([math.nan, math.inf, -math.inf, -1.0, 0.0, 12.0]),
    st.booleans(),
    st.integers(-3, 3),
)


def _weighted(common: st.SearchStrategy, rare: st.SearchStrategy, odds: int = 5):
    """``common`` ``odds`` times as often as ``rare`` (``one_of`` draws its branches evenly,
    and the same strategy given twice is one branch)."""
    return st.integers(0, odds).flatmap(lambda i: rare if i == odds else common)


def _value(name: str, default) -> st.SearchStrategy:
    """A value for a field whose default is ``default``: mostly of its type, small, and
    now and then anything (``junk``)."""
    if isinstance(default, bool):
        own = st.booleans()
    elif isinstance(default, int):
        own = st.one_of(st.integers(1, SMALL.get(name, 8)), st.integers(-1, 0))
    elif isinstance(default, float):
        own = st.one_of(st.sampled_from([0.0, 0.5, 1.0, 2.0, 4.0, 15.0, -1.0, math.inf]),
                        st.floats(-5, 20, allow_nan=False))  # fmt: skip
    elif isinstance(default, str):  # its default, or any word of any field
        own = st.one_of(st.just(default), st.sampled_from([w for w in WORDS if w not in TRAINERS]))
    elif isinstance(default, list):
        item = st.floats(0.5, 5) if default and isinstance(default[0], float) else st.integers(1, 3)
        own = st.lists(item, min_size=0, max_size=4)
    else:
        own = junk
    return _weighted(own, junk)


@st.composite
def _misspelt(draw, names: list[str]) -> str:
    """A field name that is not one: a known name with a character dropped or doubled."""
    name = draw(st.sampled_from(names))
    at = draw(st.integers(0, len(name) - 1))
    word = name[:at] + name[at + 1 :] if draw(st.booleans()) else name[:at] + name[at] + name[at:]
    return word if word not in names else word + "x"


@st.composite
def edits(draw, tables=TABLES, max_edits: int = 2) -> list[tuple[str, str, object]]:
    """(table, field, value) edits: known fields with drawn values, or misspelt fields."""
    out = []
    for _ in range(draw(st.integers(1, max_edits))):
        table = draw(st.sampled_from(sorted(tables)))
        names = sorted(tables[table])
        if draw(st.integers(0, 9)) == 0:
            out.append((table, draw(_misspelt(names)), draw(junk)))
            continue
        name = draw(st.sampled_from(names))
        out.append((table, name, draw(_value(name, tables[table][name]))))
    return out


def _apply(base: dict, changes) -> dict:
    doc = {table: dict(fields) for table, fields in base.items()}
    for table, name, value in changes:
        doc.setdefault(table, {})[name] = value
    if doc.get("learn", {}).get("generations") != 1:  # the run itself is one generation
        doc.setdefault("learn", {})["generations"] = 1
    return doc


def _named(line: str, names) -> bool:
    """Whether the error line names one of ``names`` as a field (``x:``, ``x[0].y:``,
    ``[x]``, ``'x'``, ``x=1``, or in a message about another field's bounds)."""
    return any(re.search(rf"(^|[\s.\[']){re.escape(n)}([\].\[:'=,) ]|$)", line) for n in names)


def _refused_or_trained(code: int, err: str, out_dir: Path, names, dry: bool = False) -> str:
    """Check the two ends (module docstring); returns which it was. ``dry``: a dry run,
    accepted without training."""
    lines = err.strip().splitlines()
    with contextlib.suppress(hypothesis.errors.InvalidArgument):  # outside @given: no events
        hypothesis.event("refused" if code == 2 else "accepted")
    if code == 2:
        assert len(lines) == 1 and lines[0].startswith("physrover: error: "), err
        assert _named(lines[0], names), (lines[0], names)
        assert not out_dir.exists() or not any(out_dir.iterdir()), list(out_dir.iterdir())
        return "refused"
    assert code == 0, err[-3000:]
    if dry:
        return "accepted"
    rows = read_metrics(out_dir / "metrics.csv")
    assert len(rows) == 1 and int(rows[0]["generation"]) == 1, rows
    return "trained"


def _train_toml(doc: dict, names) -> str:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "config.toml"
        try:
            path.write_text(tomlkit.dumps(doc))
        except (ValueError, TypeError):  # not expressible in TOML (e.g. a mixed array)
            return "unwritable"
        out = Path(tmp) / "run"
        code, _, err = _cli("train", "--config", str(path), "--out", str(out), "--quiet")
        return _refused_or_trained(code, err, out, [*names, str(path)])


@pytest.mark.long
@_settings(300)
@given(edits())
def test_any_config_toml_is_refused_in_one_line_or_trains(changes):
    names = [name for _, name, _ in changes] + [table for table, _, _ in changes]
    _train_toml(_apply(BASE, changes), names)


@pytest.mark.parametrize(
    ("table", "field", "value", "message"),
    [
        ("learn", "population", -1, "population: must be >= 2"),
        ("learn", "populaton", 4, "did you mean 'population'"),
        ("domain", "n_rovers", "three", "n_rovers: expected an integer"),
        ("learn", "mutation_rate", math.nan, "mutation_rate: must not be NaN"),
        ("learn", "method", "max-critc", "did you mean 'max-critic'"),
        ("sensor", "kind", "radar", "kind"),
    ],
)
def test_known_invalid_configs_are_refused(table, field, value, message):
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "config.toml"
        path.write_text(tomlkit.dumps(_apply(BASE, [(table, field, value)])))
        out = Path(tmp) / "run"
        code, _, err = _cli("train", "--config", str(path), "--out", str(out), "--quiet")
        assert _refused_or_trained(code, err, out, [field]) == "refused"
        assert message in err, err


def _literal(value) -> str:
    """``value`` as ``--set`` takes it (TOML's literal syntax), or raw text."""
    if isinstance(value, str):
        return value
    return tomlkit.item(value).as_string()


@pytest.mark.long
@_settings(300)
@given(edits(max_edits=2), st.booleans())
def test_any_set_values_are_refused_in_one_line_or_train(changes, raw_text):
    sets = []
    for _, name, value in changes:
        try:
            text = _literal(value) if not raw_text or not isinstance(value, str) else value
        except (ValueError, TypeError):
            text = str(value)
        sets += ["--set", f"{name}={text}"]
    names = [name for _, name, _ in changes]
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "base.toml"
        path.write_text(tomlkit.dumps(BASE))
        out = Path(tmp) / "run"
        code, _, err = _cli("train", "--config", str(path), *sets, "--generations", "1",
                            "--out", str(out), "--quiet")  # fmt: skip
        _refused_or_trained(code, err, out, names)


NAMES = ["rover", "uav", "scout"]


def _mostly(valid: list, invalid: list) -> st.SearchStrategy:
    """A valid value seven times in eight, else an invalid one."""
    return _weighted(st.sampled_from(valid), st.sampled_from(invalid), odds=7)


@st.composite
def agent_tables(draw) -> list[dict]:
    names = draw(st.lists(st.sampled_from(NAMES), min_size=1, max_size=3, unique=True))
    if draw(st.integers(0, 9)) == 0:  # a repeated name
        names.append(names[0])
    tables = []
    for name in names:
        table = {"name": name, "count": draw(_mostly([1, 2, 3], [0, -1]))}
        for field, strategy in (
            ("captures", st.booleans()),
            ("max_speed", _mostly([0.5, 1.0, 2.0], [0.0, -1.0])),
            ("moves_with", _mostly([[]] + [[n] for n in names], [["ghost"]])),
            ("moves_with_radius", _mostly([0.0, 3.0], [-1.0])),
            ("influence_radius", _mostly([0.0, 5.0], [-2.0])),
            ("action", _mostly(["body", "world"], ["teleport"])),
            ("spawn", _mostly(["disc"], ["circle", "positions", "nowhere"])),
            ("sensor", _mostly([
                {"kind": "lidar", "radius": 3.0, "empty": -1.0, "channels": "by-class"},
                {"kind": "lidar", "radius": 10.0},
                {"kind": "density"},
            ], [{"kind": "sonar"}, {"kind": "lidar", "radius": -1.0}])),
        ):  # fmt: skip
            if draw(st.integers(0, 3)) == 0:
                table[field] = draw(strategy)
        tables.append(table)
    return tables


@st.composite
def poi_tables(draw, names: list[str]) -> list[dict]:
    tables = []
    n_pois = draw(st.integers(1, 4))
    classes = names or ["rover"]
    for index in range(n_pois):
        table = {"value": draw(_mostly([1.0, 2.0, 4.0], [0.0, -1.0]))}
        for field, strategy in (
            ("n_req", _mostly([1, 2], [0, 9])),
            ("capture_radius", _mostly([2.0, 4.0], [-1.0])),
            ("after", _mostly([[]] + [[i] for i in range(index)], [[index], [-1], [n_pois]])),
            ("score_at", _mostly(["any", "final"], ["never"])),
            ("visible_to", _mostly([[], [classes[0]]], [["ghost"]])),
            ("disappear", _mostly(["never", "captured"], ["soon"])),
            ("require", _mostly([{classes[-1]: 1}], [{"ghost": 2}, {classes[0]: 0}])),
        ):  # fmt: skip
            if draw(st.integers(0, 3)) == 0 and not (field == "require" and "n_req" in table):
                table[field] = draw(strategy)
        tables.append(table)
    return tables


@pytest.mark.long
@_settings(150)
@given(st.data())
def test_any_agent_and_poi_tables_are_refused_in_one_line_or_train(data):
    agents = data.draw(agent_tables()) if data.draw(st.booleans()) else []
    pois = data.draw(poi_tables(sorted({a["name"] for a in agents})))
    method = data.draw(st.sampled_from(["D", "max-critic"]))
    doc = {"domain": {"n_req": 1, "steps": 5}, "learn": dict(BASE["learn"], method=method)}
    if method == "max-critic":
        doc["critic"] = BASE["critic"]
    if agents:
        doc["agents"] = agents
    else:
        doc["domain"]["n_rovers"] = 3
    doc["pois"] = pois
    _train_toml(doc, ["agents", "pois", "n_req", "n_rovers", "poi_values"])


@pytest.mark.long
@_settings(300)
@given(st.data())
def test_any_sweep_file_is_refused_in_one_line_or_runs(data):
    grid_tables = {t: TABLES[t] for t in ("domain", "learn", "sensor")}
    base = data.draw(edits(grid_tables, max_edits=1)) if data.draw(st.integers(0, 3)) == 0 else []
    seeds = data.draw(_weighted(st.integers(1, 2), junk))
    name = data.draw(_mostly(["screen", "ok-1"], ["a b", "", "../up", "x/y"]))
    doc = {"sweep": {"name": name, "seeds": seeds}, "base": _apply(BASE, base), "grid": {}}
    grid = []
    for _ in range(data.draw(st.integers(1, 2))):
        table = data.draw(st.sampled_from(sorted(grid_tables)))
        field = data.draw(st.sampled_from(sorted(grid_tables[table])))
        value = _value(field, grid_tables[table][field])
        listed = st.lists(value, min_size=1, max_size=2, unique_by=repr)
        doc["grid"][field] = data.draw(_weighted(listed, value))
        grid.append((table, field, doc["grid"][field]))
    names = ["name", "seeds", "grid", "sweep", *(f for _, f, _ in base + grid)]
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "s.toml"
        try:
            path.write_text(tomlkit.dumps(doc))
        except (ValueError, TypeError):
            return
        root = Path(tmp) / "root"
        code, out, err = _cli("sweep", str(path), "--root", str(root), "--dry-run")
        if _refused_or_trained(code, err, root, [*names, str(path)], dry=True) == "refused":
            return
        from physrover.experiment.execute import run_one
        from physrover.experiment.sweep import Sweep

        specs = Sweep.load(path).runs(root)
        assert specs and not root.exists()  # a dry run writes nothing
        assert len([line for line in out.splitlines() if line.startswith(str(root))]) == \
            len(specs)  # fmt: skip
        _, _, error = run_one(specs[0])
        assert error is None, error
        rows = read_metrics(Path(specs[0].out) / "metrics.csv")
        assert len(rows) == 1
