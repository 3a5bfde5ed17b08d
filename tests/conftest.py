"""Shared test helpers."""

import importlib.util
import json
import os
import sys

import numpy as np
import pytest

from physrover.experiment.store import read_metrics


@pytest.hookimpl(optionalhook=True)  # pytest without xdist (the BenchMARL venv) skips it
def pytest_xdist_auto_num_workers(config):
    """``-n auto`` (the README's test command): a worker per core, at most 4 (each imports
    torch and compiles or loads the kernels; more contend for the kernel cache and memory)."""
    return min(4, os.cpu_count() or 1)


# Test modules whose tests are long and share few kernel versions: spread test by test over
# the workers.
SPREAD = ("test_properties", "test_durability", "test_docs")


@pytest.hookimpl(tryfirst=True)  # before xdist reads the groups (its hook is not trylast)
def pytest_collection_modifyitems(config, items):
    """Under ``--dist loadgroup`` (the README's command) a module's tests run on one worker:
    they compile the same versions of the kernels (a world's step for one config is a
    version, ~10 s to compile cold), and two workers that need a version at once both
    compile it (numba writes its cache when a compile ends). Measured on a cold cache
    (2026-12-07, 2 workers): 87 s of the suite's 700 s of compiles were such doubles, all
    within one module. The tests of ``SPREAD`` go one by one, after the modules (xdist
    sends the largest groups first), those marked ``long`` first, so that no long test is
    left running alone at the end."""
    items.sort(key=lambda item: item.get_closest_marker("long") is None)
    for item in items:
        name = item.module.__name__.rsplit(".", 1)[-1]
        if name not in SPREAD and item.get_closest_marker("xdist_group") is None:
            item.add_marker(pytest.mark.xdist_group(name))


def load_file(path, name, monkeypatch=None):
    """The file at ``path`` (a script of ``experiments/`` or ``docs/``, not in a package)
    imported as module ``name``. With ``monkeypatch`` it is in ``sys.modules`` for the test
    only (dataclasses look their module up there by name)."""
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    if monkeypatch is not None:
        monkeypatch.setitem(sys.modules, name, module)
    spec.loader.exec_module(module)
    return module


def comparable_rows(rows):
    """metrics.csv rows without the wall time, NaN made comparable (NaN != NaN)."""
    return [
        {k: ("nan" if v != v else v) for k, v in row.items() if k != "wall_seconds"} for row in rows
    ]


def checkpoint_meta(run_dir):
    """The metadata a run's state.npz holds, without its wall time."""
    with np.load(run_dir / "state.npz") as data:
        meta = json.loads(data["__meta__"].tobytes())
    meta.pop("wall_seconds")
    return meta


def assert_same_run(a, b, exact_snapshots=False):
    """Run directories ``a`` and ``b`` hold the same metrics (wall time aside), bit for bit
    the same state.npz arrays, the same checkpoint metadata (wall time aside) and the same
    champion snapshots: what an interrupted and resumed run ``b`` must share with an
    uninterrupted ``a``. A run stopped by a signal, or trained in parts, also checkpointed
    (and snapshot) the generations it stopped at, so ``a``'s snapshots are among ``b``'s;
    after kills they are the same (``exact_snapshots``)."""
    assert comparable_rows(read_metrics(a / "metrics.csv")) == comparable_rows(
        read_metrics(b / "metrics.csv")
    )
    with np.load(a / "state.npz") as sa, np.load(b / "state.npz") as sb:
        assert set(sa.files) == set(sb.files)
        for key in sa.files:
            if key != "__meta__":
                np.testing.assert_array_equal(sa[key], sb[key], err_msg=key)
    assert checkpoint_meta(a) == checkpoint_meta(b)
    champions = sorted(p.name for p in (a / "champions").iterdir())
    found = sorted(p.name for p in (b / "champions").iterdir())
    assert champions == found if exact_snapshots else set(champions) <= set(found)
    for name in champions:
        assert (a / "champions" / name).read_bytes() == (b / "champions" / name).read_bytes()


def play_alike(worlds, actions) -> None:
    """Reset each RoverWorld of ``worlds`` with team e's generator seeded e, then step it
    through the same (T, E, R, 2) ``actions``: episodes two configs should agree on."""
    for world in worlds:
        world.reset([np.random.default_rng(e) for e in range(world.n_teams)])
        for a in actions:
            world.step(a)


def score_paths(world, paths, record=False) -> None:
    """Score hand-made positions of team 0 of a just reset ``world``: ``paths[t]`` the (R,
    2) positions at step t, for t = 1 .. (``paths[0]`` is the reset's), with the world's
    own scoring plan (its POI rules, or the mask of the agents that capture); ``record``
    also writes them into ``position_history`` (what influence credit reads)."""
    from physrover.domain.scoring.captures import score

    step = world.plan.step
    for t, positions in enumerate(paths[1:], start=1):
        world.state.rover_positions[0] = positions
        if record:
            world.position_history[t, 0] = positions
        score(world.state, world.config.d_cap, step.n_req, t, step.rules, step.counted)


def random_episode(rng, seed, teams, half_size, **domain):
    """A world of ``teams`` teams of ``domain`` on a uniform layout of ``half_size``, each
    team reset from its own generator ``[seed, e]``, played to its last step under random
    commands drawn from ``rng``."""
    from physrover.config import DomainConfig
    from physrover.domain.world import RoverWorld

    config = DomainConfig(scenario={"kind": "uniform", "half_size": half_size,
                                    "min_separation": 1.0}, **domain)  # fmt: skip
    world = RoverWorld(config, teams)
    world.reset([np.random.default_rng([seed, e]) for e in range(teams)])
    for _ in range(config.steps):
        world.step(rng.uniform(-1, 1, (teams, config.n_rovers, 2)))
    return world
