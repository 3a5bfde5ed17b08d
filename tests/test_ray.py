"""Sweeps on Ray: a Ray started here keeps to loopback; a real two-node cluster (each node
in a network namespace this test makes) gives the local pool's results, and a sweep loses
nothing when a node dies.

The cluster test needs root (``ip netns``), which CI has; elsewhere it skips, saying why.
Every address it uses is private and lives only inside the namespaces it makes, which it
removes however it ends.
"""

from __future__ import annotations

import contextlib
import ipaddress
import json
import os
import re
import secrets
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from conftest import comparable_rows

from physrover.experiment import on_ray
from physrover.experiment.claims import holder
from physrover.experiment.execute import run_sweep
from physrover.experiment.store import read_metrics
from physrover.experiment.sweep import Sweep

# Under pytest-xdist (the README's test command) every test that starts Ray runs on one
# worker (--dist loadgroup): two Ray instances at once would share this machine's ports.
pytestmark = pytest.mark.xdist_group("ray")

ray = pytest.importorskip("ray")


def _descendants(pid: int) -> set[int]:
    """``pid`` and every process below it, read from /proc."""
    children: dict[int, list[int]] = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        with contextlib.suppress(OSError, ValueError, IndexError):
            fields = stat.read_text().rsplit(")", 1)[1].split()
            children.setdefault(int(fields[1]), []).append(int(stat.parent.name))
    found, todo = set(), [pid]
    while todo:
        found.add(todo[-1])
        todo.extend(children.get(todo.pop(), []))
    return found


def _sockets(pids: set[int], netns: str | None = None) -> list[tuple[str, str]]:
    """(local address, owner) of every TCP and UDP socket of ``pids`` (``ss``)."""
    command = ["ss", "-tuanpH"]
    if netns:
        command = ["ip", "netns", "exec", netns, *command]
    out = subprocess.run(command, capture_output=True, text=True, check=True).stdout
    found = []
    for line in out.splitlines():
        owners = {int(p) for p in re.findall(r"pid=(\d+)", line)}
        if owners & pids:
            local = line.split()[4]
            found.append((local.rsplit(":", 1)[0].strip("[]"), line.split("users:")[-1]))
    return found


def _is_loopback(address: str) -> bool:
    address = address.removeprefix("::ffff:").split("%")[0]
    return address != "*" and ipaddress.ip_address(address).is_loopback


@pytest.mark.skipif(shutil.which("ss") is None, reason="needs ss (iproute2) to list sockets")
def test_ray_started_here_keeps_every_socket_on_loopback():
    if ray.is_initialized():
        ray.shutdown()
    handler = signal.getsignal(signal.SIGTERM)
    with on_ray._ray_on_loopback():
        on_ray._connect_ray(ray, "local", 1)
        try:
            # A task starts a worker process: its sockets count too.
            assert ray.get(ray.remote(lambda: os.getpid()).remote()) > 0
            sockets = _sockets(_descendants(os.getpid()))
        finally:
            ray.shutdown()
            signal.signal(signal.SIGTERM, handler)  # ray.init leaves a handler of its own
    owners = " ".join(owner for _, owner in sockets)
    assert "gcs_server" in owners and "raylet" in owners, sockets  # Ray's servers were seen
    assert [s for s in sockets if not _is_loopback(s[0])] == []
    assert "RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER" not in os.environ  # restored


# -- a real two-node cluster ---------------------------------------------------------------

PREFIX = "physrover-test-"
HEAD_IP, WORKER_IP = "10.231.0.1", "10.231.0.2"  # private, inside the test's namespaces only
PORT = 6379
BIN = Path(sys.executable).parent


def _ip(*args: str, check: bool = True) -> subprocess.CompletedProcess:
    return subprocess.run(["ip", *args], capture_output=True, text=True, check=check)


def _kill_namespace(name: str) -> None:
    """Kill every process inside network namespace ``name`` and remove it (its veth end
    goes with it)."""
    pids = _ip("netns", "pids", name, check=False).stdout.split()
    for pid in pids:
        with contextlib.suppress(ProcessLookupError, ValueError):
            os.kill(int(pid), signal.SIGKILL)
    _ip("netns", "del", name, check=False)


def _remove_stale_namespaces() -> None:
    """Namespaces an earlier run of this test left (killed before its own cleanup): those
    whose maker, the process whose pid ends their name, is gone. Another test session's
    live cluster on the same machine is left alone."""
    for line in _ip("netns", "list", check=False).stdout.splitlines():
        name = line.split()[0] if line.split() else ""
        maker = name.rsplit("-", 1)[-1]
        if name.startswith(PREFIX) and not (maker.isdigit() and Path(f"/proc/{maker}").exists()):
            _kill_namespace(name)


def _run_names(pids: set[int]) -> list[str]:
    names = []
    for pid in pids:
        with contextlib.suppress(OSError):
            names.append(Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode())
    return names


class Cluster:
    """A Ray head in one network namespace and a worker node in another, joined by a veth
    pair, with token authentication, both seeing the same filesystem (the shared run root
    a cluster needs)."""

    def __init__(self, root: Path):
        tag = str(os.getpid())
        self.head, self.worker = PREFIX + "head-" + tag, PREFIX + "worker-" + tag
        self.root = root
        token = root / "ray-token"
        token.write_text(secrets.token_hex(32))
        token.chmod(0o600)
        self.env = {k: v for k, v in os.environ.items()
                    if not k.startswith("RAY_") and k not in ("PHYSROVER_IMPORT",)}  # fmt: skip
        self.env.update(RAY_AUTH_MODE="token", RAY_AUTH_TOKEN_PATH=str(token),
                        RAY_USAGE_STATS_ENABLED="0")  # fmt: skip
        self.temp = Path(os.path.realpath("/tmp")) / f"prt{tag}"  # Ray's sockets: short paths
        self.starts = 0

    def start(self) -> None:
        veth_head, veth_worker = f"prh{os.getpid()}", f"prw{os.getpid()}"
        for name in (self.head, self.worker):
            _ip("netns", "add", name)
        _ip("link", "add", veth_head, "type", "veth", "peer", "name", veth_worker)
        for name, veth, address in ((self.head, veth_head, HEAD_IP),
                                    (self.worker, veth_worker, WORKER_IP)):  # fmt: skip
            _ip("link", "set", veth, "netns", name)
            _ip("-n", name, "addr", "add", f"{address}/24", "dev", veth)
            _ip("-n", name, "link", "set", veth, "up")
            _ip("-n", name, "link", "set", "lo", "up")
        self.start_ray()

    def start_ray(self) -> None:
        """Ray's head node, then its worker node (again, after :meth:`kill_ray`)."""
        self.starts += 1
        common = ["--num-cpus=1", "--disable-usage-stats"]
        self.exec(self.head, str(BIN / "ray"), "start", "--head", f"--node-ip-address={HEAD_IP}",
                  f"--port={PORT}", "--include-dashboard=false",
                  f"--temp-dir={self.temp}h{self.starts}", *common)  # fmt: skip
        worker = [f"--address={HEAD_IP}:{PORT}", f"--node-ip-address={WORKER_IP}"]
        self.exec(self.worker, str(BIN / "ray"), "start", *worker,
                  f"--temp-dir={self.temp}w{self.starts}", *common)  # fmt: skip

    def kill_ray(self, namespace: str, spare: set[int] = frozenset()) -> None:
        """SIGKILL every process in ``namespace`` but ``spare``: the node is lost."""
        for pid in {int(p) for p in _ip("netns", "pids", namespace, check=False).stdout.split()}:
            if pid not in spare:
                with contextlib.suppress(ProcessLookupError):
                    os.kill(pid, signal.SIGKILL)

    def exec(self, namespace: str, *command: str, timeout: float = 120) -> str:
        done = subprocess.run(["ip", "netns", "exec", namespace, *command], env=self.env,
                              capture_output=True, text=True, timeout=timeout)  # fmt: skip
        assert done.returncode == 0, f"{command}: {done.stdout[-2000:]}{done.stderr[-2000:]}"
        return done.stdout

    def sweep(self, sweep_file: Path, root: Path) -> subprocess.Popen:
        """``physrover sweep`` with ``--ray HEAD:PORT``, its driver on the head's node."""
        command = [str(BIN / "physrover"), "sweep", str(sweep_file), "--root", str(root),
                   "--ray", f"{HEAD_IP}:{PORT}"]  # fmt: skip
        output = dict(stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        return subprocess.Popen(["ip", "netns", "exec", self.head, *command], env=self.env,
                                **output)  # fmt: skip

    def worker_pids(self) -> set[int]:
        return {int(p) for p in _ip("netns", "pids", self.worker, check=False).stdout.split()}

    def stop(self) -> None:
        for name in (self.head, self.worker):
            _kill_namespace(name)
        for start in range(1, self.starts + 1):
            for node in "hw":
                shutil.rmtree(f"{self.temp}{node}{start}", ignore_errors=True)


def _netns_reason() -> str | None:
    """Why this machine cannot make the test's namespaces, or None."""
    if sys.platform != "linux" or shutil.which("ip") is None:
        return "needs Linux with iproute2's ip"
    if os.geteuid() != 0:
        return "needs root to make network namespaces (ip netns add); CI runs as root"
    probe = f"{PREFIX}probe-{os.getpid()}"
    made = _ip("netns", "add", probe, check=False)
    _ip("netns", "del", probe, check=False)
    if made.returncode != 0:
        return f"cannot make a network namespace here: {made.stderr.strip()}"
    return None


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    reason = _netns_reason()
    if reason:
        pytest.skip(reason)
    _remove_stale_namespaces()
    made = Cluster(tmp_path_factory.mktemp("cluster"))
    try:
        made.start()
        yield made
    finally:
        made.stop()


TINY = """
[sweep]
name = "NAME"
seeds = 2

[base.domain]
n_rovers = 3
n_req = 1
steps = 20

[base.learn]
generations = GENERATIONS
population = 6
eval_episodes = 2
checkpoint_every = 20

[grid]
method = ["D", "max-critic"]
"""


def _sweep_file(root: Path, name: str, generations: int) -> Path:
    path = root / f"{name}.toml"
    path.write_text(TINY.replace("NAME", name).replace("GENERATIONS", str(generations)))
    return path


def _metrics(root: Path) -> dict[str, list]:
    return {p.name: comparable_rows(read_metrics(p / "metrics.csv"))
            for p in sorted(root.iterdir()) if p.is_dir()}  # fmt: skip


def _pool_reference(path: Path, root: Path) -> dict[str, list]:
    report = run_sweep(Sweep.load(path).runs(root), workers=2, progress=False)
    assert not report.failed, report.failed
    return _metrics(root / Sweep.load(path).name)


def _finish(process: subprocess.Popen, timeout: float = 300) -> str:
    out, _ = process.communicate(timeout=timeout)
    assert process.returncode == 0, out[-3000:]
    return out


def test_a_two_node_cluster_gives_the_pools_results_and_survives_a_node_dying(cluster, tmp_path):
    start = time.monotonic()
    # 1. A small sweep across both nodes: the same metrics as on the local pool.
    small = _sweep_file(tmp_path, "small", 40)
    process = cluster.sweep(small, tmp_path / "cluster")
    ran_on_worker = False
    while process.poll() is None:
        ran_on_worker |= any("run_one" in c for c in _run_names(cluster.worker_pids()))
        time.sleep(0.1)
    _finish(process)
    assert ran_on_worker, "no run went to the worker node"
    expected = _pool_reference(small, tmp_path / "pool")
    assert _metrics(tmp_path / "cluster" / "small") == expected and len(expected) == 4

    # 2. A longer sweep; the worker node dies (all its processes killed) while it trains a
    # run that has checkpointed. Ray runs that run again on the head, which resumes it.
    long = _sweep_file(tmp_path, "long", 600)
    runs = tmp_path / "cluster" / "long"
    process = cluster.sweep(long, tmp_path / "cluster")
    deadline = time.monotonic() + 120
    while True:
        assert process.poll() is None and time.monotonic() < deadline, "no run to interrupt"
        # The run the worker node trains now (its claim's holder is one of the worker's
        # processes) has a checkpoint. Counting two checkpoints let a run the head had
        # finished stand in for it; the worker's run then started again from 0 (a CI flake).
        on_worker = {str(pid) for pid in cluster.worker_pids()}
        held = [path for path in runs.glob("*/state.json")
                if str((holder(path.parent) or {}).get("pid")) in on_worker]  # fmt: skip
        if held:
            break
        time.sleep(0.05)
    # What this test started outside its namespaces keeps to loopback meanwhile.
    outside = _sockets(_descendants(os.getpid()))
    assert [s for s in outside if not _is_loopback(s[0])] == []
    for pid in cluster.worker_pids():
        with contextlib.suppress(ProcessLookupError):
            os.kill(pid, signal.SIGKILL)
    out = _finish(process)
    assert "0 failed" in out, out[-2000:]
    resumed = [p.name for p in runs.iterdir() if p.is_dir()
               and any(s["from_generation"] > 0 for s in
                      json.loads((p / "provenance.json").read_text())["segments"])]  # fmt: skip
    assert resumed, "no run was resumed from a checkpoint after the node died"
    assert _metrics(runs) == _pool_reference(long, tmp_path / "pool")
    print(f"two-node cluster test: {time.monotonic() - start:.0f} s, resumed {resumed}")


def _segments(runs: Path) -> dict[str, list[int]]:
    """Each run's training segments: the generation each process started it from."""
    return {p.name: [s["from_generation"] for s in
                     json.loads((p / "provenance.json").read_text())["segments"]]
            for p in sorted(runs.iterdir()) if p.is_dir()}  # fmt: skip


def test_the_head_node_lost_mid_sweep_ends_in_one_line_and_a_new_head_resumes(cluster, tmp_path):
    start = time.monotonic()
    for node in (cluster.worker, cluster.head):  # both nodes up (a test before may kill one)
        cluster.kill_ray(node)
    cluster.start_ray()
    sweep = _sweep_file(tmp_path, "headless", 1000)
    runs = tmp_path / "cluster" / "headless"
    process = cluster.sweep(sweep, tmp_path / "cluster")
    deadline = time.monotonic() + 120
    while True:  # both nodes train a run that has checkpointed
        if process.poll() is not None or time.monotonic() > deadline:
            pytest.fail(f"no run to interrupt: {process.communicate()[0][-3000:]}")
        training = any("run_one" in c for c in _run_names(cluster.worker_pids()))
        checkpointed = len(list(runs.glob("*/state.json"))) if runs.exists() else 0
        if training and checkpointed >= 2:
            break
        time.sleep(0.05)
    # The head node's Ray is lost (GCS, raylet and the run it trains); the driver lives on.
    cluster.kill_ray(cluster.head, spare=_descendants(process.pid))
    out, _ = process.communicate(timeout=60)
    errors = [line for line in out.splitlines() if line.startswith("physrover: error:")]
    assert process.returncode == 1 and len(errors) == 1, out[-3000:]
    assert "lost the Ray cluster at" in errors[0] and "run the same command" in errors[0]
    assert "Traceback" not in out, out[-3000:]
    # A new head (the worker node's Ray restarts with it; alone it would give up on the old
    # head after a minute, its run with it) and the same command: the sweep completes.
    cluster.kill_ray(cluster.worker)
    cluster.start_ray()
    out = _finish(cluster.sweep(sweep, tmp_path / "cluster"))
    assert "0 failed" in out, out[-2000:]
    # Nothing lost or run twice: every run ends bit-identical to the pool's, each started
    # from generation 0 once, every later segment resuming a checkpoint ahead of the last.
    assert _metrics(runs) == _pool_reference(sweep, tmp_path / "pool")
    segments = _segments(runs)
    for name, starts in segments.items():
        assert starts[0] == 0 and starts == sorted(set(starts)), (name, starts)
    assert any(len(starts) > 1 for starts in segments.values()), segments
    print(f"head-loss test: {time.monotonic() - start:.0f} s, segments {segments}")
