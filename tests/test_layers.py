"""The package's wings: each imports only from the wings its docstring allows (lower ones),
no import cycle anywhere (inside functions too), a tree a reader can take in.

Read from the source (every ``import physrover...`` / ``from physrover... import``, also
inside functions), so a new upward import fails here, not in a reader's head.
"""

import ast
import importlib
import warnings
from pathlib import Path

import pytest

import physrover

ROOT = Path(physrover.__file__).parent

# Lowest first; each wing may import itself and the wings listed for it (DESIGN.md).
WINGS = ["core", "config", "domain", "viz", "envs", "learn", "marl", "experiment", "analysis",
         "cli"]  # fmt: skip
ALLOWED = {
    "core": {"core"},
    "config": {"config", "core"},
    "domain": {"domain", "config", "core"},
    "viz": {"viz", "domain", "config", "core"},
    "envs": {"envs", "viz", "domain", "config", "core"},
    "learn": {"learn", "envs", "domain", "config", "core"},
    "marl": {"marl", "learn", "envs", "domain", "config", "core"},
    "experiment": {"experiment", "marl", "learn", "envs", "viz", "domain", "config", "core"},
    "analysis": {
        "analysis",
        "experiment",
        "marl",
        "learn",
        "envs",
        "viz",
        "domain",
        "config",
        "core",
    },  # fmt: skip
    "cli": set(WINGS),
}
MAX_LINES = 400
MAX_LOOSE = 3  # modules at the package's top beside the wings (now: __init__ only)


def _imports() -> dict[str, set[tuple[str, bool]]]:
    """{module: {(imported physrover module, at module level?)}}."""
    found = {}
    for path in ROOT.rglob("*.py"):
        rel = path.relative_to(ROOT).with_suffix("")
        name = ".".join(rel.parts)
        tree = ast.parse(path.read_text())
        top_level = {id(node) for node in tree.body}
        out = set()
        for node in ast.walk(tree):
            targets = []
            if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                targets = [node.module]
            elif isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            for target in targets:
                if target == "physrover" or target.startswith("physrover."):
                    inner = target[len("physrover.") :] if "." in target else ""
                    if isinstance(node, ast.ImportFrom) and not inner:
                        inner = node.names[0].name  # from physrover import __version__
                    out.add((inner, id(node) in top_level))
        found[name] = out
    return found


def _wing(module: str) -> str:
    wing = module.split(".")[0]
    assert wing in ALLOWED, f"physrover.{module} is in no wing: add its folder to WINGS"
    return wing


def test_each_wing_imports_only_the_wings_below_it():
    upward = []
    for module, targets in _imports().items():
        if module == "__init__":  # the package's public surface re-exports every wing
            continue
        for target, _ in targets:
            if target in ("", "__version__"):
                continue
            if _wing(target) not in ALLOWED[_wing(module)]:
                upward.append(f"physrover.{module} imports physrover.{target}")
    assert not upward, "\n".join(upward)


def test_the_allowed_imports_only_go_down():
    for wing, allowed in ALLOWED.items():
        assert all(WINGS.index(other) <= WINGS.index(wing) for other in allowed), wing


def test_no_import_cycle_anywhere():
    """Also through imports inside functions (physrover 0.4's runs and trainer_runs imported
    each other); a package's __init__ (re-exports, lazy attributes) is left out."""
    graph = {
        module: {t for t, _ in targets if t}
        for module, targets in _imports().items()
        if not module.endswith("__init__")
    }
    modules = set(graph)

    def resolve(target):  # "domain.world" may be a module or a name inside a package
        return target if target in modules else target.rsplit(".", 1)[0]

    state: dict[str, int] = {}

    def visit(node, path):
        state[node] = 1
        for nxt in map(resolve, graph.get(node, ())):
            if nxt not in modules or nxt == node:
                continue
            if state.get(nxt) == 1:
                raise AssertionError("import cycle: " + " -> ".join([*path, nxt]))
            if nxt not in state:
                visit(nxt, [*path, nxt])
        state[node] = 2

    for module in sorted(modules):
        if module not in state:
            visit(module, [module])


def test_the_tree_reads_from_the_door():
    """Wings as folders, each saying what it owns and may import; few loose modules; no
    module too long to read."""
    loose = sorted(p.name for p in ROOT.glob("*.py"))
    assert len(loose) <= MAX_LOOSE, loose
    folders = sorted(p.name for p in ROOT.iterdir() if (p / "__init__.py").is_file())
    assert folders == sorted(WINGS)
    for wing in WINGS:
        doc = ast.get_docstring(ast.parse((ROOT / wing / "__init__.py").read_text()))
        assert doc and "May import" in doc, f"physrover/{wing}/__init__.py"
    long = {str(p.relative_to(ROOT)): n for p in ROOT.rglob("*.py")
            if (n := len(p.read_text().splitlines())) > MAX_LINES}  # fmt: skip
    assert not long, long


MAX_EXPERIMENTS = 1210  # 900 until issue 46's BenchMARL driver, plateau reading and MAPPO start


def test_experiments_hold_figure_choices_not_a_second_package():
    """experiments/ keeps this project's figure choices and studies (issue 42): what any
    user of the package needs lives in physrover.analysis, benchmarks in benchmarks/."""
    scripts = (Path(__file__).parents[1] / "experiments").glob("*.py")
    total = sum(len(p.read_text().splitlines()) for p in scripts)
    assert 0 < total <= MAX_EXPERIMENTS, total


def test_the_public_surface():
    for name in physrover.__all__:
        assert getattr(physrover, name) is not None, name
    assert physrover.RoverEnv.__module__ == "physrover.envs.gymnasium_env"


@pytest.mark.parametrize(
    "old, name, new",
    [
        ("physrover.runs", "train", "physrover.experiment.training"),
        ("physrover.runs", "read_metrics", "physrover.experiment.store"),
        ("physrover.render", "VideoWriter", "physrover.viz.video"),
        ("physrover.render", "RenderConfig", "physrover.viz.render"),
        ("physrover.sweep", "run_sweep", "physrover.experiment.execute"),
        ("physrover.stats", "mean_ci", "physrover.core.stats"),
        ("physrover.marl.parallel_env", "parallel_env", "physrover.envs.pettingzoo_env"),
    ],
)
def test_an_old_module_path_still_imports_with_a_deprecation_warning(old, name, new):
    import sys

    sys.modules.pop(old, None)
    with pytest.warns(DeprecationWarning, match=f"{old} is now .*{new}"):
        module = importlib.import_module(old)
    assert getattr(module, name) is getattr(importlib.import_module(new), name)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        exec(f"from {old} import {name}", {})  # imported once: no second warning
    with pytest.raises(AttributeError, match="has no attribute 'nothing'"):
        module.nothing  # noqa: B018


def test_the_kernel_cache_is_keyed_by_every_source_file(tmp_path, monkeypatch):
    """numba checks only a kernel's own file against its cache: a change anywhere in the
    package must move the cache to a new directory (physrover.core.compiled)."""
    from physrover.core import compiled

    (tmp_path / "a.py").write_text("x = 1\n")
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "b.py").write_text("y = 2\n")
    before = compiled.sources_key(tmp_path)
    assert compiled.sources_key(tmp_path) == before
    (tmp_path / "sub" / "b.py").write_text("y = 3\n")
    assert compiled.sources_key(tmp_path) != before
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "cache"))
    assert compiled.cache_dir() == str(tmp_path / "cache" / f"numba-{compiled.sources_key()}")


# The domain's rooms (physrover/domain/, DESIGN.md), lowest first: each imports itself and
# the rooms listed for it, so a rule lives where its concept does.
DOMAIN_ROOMS = {
    "state": set(),
    "broadphase": set(),
    "obstacles": set(),
    "agents": {"state"},
    "motion": {"state", "broadphase", "obstacles", "agents"},
    "sensing": {"state", "broadphase", "agents"},
    "scoring": {"state", "agents"},
    "layouts": set(),
    "scenarios": {"obstacles", "layouts"},
    "plan": {"agents", "motion", "sensing", "scoring"},
    "step": {"state", "agents", "motion", "sensing", "scoring"},
    "start": {"agents", "scenarios"},
    "world": {"state", "agents", "motion", "scoring", "scenarios", "plan", "step", "start"},
}


def _domain_room(module: str) -> str:
    room = module.split(".")[1]
    assert room in DOMAIN_ROOMS, f"physrover.{module} is in no room of the domain's map"
    return room


def test_the_domain_is_organised_by_concept():
    """Each room of physrover/domain/ imports only the rooms below it in the map; each
    folder says what it owns and what it may import."""
    crossing = []
    for module, targets in _imports().items():
        if not module.startswith("domain.") or module.endswith("__init__"):
            continue
        room = _domain_room(module)
        for target, _ in targets:
            if target.startswith("domain.") and _domain_room(target) not in DOMAIN_ROOMS[room] | {
                room
            }:
                crossing.append(f"physrover.{module} imports physrover.{target}")
    assert not crossing, "\n".join(crossing)
    for folder in ("agents", "motion", "sensing", "scoring"):
        doc = ast.get_docstring(ast.parse((ROOT / "domain" / folder / "__init__.py").read_text()))
        assert doc and "Owns" in doc and "May import" in doc, f"physrover/domain/{folder}"
    modules = {p.stem for p in (ROOT / "domain").glob("*.py")} - {"__init__"}
    folders = {p.name for p in (ROOT / "domain").iterdir() if (p / "__init__.py").is_file()}
    assert modules | folders == set(DOMAIN_ROOMS)


def test_no_private_name_is_imported_across_modules():
    private = []
    for path in ROOT.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("physrover"):
                private += [f"{path.relative_to(ROOT)}: {a.name}" for a in node.names
                            if a.name.startswith("_") and a.name != "__version__"]  # fmt: skip
    assert not private, private


STEP_PARTS = {
    "move": {"move_team"},
    "sense": {"sense_team", "sense_classes", "sense", "lidar_rows"},
    "score": {"score_team", "score"},
}


def _calls(functions: dict, name: str, seen: set) -> set:
    """The names function ``name`` calls, itself or through the functions of its module."""
    out = set()
    for c in ast.walk(functions[name]):
        if isinstance(c, ast.Call) and isinstance(c.func, ast.Name | ast.Attribute):
            callee = c.func.id if isinstance(c.func, ast.Name) else c.func.attr
            out.add(callee)
            if callee in functions and callee not in seen:
                out |= _calls(functions, callee, seen | {callee})
    return out


def test_the_step_is_composed_once():
    """Only physrover.domain.step calls (itself or through helpers of its module) the
    kernels of more than one part of the step (move, sense, score): a second composition,
    in the world, a learner's episode or an env, fails here."""
    composers = []
    for path in ROOT.rglob("*.py"):
        functions = {node.name: node for node in ast.walk(ast.parse(path.read_text()))
                     if isinstance(node, ast.FunctionDef)}  # fmt: skip
        for name in functions:
            called = _calls(functions, name, {name})
            if sum(bool(called & names) for names in STEP_PARTS.values()) > 1:
                composers.append(f"{path.relative_to(ROOT)}:{name}")
    expected = ["domain/step.py:step_team", "domain/step.py:step_teams",
                "domain/step.py:step_teams_at"]  # fmt: skip
    assert sorted(composers) == expected, composers
