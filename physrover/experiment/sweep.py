"""Sweeps: grids of training runs on a local process pool or on a Ray cluster.

A sweep file (TOML) names a base config and a grid::

    [sweep]
    name = "fig4-7"          # runs go under ROOT/name/ (ROOT: --root, default runs/sweeps)
    seeds = 5                # seeds 0 .. seeds-1 for every cell (--seeds N or A:B overrides)
    imports = ["my_parts.py"]  # optional: your own parts the grid names (physrover.core.plugins)

    [base.domain]            # the base RunConfig, as in a run's config.toml
    n_rovers = 15
    [base.learn]
    generations = 1000

    [grid]                   # any config field -> the values to try
    method = ["D", "average", "mean-critic", "max-critic"]
    n_req = [3, 4, 5, 6]

    [[variants]]             # optional: combinations that are not a product, each crossed
    motion = "ideal"         # with the grid (here: idealised, and physics without and
    [[variants]]             # with collisions; "ideal with collisions" would be a copy)
    motion = "physics"
    collisions = false

A method's own table in the base (``[base.critic]``, ``[base.sampled]``, ``[base.mappo]``:
:mod:`physrover.learn.configs`) is the settings of every run whose method takes it, so one
sweep can set the critics' and the average's settings beside D's runs.

Every cell x seed is one ``train`` run in its own directory, named by its grid values and
seed. Re-running a sweep skips finished runs and resumes interrupted ones from their
checkpoints; a crashed run is reported with its error and does not stop the others. Each
worker runs one training at a time with torch/BLAS pinned to one thread.

``--seeds A:B`` runs seeds A .. B-1 only: a sweep too long for one machine's lifetime can be
run in chunks of seeds (e.g. ``--seeds 0:5`` then ``--seeds 5:10``), each run's name and
results being those it has in the whole sweep. ``--skip-listed CSV`` leaves out the runs a
results table (``experiments/results/runs.csv``: columns sweep, run, generations) lists as
finished, so a later machine runs only what no earlier one finished (:func:`listed_finished`).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from physrover.config import (
    ConfigError,
    LearnConfig,
    RunConfig,
    load_toml_file,
    naming_file,
    settings_class,
    settings_tables,
)
from physrover.core import plugins
from physrover.experiment.claims import holder
from physrover.experiment.store import last_checkpoint


@dataclass(frozen=True)
class RunSpec:
    name: str
    config_toml: str
    out: str
    drop_state: bool = False
    """Delete the run's checkpoint (state.npz, state.prev.npz) when it finishes (see
    :func:`physrover.experiment.store.drop_state`)."""


@dataclass(frozen=True)
class Sweep:
    name: str
    base: RunConfig
    grid: dict[str, list[Any]]
    seeds: int
    variants: tuple[dict[str, Any], ...] = ({},)
    imports: tuple[str, ...] = ()
    """[sweep] imports: modules or .py files (relative to the sweep file) of the researcher's
    own parts that the runs name, imported when the file is loaded and by every worker
    (:mod:`physrover.core.plugins`)."""
    comparisons: tuple[dict[str, dict[str, Any]], ...] = ()
    """``[[comparisons]]``: the planned comparisons ``physrover results`` tests, each
    ``{"a": {field: value}, "b": {field: value}}`` and an optional ``"where"``, ``{field:
    [values]}`` (:mod:`physrover.analysis.comparisons`)."""
    tables: tuple[tuple[str, tuple[tuple[str, Any], ...]], ...] = ()
    """The base's tables of methods other than the base's own (``[base.sampled]`` when the
    base method is the max critic), as ``((section, ((field, value), ...)), ...)``: the
    settings of each run whose method takes them (:meth:`config`)."""

    def config(self, overrides: dict[str, Any]) -> RunConfig:
        """The config of a run: the base with ``overrides`` ({field: value}) and, if the
        run's method takes one of :attr:`tables`, that table's settings under them."""
        return _resolve(self.base, {s: dict(table) for s, table in self.tables}, overrides)

    @classmethod
    def load(cls, path: str | Path) -> Sweep:
        """The sweep in a TOML file, or a sweep shipped with physrover by its name
        (``fig4-7-long``: :func:`shipped_sweeps`); every error names the file."""
        path = resolve_sweep_file(path)
        data = load_toml_file(path)
        with naming_file(path):
            return cls._from_dict(data, path)

    @classmethod
    def _from_dict(cls, data: dict, path: str | Path) -> Sweep:
        tables = ("sweep", "base", "grid", "variants", "comparisons")
        unknown = sorted(set(data) - set(tables))
        if unknown:
            raise ConfigError(unknown[0], f"unknown sweep table (known: {', '.join(tables)})")
        meta = data.get("sweep", {})
        bad = sorted(set(meta) - {"name", "seeds", "imports"})
        if bad:
            raise ConfigError(bad[0], "unknown [sweep] key (known: name, seeds, imports)")
        imports = meta.get("imports", [])
        if not isinstance(imports, list) or not all(isinstance(i, str) for i in imports):
            raise ConfigError("imports", "must be a list of module names or .py paths")
        plugins.load(imports, base=Path(path).resolve().parent)  # before any name is checked
        base, tables = _base(data.get("base", {}))
        grid = data.get("grid", {})
        for field, values in grid.items():
            if not isinstance(values, list) or not values:
                raise ConfigError(field, "grid values must be a non-empty list")
            for value in values:  # the name must be a config field, each value valid
                _resolve(base, tables, {field: value})
        seeds = meta.get("seeds", 1)
        if not isinstance(seeds, int) or seeds < 1:
            raise ConfigError("seeds", f"must be a positive integer, got {seeds!r}")
        variants = tuple(data.get("variants", [{}]))
        points = itertools.product(*([(f, v) for v in values] for f, values in grid.items()))
        runs = [{**dict(point), **variant} for point in points for variant in variants]
        for run in runs:  # every run's config must be valid (a variant may need the grid's)
            _resolve(base, tables, run)
        name = str(meta.get("name", Path(path).stem))
        comparisons = _comparisons(data.get("comparisons", []), base, tables, runs)
        frozen = tuple((section, tuple(table.items())) for section, table in tables.items())
        return cls(name, base, grid, seeds, variants, tuple(imports), comparisons, frozen)

    def write_copy(self, root: str | Path, text: str) -> None:
        """The sweep file's ``text`` as ``ROOT/NAME/sweep.toml``, where ``physrover results``
        finds its planned comparisons (written again by each driver: the same text)."""
        from physrover.experiment.store import atomic_write

        folder = Path(root) / self.name
        folder.mkdir(parents=True, exist_ok=True)
        atomic_write(folder / SWEEP_COPY, text)

    def with_overrides(self, overrides: dict[str, Any]) -> Sweep:
        """The same sweep with ``overrides`` ({field: value}, as ``--set``) applied to every
        run, named ``NAME+field=value+...`` so that its runs never resume (or are resumed
        as) the runs of the sweep as its file has it. A grid or variant field cannot be
        overridden (each run has its own value)."""
        if not overrides:
            return self
        varied = set(self.grid) | {f for variant in self.variants for f in variant}
        for field in overrides:
            if field in varied:
                raise ConfigError(field, f"is varied by sweep {self.name}'s grid or variants; "
                                  "--set cannot override it (edit a copy of the file)")  # fmt: skip
        tables = {section: dict(table) for section, table in self.tables}
        own, mine = {}, settings_class(self.base.learn.method)
        common = {*LearnConfig.field_names(), *self.base.domain.flat_dict()}
        for field, value in overrides.items():  # a method's setting goes to its table
            section, _, name = field.rpartition(".")
            if not section and name in common:
                own[field] = value
                continue
            others = [s for s in ([section] if section else settings_tables())
                      if s in settings_tables() and (mine is None or s != mine.section)
                      and name in _table_class(s).field_names()]  # fmt: skip
            for other in others:
                tables.setdefault(other, {})[name] = value
                try:
                    _table_class(other).from_dict(tables[other])
                except ConfigError as exc:
                    raise ConfigError(f"{other}.{exc.field}", exc.message) from None
            takes = mine is not None and section in ("", mine.section)
            if (takes and name in mine.field_names()) or not others:
                own[field] = value
        base = self.base.with_overrides(own)
        suffix = "+".join(f"{field}={_slug(value)}" for field, value in sorted(overrides.items()))
        frozen = tuple((section, tuple(table.items())) for section, table in tables.items())
        return replace(self, name=f"{self.name}+{suffix}", base=base, tables=frozen)

    def runs(
        self, root: str | Path, seeds: int | range | None = None, drop_state: bool = False
    ) -> list[RunSpec]:
        """Every cell x seed, with its resolved config; invalid cells are config errors.
        In the order they run: every cell's first seed, then every cell's second, ... (so a
        sweep stopped part-way has its finished seeds spread evenly over the cells).
        ``seeds``: how many (seeds 0 .. seeds-1) or which (a range); default the file's.
        ``drop_state``: each run deletes its checkpoint when it finishes."""
        fields = list(self.grid)
        specs = []
        cells = list(
            itertools.product(itertools.product(*(self.grid[f] for f in fields)), self.variants)
        )
        chosen = seeds if isinstance(seeds, range) else range(seeds or self.seeds)
        for seed in chosen:  # seed-major: a sweep stopped part-way leaves every cell its seeds
            for values, variant in cells:
                overrides = {**dict(zip(fields, values, strict=True)), **variant, "seed": seed}
                config = self.config(overrides)
                name = "_".join(f"{f}={_slug(v)}" for f, v in overrides.items())
                out = str(Path(root) / self.name / name)
                specs.append(RunSpec(name, config.to_toml(), out, drop_state))
        return specs


def shipped_sweeps() -> dict[str, Path]:
    """{name: file} of the sweep files shipped in the package (``physrover/sweeps``: the
    paper's figures, the studies of RESULTS.md, ``smoke``), so an installed wheel reproduces
    the paper without the repository."""
    folder = Path(__file__).resolve().parent.parent / "sweeps"
    return {p.stem: p for p in sorted(folder.glob("*.toml"))}


def resolve_sweep_file(path: str | Path) -> Path:
    """``path`` if it names a file, else the shipped sweep of that name (with or without
    ``.toml``); a ConfigError listing the shipped ones otherwise."""
    given = Path(path)
    if given.is_file():
        return given
    shipped = shipped_sweeps()
    name = given.name.removesuffix(".toml")
    if given.parent == Path(".") and name in shipped:
        return shipped[name]
    known = ", ".join(shipped)
    raise ConfigError(str(path), f"no such sweep file, nor a shipped sweep (shipped: {known})")


def parse_seeds(text: str) -> int | range:
    """``--seeds``: ``N`` (seeds 0 .. N-1) or ``A:B`` (seeds A .. B-1), N >= 1, 0 <= A < B."""
    try:
        if ":" in text:
            first, stop = (int(part) for part in text.split(":"))
            if 0 <= first < stop:
                return range(first, stop)
        elif int(text) >= 1:
            return int(text)
    except ValueError:
        pass
    raise ConfigError(
        "seeds", f"must be N >= 1 (seeds 0..N-1) or A:B with 0 <= A < B, got {text!r}"
    )


def listed_finished(specs: list[RunSpec], table: str | Path, sweep: str) -> set[str]:
    """The names of the ``specs`` that the CSV ``table`` (columns ``sweep``, ``run``,
    ``generations``) lists under ``sweep`` with at least the generations their config asks
    for: runs an earlier machine finished."""
    import csv

    path = Path(table)
    if not path.is_file():
        raise ConfigError("skip-listed", f"{path} is not a file")
    with open(path, newline="") as f:
        reader = csv.DictReader(f)
        missing = {"sweep", "run", "generations"} - set(reader.fieldnames or ())
        if missing:
            raise ConfigError("skip-listed", f"{path} has no column {sorted(missing)[0]!r}")
        done = {row["run"]: int(row["generations"]) for row in reader if row["sweep"] == sweep}
    return {
        spec.name
        for spec in specs
        if spec.name in done and done[spec.name] >= RunConfig.from_toml(spec.config_toml).length
    }


def _slug(value: Any) -> str:
    if isinstance(value, (list, tuple)):
        return "-".join(_slug(v) for v in value)
    return str(value).lower() if isinstance(value, bool) else str(value)


SWEEP_COPY = "sweep.toml"
"""The copy of its file a sweep keeps in its folder (:meth:`Sweep.write_copy`)."""


def _comparisons(given: Any, base: RunConfig, tables: dict,
                 runs: list[dict[str, Any]]) -> tuple[dict[str, dict[str, Any]], ...]:  # fmt: skip
    """``[[comparisons]]`` checked: each an ``a`` and a ``b`` table of config fields and
    values that differ somewhere (the runs each side picks), each side valid with some run
    of the sweep (``runs``: each run's grid and variant fields)."""
    if not isinstance(given, list):
        raise ConfigError("comparisons", "must be [[comparisons]] tables, each with a and b")
    out = []
    for k, table in enumerate(given):
        where = f"comparisons[{k}]"
        if not isinstance(table, dict) or not {"a", "b"} <= set(table) <= {"a", "b", "where"}:
            raise ConfigError(where, 'needs a and b (and may have where), e.g. '
                              'a = { method = "D" }')  # fmt: skip
        for side in ("a", "b"):
            if not isinstance(table[side], dict) or not table[side]:
                raise ConfigError(f"{where}.{side}", "must be a table of config fields")
            _valid_somewhere(base, tables, runs, table[side])
        if table["a"] == table["b"]:
            raise ConfigError(where, "a and b pick the same runs")
        cells = table.get("where", {})
        if not isinstance(cells, dict) or not all(isinstance(v, list) and v
                                                  for v in cells.values()):  # fmt: skip
            raise ConfigError(f"{where}.where", "must be a table of grid fields and lists of "
                              "values, e.g. where = { n_req = [5, 6] }")  # fmt: skip
        for value in itertools.product(*cells.values()):
            _valid_somewhere(base, tables, runs, dict(zip(cells, value, strict=True)))
        out.append({k: dict(v) for k, v in table.items()})
    return tuple(out)


def _valid_somewhere(base: RunConfig, tables: dict, runs: list[dict[str, Any]],
                     side: dict[str, Any]) -> None:  # fmt: skip
    """A comparison's side is config fields with values some run of the sweep can have;
    else the error of the first run tried."""
    first = None
    for run in runs:
        try:
            _resolve(base, tables, {**run, **side})
            return
        except ConfigError as exc:
            first = first or exc
    raise first


def _base(doc: dict[str, Any]) -> tuple[RunConfig, dict[str, dict[str, Any]]]:
    """A sweep's [base.*] as the base RunConfig and the tables of methods other than its
    own (:attr:`Sweep.tables`), each validated as its class."""
    doc = dict(doc)
    base_method = doc.get("learn", {}).get("method", RunConfig().learn.method)
    own = settings_class(base_method) if isinstance(base_method, str) else None
    tables = {}
    for section in settings_tables():
        if section in doc and (own is None or section != own.section):
            table = doc.pop(section)
            try:
                _table_class(section).from_dict(table)
            except ConfigError as exc:
                raise ConfigError(f"base.{section}.{exc.field}", exc.message) from None
            tables[section] = dict(table)
    return RunConfig.from_dict(doc), tables


def _table_class(section: str) -> type:
    """The settings class whose TOML table is ``section``."""
    return settings_class(settings_tables()[section][0])


def _resolve(base: RunConfig, tables: dict, overrides: dict[str, Any]) -> RunConfig:
    """``base`` with ``overrides`` and the table in ``tables`` of the run's method under
    them (see :meth:`Sweep.config`)."""
    method = overrides.get("method", overrides.get("learn.method", base.learn.method))
    cls = settings_class(method) if isinstance(method, str) else None
    table = tables.get(cls.section, {}) if cls is not None else {}
    under = {f"{cls.section}.{k}": v for k, v in table.items()
             if k not in overrides and f"{cls.section}.{k}" not in overrides}  # fmt: skip
    return base.with_overrides({**under, **overrides})


def run_status(spec: RunSpec) -> str:
    """ "done", "partial" (has a checkpoint or a started directory) or "new"."""
    return run_progress(spec)[0]


def run_progress(spec: RunSpec) -> tuple[str, int, int]:
    """(:func:`run_status`, the generation of the run's last checkpoint (0 without one),
    the run's length): a resume starts from that checkpoint, so a run that is training
    now is reported as far as it has checkpointed."""
    out = Path(spec.out)
    length = RunConfig.from_toml(spec.config_toml).length
    if not out.exists():
        return "new", 0, length
    generation = last_checkpoint(out)
    if generation is None:
        return "partial", 0, length
    return ("done" if generation >= length else "partial"), generation, length


def status_report(name: str, specs: list[RunSpec], listed: int = 0) -> list[str]:
    """``physrover sweep FILE --status``: a line per run that is not done (its status and
    checkpointed generations of its length, then its directory and, while a process trains
    it, which: :mod:`physrover.experiment.claims`), and a last line counting
    done, partial and new runs, the share of their generations that is checkpointed, and
    the ``listed`` runs that ``--skip-listed`` left out."""
    counts = {"done": 0, "partial": 0, "new": 0}
    lines, reached, total = [], 0, 0
    for spec in specs:
        status, generation, length = run_progress(spec)
        counts[status] += 1
        reached, total = reached + min(generation, length), total + length
        if status != "done":
            who = holder(Path(spec.out)) if status == "partial" else None
            by = f"  (pid {who['pid']} on {who['host']})" if who else ""
            lines.append(f"{status:7s} {generation:>7d}/{length:<7d} {spec.out}{by}")
    share = 100.0 * reached / total if total else 100.0
    summary = ", ".join(f"{n} {s}" for s, n in counts.items())
    summary += f"; {share:.1f}% of their generations checkpointed"
    if listed:
        summary += f"; {listed} more listed as finished by --skip-listed"
    lines.append(f"sweep {name}: {summary}")
    return lines
