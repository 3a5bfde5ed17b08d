"""Every code block of the documentation works as printed.

- ```python blocks run, page by page in order, in a scratch directory (what they write is
  checked where the page promises it);
- the Getting-started page's ```bash blocks run for real, in order (but its install block);
- every other ```bash line that calls ``physrover`` is a command the CLI accepts (parsed,
  not run: some are hours of training), and the rest is valid shell (``bash -n``);
- links between the pages point at pages that exist (``mkdocs build --strict`` in CI checks
  them again, with the API reference).
"""

import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import load_file

from physrover.cli import build_parser
from physrover.config import RunConfig

ROOT = Path(__file__).parent.parent
DOCS = ROOT / "docs"
PAGES = sorted(p for p in DOCS.rglob("*.md") if "assets" not in p.relative_to(DOCS).parts)


@pytest.fixture(autouse=True)
def _registries_as_they_were():
    """A page's examples register parts of their own (a credit, a fitness method, a
    trainer); they are unregistered after its test, so that a test listing a registry (the
    plots' colour per method) sees the same names whichever worker ran the page first."""
    from physrover.core import registry

    saved = [(r, dict(r._entries), set(r._aliases)) for r in vars(registry).values()
             if isinstance(r, registry.Registry)]  # fmt: skip
    yield
    for r, entries, aliases in saved:
        r._entries.clear()
        r._entries.update(entries)
        r._aliases.clear()
        r._aliases.update(aliases)


def _blocks(page: Path, language: str) -> list[str]:
    return re.findall(rf"^```{language}\n(.*?)^```", page.read_text(), re.S | re.M)


def _id(page: Path) -> str:
    return str(page.relative_to(DOCS))


@pytest.mark.parametrize("page", [p for p in PAGES if _blocks(p, "python")], ids=lambda p: _id(p))
def test_python_blocks_run(page, tmp_path, monkeypatch):
    if "benchmarl" in page.name:  # its own venv (.ci/run): BenchMARL pins older packages
        pytest.importorskip("benchmarl")
    monkeypatch.chdir(tmp_path)
    namespace: dict = {}
    for i, block in enumerate(_blocks(page, "python")):
        exec(compile(block, f"{_id(page)} block {i + 1}", "exec"), namespace)  # noqa: S102
    if page.name == "extending.md":
        metrics = (tmp_path / "runs" / "extending" / "metrics.csv").read_text().splitlines()
        assert len(metrics) == 1 + 20
        config = (tmp_path / "runs" / "extending" / "config.toml").read_text()
        assert '[scenario]\nkind = "line"' in config and 'kind = "poi-distances"' in config
        blend = tmp_path / "runs" / "blend"  # a fitness method with its own settings
        assert len((blend / "metrics.csv").read_text().splitlines()) == 1 + 5
        assert RunConfig.load(blend / "config.toml").settings.weight == 0.25
        run = tmp_path / "runs" / "random-search"
        metrics = (run / "metrics.csv").read_text().splitlines()
        assert len(metrics) == 1 + 20 and metrics[-1].split(",")[-2:] == ["200", "10000"]
        assert "[random-search]\nnum_envs = 10\ntotal_episodes = 200\n" in (
            (run / "config.toml").read_text()
        )
    if page.name == "torchrl-benchmarl.md":  # two iterations, BenchMARL's csv of each
        (frames,) = tmp_path.rglob("scalars/counters_total_frames.csv")
        assert frames.read_text().split() == ["0,600.0", "1,1200.0"]


def _commands(block: str) -> list[str]:
    """The block's commands, continuation lines joined, comments dropped."""
    text = re.sub(r"\\\n\s*", " ", block)
    return [line.split(" #")[0].strip() for line in text.splitlines()
            if line.strip() and not line.lstrip().startswith("#")]  # fmt: skip


@pytest.mark.parametrize("page", [p for p in PAGES if _blocks(p, "bash")], ids=lambda p: _id(p))
def test_bash_blocks_are_commands_the_cli_accepts(page):
    parser = build_parser()
    for block in _blocks(page, "bash"):
        checked = subprocess.run(["bash", "-n"], input=block, text=True, capture_output=True)
        assert checked.returncode == 0, f"{_id(page)}: {checked.stderr}\n{block}"
        for command in _commands(block):
            for part in re.split(r"&&|;|\|", command):
                if not part.strip().startswith("physrover "):
                    continue
                words = shlex.split(part)
                if words:
                    try:
                        parser.parse_args(words[1:])
                    except SystemExit as exc:
                        pytest.fail(f"{_id(page)}: `{part.strip()}` is not accepted ({exc})")


@pytest.mark.long
def test_the_getting_started_page_runs_as_printed(tmp_path):
    """Its commands, in order, in a fresh directory (the sweep it runs is shipped in the
    package); the install block is the machine's, not the test's."""
    blocks = _blocks(DOCS / "getting-started.md", "bash")
    assert "pip install -e ." in blocks[0]
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}"}
    for block in blocks[1:]:
        for command in _commands(block):
            done = subprocess.run(command, shell=True, cwd=tmp_path, env=env, text=True,
                                  capture_output=True, timeout=600)  # fmt: skip
            assert done.returncode == 0, f"{command}\n{done.stdout[-2000:]}{done.stderr[-2000:]}"
    run = tmp_path / "runs" / "tutorial"
    assert (run / "curves.png").stat().st_size > 0 and (run / "team.mp4").stat().st_size > 0
    assert len((run / "metrics.csv").read_text().splitlines()) == 1 + 400  # resumed to 400
    results = tmp_path / "runs" / "sweeps" / "results"
    assert len((results / "runs.csv").read_text().splitlines()) == 1 + 12
    assert "| max-critic | 2 |" in (results / "cells.md").read_text()


def test_the_agent_classes_training_example_learns(tmp_path):
    """The page's team that picks UAVs, trained as its command says but for 200 of its
    1000 generations: the learning curve has climbed as the page says (from about 2.5 over
    the first 10 generations to about 4.5 after 100; 5-6 at 1000)."""
    from physrover.experiment.training import train

    page = (DOCS / "user-guide" / "agent-classes.md").read_text()
    (toml,) = [b for b in _blocks_text(page, "toml") if 'action = "pick"' in b and "[[pois]]" in b]
    config = RunConfig.from_toml(toml).with_overrides({"method": "D", "feedback": "ID-step"})
    assert "--method D --set feedback=ID-step" in page and "--generations 1000" in page
    run = train(config, tmp_path / "run", generations=200, progress=False)
    rows = (run / "metrics.csv").read_text().splitlines()
    header = rows[0].split(",")
    eval_G = [float(r.split(",")[header.index("eval_G")]) for r in rows[1:]]
    assert len(eval_G) == 200
    first, last = sum(eval_G[:10]) / 10, sum(eval_G[-50:]) / 50
    assert first < 3.0 and last >= 3.5 and last >= first + 1.0  # it learned


def test_the_failing_agents_example_learns(tmp_path):
    """The page's team that loses three rovers an episode, trained as its command says but
    for 150 of its 300 generations: the curve has climbed as the page says (from about 0.3
    over the first 10 generations to about 4.5 near generation 100; 7.9 at 300)."""
    from physrover.experiment.training import train

    page = (DOCS / "user-guide" / "failures.md").read_text()
    command = '--method D --set n_req=2 --set n_failing=3 --set "between=[0,25]"'
    assert command in page and "--generations 300" in page
    config = RunConfig().with_overrides({"method": "D", "n_req": 2, "n_failing": 3,
                                         "between": [0, 25]})  # fmt: skip
    run = train(config, tmp_path / "run", generations=150, progress=False)
    rows = (run / "metrics.csv").read_text().splitlines()
    header = rows[0].split(",")
    eval_G = [float(r.split(",")[header.index("eval_G")]) for r in rows[1:]]
    first, last = sum(eval_G[:10]) / 10, sum(eval_G[-50:]) / 50
    assert len(eval_G) == 150 and first < 1.0 and last >= 3.5  # it learned


def _blocks_text(text: str, language: str) -> list[str]:
    return re.findall(rf"^```{language}\n(.*?)^```", text, re.S | re.M)


LINK = re.compile(r"\]\(([^)#]+)(?:#[^)]*)?\)")
"""A Markdown link's target, without its anchor."""


def _hooks():
    """docs/hooks.py, the MkDocs hook module (a file, not a package)."""
    return load_file(DOCS / "hooks.py", "hooks")


def test_links_between_pages_point_at_pages():
    for page in PAGES:
        for target in LINK.findall(page.read_text()):
            if re.match(r"[a-z]+://", target):
                continue
            assert (page.parent / target).exists(), f"{_id(page)} links to {target}"


@pytest.mark.skipif(shutil.which("mkdocs") is None, reason="needs the docs extra (mkdocs)")
def test_the_nav_lists_every_page():
    nav = (ROOT / "mkdocs.yml").read_text()
    for page in PAGES:
        assert _id(page) in nav, f"{_id(page)} is in no nav entry of mkdocs.yml"


def _roles_extension():
    """docs/griffe_roles.py, imported as mkdocstrings imports it."""
    pytest.importorskip("griffe", reason="needs the docs extra (mkdocstrings)")
    sys.path.insert(0, str(DOCS))
    try:
        import griffe_roles
    finally:
        sys.path.remove(str(DOCS))
    return griffe_roles


def test_the_api_reference_links_every_sphinx_role():
    """No docstring reaches the API pages with a raw Sphinx role, and every role naming
    something of physrover links to it (a stale name, as ``StackedMLP`` was, fails)."""
    import builtins
    import importlib.util

    import griffe

    roles = _roles_extension()
    extension = roles.SphinxRoles()
    package = griffe.load("physrover", search_paths=[str(ROOT)],
                          extensions=griffe.load_extensions(extension))  # fmt: skip
    links, left = 0, []

    def visit(obj):
        nonlocal links
        if obj.docstring is not None:
            links += obj.docstring.value.count("<autoref ")
            left.extend((obj.path, m.group(0)) for m in roles.ROLE.finditer(obj.docstring.value))
        for member in obj.members.values():
            if not member.is_alias:
                visit(member)

    visit(package)
    assert left == [] and links > 500
    for where, target in extension.unresolved:  # outside the package: builtins, libraries
        first = target.lstrip("~.").split(".")[0]
        outside = hasattr(builtins, first) or importlib.util.find_spec(first) is not None
        assert outside and first != "physrover", f"{where}: {target} names nothing"


def test_roles_resolve_from_their_scope_as_python_would():
    import griffe

    roles = _roles_extension()
    package = griffe.load("physrover", search_paths=[str(ROOT)])
    names = roles.index(package)
    step = package["domain.step"]
    assert roles.resolve("step_team", step, package, names) == "physrover.domain.step.step_team"
    assert roles.resolve("WorldState", step, package, names) == "physrover.domain.state.WorldState"
    assert roles.resolve("physrover.domain.plan.StepPlan.motion", step, package,
                         names) == "physrover.domain.plan.StepPlan.motion"  # fmt: skip
    assert roles.resolve("numpy.ndarray", step, package, names) is None
    unresolved = []
    text = roles.rewrite(":func:`~physrover.domain.step.step_team` and :class:`numpy.ndarray`",
                         step, package, names, unresolved)  # fmt: skip
    assert text == (
        '<autoref identifier="physrover.domain.step.step_team" optional>'
        "<code>step_team()</code></autoref> and <code>numpy.ndarray</code>"
    )
    assert unresolved == [("physrover.domain.step", "numpy.ndarray")]


def test_the_results_page_table_is_the_committed_sweep_s():
    """The table of Figs 4-7 on the Results page is fig7_long_final_vs_nreq.csv, rounded."""
    import csv

    rows = csv.DictReader((ROOT / "experiments/results/fig7_long_final_vs_nreq.csv").open())
    final = {(r["group"], int(r["n_req"])): float(r["mean"]) for r in rows}
    page = (DOCS / "results.md").read_text()
    table = page[page.index("| coupling n_req |") :].split("\n\n")[0].splitlines()[2:]
    methods = ["D", "average", "mean-critic", "max-critic"]
    assert len(table) == 4
    for line in table:
        cells = [c.strip().strip("*") for c in line.strip("|").split("|")]
        n_req = int(cells[0])
        for method, cell in zip(methods, cells[1:], strict=True):
            assert float(cell.split("+-")[0]) == round(final[method, n_req], 2), (method, n_req)


def test_every_shipped_sweep_is_a_row_of_what_was_run():
    """A number's sweep file, commit, seeds and compute are one look away: the table under
    "What was run" in RESULTS.md names every shipped sweep (the smoke test aside)."""
    from physrover.experiment.sweep import shipped_sweeps

    text = (ROOT / "experiments/results/RESULTS.md").read_text()
    section = text.split("\n## What was run\n")[1].split("\n## ")[0]
    listed = set(re.findall(r"^\| `([\w.-]+)`", section, re.MULTILINE))
    assert sorted(set(shipped_sweeps()) - {"smoke"} - listed) == []


def test_the_standing_table_on_the_site_is_the_committed_cells():
    """Every cell of the Results page's standing table is the committed cells.md value
    of the sweep its row names (mean and 95% interval, as rounded there)."""
    cells = {}
    for path in ("cells.md", "standing-table/cells.md", "standing-table-low/cells.md",
                 "step-target-long/cells.md", "standing-table-winner/cells.md",
                 "standing-table-lenient/cells.md"):  # fmt: skip
        sweep = None
        for line in (ROOT / "experiments/results" / path).read_text().splitlines():
            if line.startswith("### "):
                sweep = line[4:].strip()
            elif line.startswith("| ") and "+-" in line.split("|")[-3]:
                parts = [c.strip() for c in line.strip("|").split("|")]
                if not parts[1].isdigit():  # the header
                    continue
                feedback = parts[2] if sweep == "standing-table" else "D"
                if sweep == "step-target-long":  # feedback and the critic's target
                    feedback = f"{parts[2]}/{parts[3]}"
                elif sweep == "standing-table-winner":  # D++, per-step targets: the file's base
                    feedback = "D++/step"
                cells[sweep, parts[0], feedback, int(parts[1])] = parts[-2]
    rows = {"D": ("D", "D"), "G": ("G", "D"), "D on D++": ("D", "D++"),
            "average of 10 episodes": ("average", "D"),
            "leniency (max of D over 10 episodes)": ("leniency", "D"),
            "hall of fame (D with the best team as teammates)": ("hall-of-fame", "D"),
            "mean critic": ("mean-critic", "D"),
            "max critic": ("max-critic", "D"),
            'max critic on D++, per-step targets (`feedback = "D++"`, `critic_target = "step"`)':
            ("max-critic", "D++/step")}  # fmt: skip
    page = (DOCS / "results.md").read_text()
    table = page[page.index("| method | n_req 1 |") :].split("\n\n")[0].splitlines()[2:]
    assert [line.split("|")[1].strip() for line in table] == list(rows)
    for line in table:
        parts = [c.strip().strip("*") for c in line.strip("|").split("|")]
        method, feedback = rows[parts[0]]
        sweeps = [name.strip(" `") for name in parts[7].split(",")]
        for n_req, shown in enumerate(parts[1:7], start=1):
            found = [cells[s, method, feedback, n_req] for s in sweeps
                     if (s, method, feedback, n_req) in cells]  # fmt: skip
            if shown == "":  # a cell its sweep did not run
                assert found == [], (parts[0], n_req)
                continue
            assert len(found) == 1, (parts[0], n_req)
            expected = "0.00" if found[0] == "0.00 +- 0.00" else found[0]
            assert shown == expected, (parts[0], n_req, shown, expected)


def _cells_md(path: Path) -> dict[tuple[str, ...], tuple[str, int]]:
    """{(method, n_req, *grid values): (mean +- CI, seeds)} of a committed cells.md."""
    cells = {}
    for line in path.read_text().splitlines():
        parts = [c.strip() for c in line.strip("|").split("|")]
        if line.startswith("| ") and len(parts) >= 4 and parts[1].isdigit():
            cells[tuple(parts[:-2])] = (parts[-2], int(parts[-1]))
    return cells


def test_the_rows_short_of_seeds_on_the_site_are_the_committed_runs():
    """The Results page's table of rows still short of 10 seeds (MAPPO, its wide-std and
    curriculum rows, IPPO) shows each cell as the committed runs have it: each seed's
    final G in seed order, "X on each", "mean +- CI (seeds)" as cells.md rounds it, or
    "not yet" (or empty: a cell its sweep does not run) with no run."""
    import csv

    results = ROOT / "experiments/results"
    rows = {"MAPPO,": ("standing-table-marl", ("true",)),
            "MAPPO with `init_log_std = 1` (": ("mappo-wide-std", ()),
            "MAPPO with `init_log_std = 1` and the coupling": ("mappo-curriculum-screen", ()),
            "IPPO": ("standing-table-marl", ("false",))}  # fmt: skip
    page = (DOCS / "results.md").read_text()
    start = page.index("| method | n_req 1 |", page.index("short of 10 seeds"))
    table = page[start:].split("\n\n")[0].splitlines()[2:]
    checked = set()
    for line in table:
        parts = [c.strip() for c in line.strip("|").split("|")]
        key = next((k for k in rows if parts[0].startswith(k)), None)
        if key is None:  # MADDPG and BenchMARL: tables of their own
            continue
        sweep, grid = rows[key]
        assert parts[7] == f"`{sweep}`", parts[0]
        runs = list(csv.DictReader((results / sweep / "runs.csv").open()))
        runs = [r for r in runs if tuple(r[f] for f in r if f.startswith("mappo.")) == grid]
        cells = _cells_md(results / sweep / "cells.md")
        for n_req, shown in enumerate(parts[1:7], start=1):
            cell = sorted(
                (r for r in runs if int(r["n_req"]) == n_req), key=lambda r: int(r["seed"])
            )
            finals = [f"{float(r['final_G']):.2f}" for r in cell]
            shown = shown.replace("**", "")
            where = (parts[0], n_req, shown)
            if shown in ("not yet", ""):  # "": a cell its sweep does not run
                assert finals == [], where
            elif shown.endswith(" on each"):
                assert finals and set(finals) == {shown.removesuffix(" on each")}, where
            elif "+-" in shown:
                value, seeds = re.fullmatch(r"(.+ \+- \S+) \((\d+)\)", shown).groups()
                assert cells[("mappo", str(n_req)) + grid] == (value, int(seeds)), where
                assert len(finals) == int(seeds), where
            else:
                assert shown.split(", ") == finals, where
        checked.add(key)
    assert checked == set(rows)


def test_results_in_full_are_on_the_site_without_their_data():
    """RESULTS.md is a page of the site (its links to the docs rewritten by docs/hooks.py),
    its figures with it, the CSVs behind them not (46 MB the site never showed)."""
    from types import SimpleNamespace

    config = (ROOT / "mkdocs.yml").read_text()
    assert "assets/results/RESULTS.md" in config.split("nav:")[1]
    assert "!assets/results/RESULTS.md" in config and "assets/results/**/*.csv" in config
    hooks = _hooks()
    text = (ROOT / "experiments/results/RESULTS.md").read_text()
    page = SimpleNamespace(file=SimpleNamespace(src_uri=hooks.RESULTS))
    shown = hooks.on_page_markdown(text, page)
    site_page = DOCS / "assets/results"
    for target in LINK.findall(shown):
        if not re.match(r"[a-z]+://", target):
            assert Path(os.path.normpath(site_page / target)).exists(), target  # as the site
    other = SimpleNamespace(file=SimpleNamespace(src_uri="results.md"))
    assert hooks.on_page_markdown(text, other) == text


def test_the_changelog_links_resolve_in_the_repository_and_on_the_site():
    """CHANGELOG.md's links resolve from the repository root, and on the site's changelog
    page (which includes it, its links rewritten by docs/hooks.py) from docs/. CI's
    ``mkdocs build --strict`` misses a broken one if it runs with ``--quiet``."""
    from types import SimpleNamespace

    hooks = _hooks()
    text = (ROOT / "CHANGELOG.md").read_text()
    page = SimpleNamespace(file=SimpleNamespace(src_uri=hooks.CHANGELOG))
    config = {"config_file_path": str(ROOT / "mkdocs.yml")}
    shown = hooks.on_page_markdown((DOCS / hooks.CHANGELOG).read_text(), page, config=config)
    assert hooks.CHANGELOG_SNIPPET not in shown and "](docs/" in text
    assert shown.strip().endswith(text.replace("](docs/", "](").strip())
    for where, markdown in ((ROOT, text), (DOCS, shown)):
        targets = [t for t in LINK.findall(markdown) if not re.match(r"[a-z]+://", t)]
        for target in targets:
            assert (where / target).exists(), f"{target} from {where}"
    assert "--quiet" not in (ROOT / ".ci/run").read_text().split("mkdocs build")[1].split("\n")[0]


def test_the_site_keeps_identifiers_whole_and_names_each_section_once():
    """Issue 44's layout points, as configuration a browser would show (checked by eye at
    1400 px in headless Chromium): table cells never break an identifier mid-word, the API
    reference section is its own index page (not a section and its first item of one name),
    and the long pages are cut by subheadings."""
    config = (ROOT / "mkdocs.yml").read_text()
    assert "navigation.indexes" in config and "stylesheets/extra.css" in config
    css = (DOCS / "stylesheets/extra.css").read_text()
    assert "td code" in css and "white-space: nowrap" in css
    for page in ("user-guide/training.md", "user-guide/watching.md"):
        assert len(re.findall(r"^## ", (DOCS / page).read_text(), re.M)) >= 4, page


def test_one_torch_line_takes_the_cpu_build_anywhere():
    """The README's quick start, the PyPI README and Getting started install torch with the
    same line: the version CI installs (``.ci/run``), with PyTorch's CPU index added, so that
    pip prefers its ``+cpu`` build to PyPI's CUDA build on a laptop and, where that index is
    out of reach, takes the CPU build on local disk (a line that pinned the local file alone
    pulled a CUDA build of several GB anywhere else)."""
    (pin,) = re.findall(
        r"pip install --quiet (torch==[\d.]+)\n", (ROOT / ".ci" / "run").read_text()
    )
    line = f"pip install {pin} --extra-index-url https://download.pytorch.org/whl/cpu --retries 0"
    for page in (ROOT / "README.md", ROOT / "README.pypi.md", DOCS / "getting-started.md"):
        installs = re.findall(r"pip install [^&\n]*torch[^&\n]*", page.read_text())
        assert installs and all(i.strip() == line for i in installs if "torchvision" not in i), (
            page.name, installs)  # fmt: skip
