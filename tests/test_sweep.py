"""Sweeps: grid expansion, local pool vs Ray equality, skip and resume, crash reporting."""

import os
from pathlib import Path

import pytest
from conftest import comparable_rows

from physrover.config import ConfigError
from physrover.experiment.execute import run_sweep
from physrover.experiment.store import read_metrics
from physrover.experiment.sweep import Sweep, parse_seeds, run_status
from physrover.experiment.training import train

SWEEP = """
[sweep]
name = "tiny"
seeds = 2

[base.domain]
n_rovers = 3
n_req = 1
steps = 20

[base.learn]
generations = 3
population = 6
eval_episodes = 2
checkpoint_every = 2

[grid]
method = ["D", "max-critic"]
"""


def _sweep(tmp_path, text=SWEEP):
    path = tmp_path / "tiny.toml"
    path.write_text(text)
    return Sweep.load(path)


def _metrics(specs):
    out = {}
    for spec in specs:
        rows = read_metrics(os.path.join(spec.out, "metrics.csv"))
        out[os.path.basename(spec.out)] = comparable_rows(rows)
    return out


def test_grid_expands_to_cells_times_seeds(tmp_path):
    specs = _sweep(tmp_path).runs(tmp_path / "root")
    names = sorted(os.path.basename(s.out) for s in specs)
    assert names == [
        "method=D_seed=0", "method=D_seed=1", "method=max-critic_seed=0", "method=max-critic_seed=1"
    ]  # fmt: skip
    assert len(_sweep(tmp_path).runs(tmp_path, seeds=3)) == 6


def test_runs_are_seed_major(tmp_path):
    """Every cell's seed 0 runs before any cell's seed 1: a sweep stopped part-way has its
    finished runs spread over the cells, not all seeds of the first cells."""
    names = [os.path.basename(s.out) for s in _sweep(tmp_path).runs(tmp_path, seeds=3)]
    assert names == [f"method={m}_seed={seed}" for seed in range(3) for m in ("D", "max-critic")]


def test_chunks_of_seeds_are_the_whole_sweeps_runs(tmp_path):
    """--seeds 0:2 then 2:5 gives the runs of --seeds 5, names, configs and directories."""
    sweep = _sweep(tmp_path)
    whole = sweep.runs(tmp_path, seeds=5)
    chunks = sweep.runs(tmp_path, seeds=range(0, 2)) + sweep.runs(tmp_path, seeds=range(2, 5))
    assert chunks == whole  # seed-major: the chunks are the whole sweep's list, cut
    later = sweep.runs(tmp_path, seeds=parse_seeds("3:5"))
    assert sorted(s.name for s in later) == [
        "method=D_seed=3", "method=D_seed=4", "method=max-critic_seed=3", "method=max-critic_seed=4"
    ]  # fmt: skip
    assert parse_seeds("4") == 4 and parse_seeds("2:3") == range(2, 3)
    for bad in ("0", "-1", "3:3", "5:2", "-1:2", "a", "1:2:3", ""):
        with pytest.raises(ConfigError, match="seeds: must be"):
            parse_seeds(bad)


def test_bad_sweep_files(tmp_path):
    with pytest.raises(ConfigError, match="n_reqs: unknown config field"):
        _sweep(tmp_path, SWEEP.replace('method = ["D", "max-critic"]', "n_reqs = [1, 2]"))
    with pytest.raises(ConfigError, match="n_req: must be in"):
        _sweep(tmp_path, SWEEP.replace('method = ["D", "max-critic"]', "n_req = [1, 9]")).runs(
            tmp_path
        )
    with pytest.raises(ConfigError, match="grid values must be a non-empty list"):
        _sweep(tmp_path, SWEEP.replace('method = ["D", "max-critic"]', 'method = "D"'))


@pytest.mark.xdist_group("ray")  # one worker starts Ray at a time (test_ray.py)
def test_pool_and_ray_give_the_same_metrics(tmp_path):
    pytest.importorskip("ray")
    sweep = _sweep(tmp_path)
    pool_specs = sweep.runs(tmp_path / "pool")
    report = run_sweep(pool_specs, workers=2, progress=False)
    assert len(report.finished) == 4 and not report.failed
    ray_specs = sweep.runs(tmp_path / "ray")
    report = run_sweep(ray_specs, workers=2, ray_address="local", progress=False)
    assert len(report.finished) == 4 and not report.failed
    assert _metrics(pool_specs) == _metrics(ray_specs)
    assert all(len(rows) == 3 for rows in _metrics(pool_specs).values())


def test_interrupted_sweep_resumes_and_finished_runs_are_skipped(tmp_path):
    sweep = _sweep(tmp_path)
    reference = sweep.runs(tmp_path / "reference")
    run_sweep(reference, workers=2, progress=False)

    specs = sweep.runs(tmp_path / "interrupted")
    # Run 0 finished, run 1 stopped after its checkpoint at generation 2, the others untouched.
    from physrover.config import RunConfig

    train(RunConfig.from_toml(specs[0].config_toml), specs[0].out, progress=False)
    train(RunConfig.from_toml(specs[1].config_toml), specs[1].out, generations=2, progress=False)
    assert [run_status(s) for s in specs] == ["done", "partial", "new", "new"]
    finished_mtime = os.path.getmtime(os.path.join(specs[0].out, "metrics.csv"))
    report = run_sweep(specs, workers=2, progress=False)
    assert report.skipped == 1 and len(report.finished) == 3
    assert os.path.getmtime(os.path.join(specs[0].out, "metrics.csv")) == finished_mtime
    assert _metrics(specs) == _metrics(reference)


def test_a_crashed_run_is_reported_and_the_others_finish(tmp_path):
    specs = _sweep(tmp_path).runs(tmp_path / "crash")
    os.makedirs(specs[2].out)
    with open(os.path.join(specs[2].out, "config.toml"), "w") as f:
        f.write("[domain]\nn_req = 99\n")  # a corrupt run directory
    report = run_sweep(specs, workers=2, progress=False)
    assert list(report.failed) == [os.path.basename(specs[2].out)]
    assert "n_req" in report.failed[os.path.basename(specs[2].out)]
    assert len(report.finished) == 3


def test_variants_cross_the_grid(tmp_path):
    text = (
        SWEEP
        + """
[[variants]]
motion = "ideal"

[[variants]]
motion = "physics"
collisions = false
"""
    )
    specs = _sweep(tmp_path, text).runs(tmp_path, seeds=1)
    names = sorted(os.path.basename(s.out) for s in specs)
    assert names == [
        "method=D_motion=ideal_seed=0",
        "method=D_motion=physics_collisions=false_seed=0",
        "method=max-critic_motion=ideal_seed=0",
        "method=max-critic_motion=physics_collisions=false_seed=0",
    ]
    from physrover.config import RunConfig

    physics = RunConfig.from_toml(specs[1].config_toml).domain
    assert (physics.motion, physics.physics.collisions) == ("physics", False)
    with pytest.raises(ConfigError, match="motion: unknown motion model 'teleport'"):
        _sweep(tmp_path, SWEEP + '\n[[variants]]\nmotion = "teleport"\n')


def test_drop_state_keeps_what_plots_and_videos_need(tmp_path):
    from physrover.experiment.store import RunError, load_champions

    specs = _sweep(tmp_path).runs(tmp_path / "drop", drop_state=True)[:2]
    run_sweep(specs, workers=1, progress=False)
    for spec in specs:
        names = {p.name for p in os.scandir(spec.out)}
        assert "state.npz" not in names and "state.prev.npz" not in names
        assert {"config.toml", "metrics.csv", "state.json", "champions"} <= names
        assert run_status(spec) == "done"
        load_champions(Path(spec.out))
    again = run_sweep(specs, workers=1, progress=False)  # finished: skipped, not re-run
    assert again.skipped == 2 and not again.finished
    with pytest.raises(RunError, match="state.npz was dropped"):
        train(None, specs[0].out, resume=True, generations=99, progress=False)


def test_sweep_cost_estimate_arithmetic(tmp_path):
    from physrover.experiment.bench import estimate_sweep, sweep_wall_time

    specs = _sweep(tmp_path).runs(tmp_path / "est", seeds=3)
    # a timer that charges by method: cells must be timed once each, seeds multiply
    timed = []

    def timer(config):
        timed.append(config.learn.seed)
        return 0.5 if config.learn.method == "D" else 2.0

    estimates = estimate_sweep(specs, timer=timer)
    assert len(estimates) == len(specs) // 3 and set(timed) == {0}
    for e in estimates:
        assert e.runs == 3 and e.total_seconds == pytest.approx(e.run_seconds * 3)
    total = sum(e.total_seconds for e in estimates)
    assert sweep_wall_time(estimates, 2) == pytest.approx(
        max(total / 2, max(e.run_seconds for e in estimates))
    )
    assert sweep_wall_time(estimates, 1000) == pytest.approx(max(e.run_seconds for e in estimates))


def test_sweep_cost_estimate_counts_a_trainers_iterations(tmp_path):
    # A gradient-based trainer's cell costs its iterations (ceil(total_episodes / num_envs)),
    # not generations, and is timed per iteration.
    from physrover.experiment.bench import estimate_sweep

    text = """
[sweep]
name = "trainer"
seeds = 2

[base.domain]
n_rovers = 3

[base.learn]
method = "mappo"

[grid]
n_req = [1, 2]

[[variants]]
total_episodes = 100
num_envs = 8
"""
    specs = _sweep(tmp_path, text).runs(tmp_path / "est")
    estimates = estimate_sweep(specs, timer=lambda config: 0.5)
    assert len(estimates) == 2
    for e in estimates:
        assert (e.generations, e.unit, e.runs, e.total_seconds) == (13, "it", 2, 13.0)


def test_a_variant_is_checked_with_each_grid_value_it_runs_with(tmp_path):
    # curriculum_start 3 needs a coupling above 3: valid with n_req 5 and 6, not with 3
    grid = '[sweep]\nname = "cur"\n[grid]\nn_req = [5, 6]\n'
    variant = "\n[[variants]]\ncurriculum_start = 3\n"
    assert len(_sweep(tmp_path, grid + variant).runs(tmp_path, seeds=1)) == 2
    with pytest.raises(ConfigError, match=r"below the domain's coupling \(n_req 3\), got 3"):
        _sweep(tmp_path, grid.replace("[5, 6]", "[5, 3]") + variant)


def test_each_methods_table_in_the_base_is_the_settings_of_its_runs(tmp_path):
    text = SWEEP.replace('method = ["D", "max-critic"]', 'method = ["D", "average", "max-critic"]')
    text += "\n[base.critic]\ncritic_hidden = 8\n\n[base.sampled]\nn_samples = 3\n"
    from physrover.config import RunConfig
    from physrover.learn.configs import CriticConfig, SampledConfig

    sweep = _sweep(tmp_path, text)
    configs = [RunConfig.from_toml(s.config_toml) for s in sweep.runs(tmp_path, 1)]
    expected = {"D": None, "average": SampledConfig(n_samples=3),
                "max-critic": CriticConfig(critic_hidden=8)}  # fmt: skip
    assert {c.learn.method: c.settings for c in configs} == expected
    # --set of one method's setting reaches that method's runs only, and names the sweep
    bigger = sweep.with_overrides({"n_samples": 5, "critic.critic_lr": 1e-4})
    configs = [RunConfig.from_toml(s.config_toml) for s in bigger.runs(tmp_path, 1)]
    critic = CriticConfig(critic_hidden=8, critic_lr=1e-4)
    assert [c.settings for c in configs] == [None, SampledConfig(n_samples=5), critic]
    assert bigger.name == "tiny+critic.critic_lr=0.0001+n_samples=5"
    # the base's own method takes it too, and a method without a table in the file gets one
    plain = _sweep(tmp_path, SWEEP.replace('"max-critic"]', '"max-critic", "average"]'))
    set_both = plain.with_overrides({"critic_lr": 1e-4, "n_samples": 4})
    configs = [RunConfig.from_toml(s.config_toml) for s in set_both.runs(tmp_path, 1)]
    assert [c.settings for c in configs] == [None, CriticConfig(critic_lr=1e-4),
                                             SampledConfig(n_samples=4)]  # fmt: skip
    with pytest.raises(ConfigError, match="sampled.n_samples: must be >= 1"):
        plain.with_overrides({"n_samples": 0})
    with pytest.raises(ConfigError, match="base.sampled.n_samples: must be >= 1"):
        _sweep(tmp_path, text.replace("n_samples = 3", "n_samples = 0"))
    with pytest.raises(ConfigError, match="n_samples: is a setting of .*not of method 'D'"):
        _sweep(tmp_path, SWEEP + "\n[[variants]]\nn_samples = 3\n")


def test_the_head_watch_loses_the_head_only_after_it_stops_answering(monkeypatch):
    import socket

    from physrover.experiment import on_ray

    server = socket.create_server(("127.0.0.1", 0))
    clock = [100.0]
    monkeypatch.setattr(on_ray.time, "monotonic", lambda: clock[0])
    watch = on_ray.HeadWatch(f"127.0.0.1:{server.getsockname()[1]}")
    assert not watch.lost() and watch.silent_since is None  # it answers
    server.close()
    clock[0] += 0.5
    assert not watch.lost() and watch.silent_since is None  # not asked again within 1 s
    clock[0] += 1.0
    assert not watch.lost() and watch.silent_since == clock[0]  # silent from now
    clock[0] += on_ray.HEAD_LOST_AFTER
    assert watch.lost()
    assert not on_ray.HeadWatch(None).lost() and on_ray.HeadWatch("no-port").lost() is False
