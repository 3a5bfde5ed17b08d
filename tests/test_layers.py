"""The package's layers: nothing imports from a layer above it, and no module-level cycles.

Read from the source (every ``import physrover...`` / ``from physrover... import``, also
inside functions), so a new upward import fails here, not in a reader's head.
"""

import ast
from pathlib import Path

import physrover

ROOT = Path(physrover.__file__).parent

# Lowest first. A module may import from its own layer or below.
LAYERS = [
    {"registry", "compiled", "stats", "threads", "config", "progress", "provenance", "plugins"},
    {"domain"},  # the rover domain: state, kernels, physics, world
    {"render", "video"},  # frames and videos of the domain (the envs' render_mode)
    {"envs"},  # gymnasium envs over the world
    {"learn", "marl"},  # learners and MARL interfaces over the envs
    # run directories (the CCEA's and the gradient-based trainers') and what reads them
    {"runs", "trainer_runs", "evaluate", "curve_data", "plots", "compare"},
    {"playback", "sweep", "bench"},
    {"cli", "commands"},
]
PACKAGE_INIT = "__init__"  # the package's __init__ registers and re-exports: any layer


def _layer(module: str) -> int:
    top = module.split(".")[0]
    for level, names in enumerate(LAYERS):
        if top in names:
            return level
    raise AssertionError(f"physrover.{module} is in no layer: add it to LAYERS")


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
                        inner = node.names[0].name  # from physrover import plots
                    out.add((inner, id(node) in top_level))
        found[name] = out
    return found


def test_no_module_imports_from_a_layer_above_it():
    upward = []
    for module, targets in _imports().items():
        if module.split(".")[-1] == PACKAGE_INIT and module.count(".") == 0:
            continue
        for target, _ in targets:
            if not target or target.split(".")[0] in ("__version__",):
                continue
            if _layer(target) > _layer(module):
                upward.append(f"physrover.{module} imports physrover.{target}")
    assert not upward, "\n".join(upward)


def test_no_import_cycles_at_module_level():
    graph = {
        module: {t for t, top in targets if top and t}
        for module, targets in _imports().items()
        if not module.endswith(PACKAGE_INIT)
    }
    modules = set(graph)

    def resolve(target):  # "domain.world" may be a module or a name inside a package
        return target if target in modules else target.rsplit(".", 1)[0]

    state: dict[str, int] = {}

    def visit(node, path):
        state[node] = 1
        for nxt in map(resolve, graph.get(node, ())):
            if nxt not in modules:
                continue
            if state.get(nxt) == 1:
                raise AssertionError("import cycle: " + " -> ".join([*path, nxt]))
            if nxt not in state:
                visit(nxt, [*path, nxt])
        state[node] = 2

    for module in sorted(modules):
        if module not in state:
            visit(module, [module])


def test_layers_cover_every_module():
    for module in _imports():
        if module.split(".")[-1] != PACKAGE_INIT:
            _layer(module)


def test_the_kernel_cache_is_keyed_by_every_source_file(tmp_path, monkeypatch):
    """numba checks only a kernel's own file against its cache: a change anywhere in the
    package must move the cache to a new directory (physrover.compiled)."""
    from physrover import compiled

    (tmp_path / "a.py").write_text("x = 1\n")
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "b.py").write_text("y = 2\n")
    before = compiled.sources_key(tmp_path)
    assert compiled.sources_key(tmp_path) == before
    (tmp_path / "sub" / "b.py").write_text("y = 3\n")
    assert compiled.sources_key(tmp_path) != before
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "cache"))
    assert compiled.cache_dir() == str(tmp_path / "cache" / f"numba-{compiled.sources_key()}")
