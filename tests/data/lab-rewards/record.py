"""Record every reward assertion of the AADILab/influence-shaping unit tests into cases.json.

The lab's reward tests (``test/env/rewards/test_*.py``) are executed with the lab's C++ core
(cppyy / librovers) and ``createEnv`` replaced by stubs, and with the ``TestEnv`` /
``InfluenceTestCase`` assertion helpers replaced by recorders: instead of checking anything, each
reward assertion stores the env config it used, the agent paths and the expected rewards. Tests
that check something other than rewards (or cannot be replayed without the C++ core) are listed
under ``not_recorded`` with the reason. The output also carries descriptions of the lab helpers
and notes on the lab's semantics; ``tests/test_lab_rewards.py`` replays the cases.

Regenerate (from the repo root)::

    python tests/data/lab-rewards/record.py /work/.mirror/AADILab+influence-shaping/repo

LAB is any git repository of the lab (a checkout or a bare mirror); its HEAD is used and
recorded as ``lab_commit``. The script extracts the lab itself into a temporary directory with
the equivalent of ``git -C LAB archive HEAD src test | tar -x -C TMPDIR``. Only ``src`` and
``test`` are archived: ``git archive HEAD`` of the whole repo fails on blobs missing from the
mirror. Uncommitted changes of a checkout are ignored.

Needs only numpy and PyYAML (the lab's ``load_config``): the lab's C++ core is stubbed, and
pandas (used by ``test_results.py``) is always replaced by a csv-module stand-in, so the output
does not depend on whether pandas is installed. The file name does not start with ``test_``, so
pytest does not collect it.
"""

import argparse
import ast
import copy
import csv
import importlib.util
import inspect
import json
import os
import subprocess
import sys
import tempfile
import types
import unittest
from pathlib import Path

import numpy as np

SOURCE = "test/env/rewards"
FILES = [
    "test_difference.py",
    "test_final_state.py",
    "test_global.py",
    "test_indirect_difference.py",
    "test_results.py",
    "test_sequence.py",
]


HELPERS = {
    "assert_correct_rewards": (
        "TestEnv.assert_correct_rewards(config, expected_rewards): env=createEnv(config); "
        "_,r=env.reset() (agents placed at their fixed spawn, every path = [spawn], t=0); checks r "
        "(one reward per agent, rovers then uavs, each agent's own reward_type via the "
        "RewardComputer) elementwise with np.isclose (rtol 1e-5, atol 1e-8) against expected; "
        "zip-truncated, lengths not checked. 'paths' is always [] here."
    ),
    "assert_path_rewards": (
        "TestEnv.assert_path_rewards(env, agent_paths, expected_rewards_at_each_step, "
        "start_msg=''): env.reset() then expected[0] vs reset rewards (t=0, spawn positions); then "
        "for t=1..len(paths): env.rovers()[i].set_position(*paths[t-1][i]) for every agent "
        "(appends to the agent's path; no dynamics, no bounds clamp) and env.status()[1] (rewards "
        "over the whole path so far) vs expected[t]. Per-step per-agent vectors, np.isclose, "
        "zip-truncated over steps and agents. No separate G check."
    ),
    "assert_final_rewards": (
        "TestEnv.assert_final_rewards(env, agent_paths, expected_final_rewards, msg=None): "
        "env.reset(); set_position every agent for every step of agent_paths without computing "
        "rewards; then env.rewards() once vs expected (one value per agent, np.isclose, "
        "zip-truncated). Only the final step (whole path incl. spawn) is checked."
    ),
    "assert_np_close:G": (
        "Plain test code in test_global: env=createEnv(config); env.reset(); set_position for the "
        "given 'paths' steps (spawn is path[0]); then compute_G(env) = "
        "env.rovers()[0].reward(AgentPack(0, all agents, all pois)) i.e. G = sum over POIs of "
        "value*constraint value, independent of reward_type; assert np.isclose(G, expected) "
        "(scalar)."
    ),
    "assert_np_close:reset_rewards": (
        "Plain test code: _, rewards = env.reset(); assert np.isclose(rewards, expected) where "
        "rewards is the whole reset reward vector (1 agent here) and expected a scalar."
    ),
    "assert_np_close:reset_rewards[i]": (
        "Plain test code: _, rewards = env.reset(); assert np.isclose(rewards[agent_index], "
        "expected) (scalar, t=0)."
    ),
}

NOTES = [
    (
        "ids are 'file.py::Class::method#n', n = 1-based order of the recorded assertion inside "
        "that test method."
    ),
    (
        "config is a deep copy of the dict exactly as passed to createEnv (before createEnv's "
        "in-place defaulting). createEnv fills, when absent: POI constraint='final', "
        "capture_radius=-1.0 (disabled), disappear_bool=False, subtype=''; agent sensor type "
        "'SmartLidar', accum_type 'average', measurement_type 'inverse_distance_squared', "
        "default_value -1.0; bounds = [0,map_size]; IndirectDifference = {type:'removal', "
        "assignment:'automatic', automatic:{timescale:'trajectory', credit:'AllOrNothing'}, "
        "add_G:False}; 'manual' defaults to [] and add_G to False when an IndirectDifference dict "
        "omits them; debug.reward_equals_G False."
    ),
    (
        "Lab reward semantics (custom_env.py): only agents of type 'rover' can capture POIs. A POI "
        "is captured by a rover at distance d if (capture_radius != -1 and d <= capture_radius) or "
        "(d <= rover observation_radius and d <= POI observation_radius). Constraint value = "
        "coupling * prod over the `coupling` closest rovers of 1/max(1,d). 'final' uses the last "
        "path point; 'sequential' uses the max over all path points (incl. spawn). G = sum "
        "value*constraint."
    ),
    (
        "env_serial identifies the env object the assertion used; cases sharing env_serial reused "
        "one env (e.g. "
        "test_indirect_difference.py::TestOneRoverOneUavOnePoiPath::"
        "test_one_rover_one_uav_one_poi_path_b#3 and #4: #4's comment says the rover was switched "
        "to Difference, but the env was not rebuilt, so the recorded config is the "
        "IndirectDifference one the env really had)."
    ),
    "lab_line is the line of the assertion call in the lab test file.",
    (
        "test_sequence.py::TestTwoRoversTwoUavsSixPois defines "
        "test_config_a_path_a1_IndirectDifferenceAutomaticTimestep twice; the first def (line 689, "
        "an assert_path_rewards) is shadowed and never run by the lab. It was executed separately "
        "and is recorded with shadowed_in_lab=true; the live def (assert_final_rewards) is "
        "recorded normally."
    ),
    (
        "test_indirect_difference.py::TestTwoRoversTwoUavsTwoPoisPath::test_a builds a third "
        "expectation (IndirectDifference, [[0,0,0,0],[0,0,0,0],[1,1,1,1]]) but never asserts it; "
        "nothing recorded for it."
    ),
    (
        "test_global.py config builders reuse one dict object when appending "
        "(get_one_rover_three_pois_config etc.), so both extra POIs sit at [35,35], "
        "test_one_rover_two_uavs_three_pois has 3 uavs (all at [35,35]) and "
        "test_three_rovers_three_uavs_three_pois has 4 rovers and 0 uavs; the recorded configs "
        "show what was really passed."
    ),
    (
        "test_final_state.py's test classes are verbatim copies of the static (no-path) classes in "
        "test_indirect_difference.py, so those cases appear twice under different ids."
    ),
    (
        "test_results.py::TestResults::test_quartz: config is test/resources/quartz/config.yaml "
        "(full file incl. ccea/data/... sections) with hidden POIs fixed at their positions from "
        "eval_team_6_joint_traj.csv row 0; paths are rows 1..150 (rover_0, uav_0); expected = "
        "fitness.csv generation-0 team_6_rover_0 / team_6_uav_0. pandas was not installed: the "
        "CSVs were read with a csv-module stand-in (python float parsing)."
    ),
]


class NotRecordable(Exception):
    pass


class _Recording:
    """What has been recorded so far, and which lab test is running."""

    def __init__(self):
        self.test_dir = ""
        self.cases = []
        self.not_recorded = []
        self.test_id = None
        self.n = 0
        self.extra = {}
        self.env_serial = 0


REC = _Recording()


# ---------------------------------------------------------------- stubs
class _Anything:
    """Swallows any attribute access / call (only used for cppyy namespace objects)."""

    def __getattr__(self, name):
        return _Anything()

    def __call__(self, *a, **k):
        return _Anything()

    def __getitem__(self, k):
        return _Anything()


def _conv(v):
    try:
        return float(v)
    except ValueError:
        return v


def _read_csv(path, index_col=None, **kwargs):
    """pandas.read_csv stand-in: {column name: list of values}, numbers parsed with float()."""
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    header = rows[0]
    cols = {}
    for j, name in enumerate(header):
        if name == "":
            continue
        cols[name] = [_conv(r[j]) for r in rows[1:] if j < len(r)]
    return cols


class _P:
    def __init__(self, x, y):
        self.x, self.y = x, y


def _resolve(pos):
    if pos["spawn_rule"] != "fixed":
        raise NotRecordable(f"non-fixed spawn rule {pos['spawn_rule']!r}")
    return [pos["fixed"][0], pos["fixed"][1]]


class FakeEntity:
    def __init__(self, env, idx, kind):
        self.env, self.idx, self.kind = env, idx, kind

    def position(self):
        if self.env.positions is None:
            raise NotRecordable("position read before reset")
        p = (self.env.positions if self.kind == "agent" else self.env.poi_positions)[self.idx]
        return _P(p[0], p[1])

    def set_position(self, x, y):
        if self.kind != "agent":
            raise NotRecordable("poi set_position")
        self.env.positions[self.idx] = [x, y]
        self.env.trace.append((self.idx, x, y))


class ObsToken:
    def __init__(self, env, i):
        self.env, self.i = env, i


class RewardVecToken:
    def __init__(self, env, trace):
        self.env, self.trace = env, list(trace)
        self.index = None

    def __getitem__(self, i):
        t = RewardVecToken(self.env, self.trace)
        t.index = i
        return t

    def __iter__(self):
        raise NotRecordable("iterating over a reward vector outside a helper")


class GToken:
    def __init__(self, env, trace):
        self.env, self.trace = env, list(trace)


class FakeEnv:
    """Holds a deep copy of the config; tracks positions for the plain assert_np_close checks
    in test_global (it never computes a reward)."""

    def __init__(self, config):
        REC.env_serial += 1
        self.serial = REC.env_serial
        self.config = copy.deepcopy(config)
        self.positions = None
        self.positions_at_reset = None
        self.poi_positions = None
        self.trace = []

    def _n_agents(self):
        a = self.config["env"]["agents"]
        return len(a["rovers"]) + len(a["uavs"])

    def reset(self):
        a = self.config["env"]["agents"]
        p = self.config["env"]["pois"]
        self.positions = [_resolve(c["position"]) for c in a["rovers"] + a["uavs"]]
        self.poi_positions = [_resolve(c["position"]) for c in p["rover_pois"] + p["hidden_pois"]]
        self.positions_at_reset = [list(q) for q in self.positions]
        self.trace = []
        obs = [ObsToken(self, i) for i in range(self._n_agents())]
        return obs, RewardVecToken(self, self.trace)

    def rovers(self):
        return [FakeEntity(self, i, "agent") for i in range(self._n_agents())]

    def pois(self):
        p = self.config["env"]["pois"]
        return [
            FakeEntity(self, i, "poi") for i in range(len(p["rover_pois"]) + len(p["hidden_pois"]))
        ]

    def status(self):
        raise NotRecordable("env.status() outside a helper")

    def rewards(self):
        raise NotRecordable("env.rewards() outside a helper")


# ---------------------------------------------------------------- recorders
def _call_line():
    for fr in inspect.stack(0)[2:]:
        if os.path.abspath(fr.filename).startswith(REC.test_dir):
            return os.path.basename(fr.filename), fr.lineno
    return None, None


def _plain(x):
    if isinstance(x, dict):
        return {k: _plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_plain(v) for v in x]
    if isinstance(x, np.ndarray):
        return _plain(x.tolist())
    if isinstance(x, (bool, np.bool_)):
        return bool(x)
    if isinstance(x, (int, np.integer)):
        return int(x)
    if isinstance(x, (float, np.floating)):
        return float(x)
    return x


def _record(helper, env, **fields):
    REC.n += 1
    _, line = _call_line()
    case = {
        "id": f"{REC.test_id}#{REC.n}",
        "helper": helper,
        "lab_line": line,
        "env_serial": env.serial,
        "n_agents": env._n_agents(),
        "config": _plain(env.config),
    }
    case.update(REC.extra)
    case.update({k: _plain(v) for k, v in fields.items()})
    REC.cases.append(case)


def rec_assert_correct_rewards(self, config, expected_rewards):
    env = FakeEnv(config)  # what the stubbed createEnv returns
    _record("assert_correct_rewards", env, paths=[], expected=expected_rewards)


def rec_assert_path_rewards(self, env, agent_paths, expected_rewards_at_each_step, start_msg=""):
    kw = {}
    if start_msg != "":
        kw["start_msg"] = start_msg
    _record(
        "assert_path_rewards", env, paths=agent_paths, expected=expected_rewards_at_each_step, **kw
    )


def rec_assert_final_rewards(self, env, agent_paths, expected_final_rewards, msg=None):
    kw = {}
    if msg is not None:
        kw["msg"] = msg
    _record("assert_final_rewards", env, paths=agent_paths, expected=expected_final_rewards, **kw)


def _trace_to_steps(env, trace):
    """Group set_position calls made after reset into steps (a new step starts when an
    agent id repeats). Each step lists every agent's position after that step."""
    pos = [list(p) for p in env.positions_at_reset]
    steps, seen = [], set()
    for i, x, y in trace:
        if i in seen:
            steps.append([list(p) for p in pos])
            seen = set()
        pos[i] = [x, y]
        seen.add(i)
    if seen:
        steps.append([list(p) for p in pos])
    return steps


def rec_compute_G(env):
    if not isinstance(env, FakeEnv):
        raise NotRecordable("compute_G on a non-fake env")
    return GToken(env, env.trace)


def rec_assert_np_close(self, arg0, arg1):
    tok, exp = (arg0, arg1) if isinstance(arg0, (GToken, RewardVecToken)) else (arg1, arg0)
    if not isinstance(tok, (GToken, RewardVecToken)):
        raise NotRecordable("assert_np_close on values not produced by the env")
    env = tok.env
    steps = _trace_to_steps(env, tok.trace)
    if isinstance(tok, GToken):
        _record("assert_np_close:G", env, paths=steps, expected=exp)
    elif tok.index is None:
        if tok.trace:
            raise NotRecordable("reward vector after moves")
        _record("assert_np_close:reset_rewards", env, paths=steps, expected=exp)
    else:
        _record(
            "assert_np_close:reset_rewards[i]",
            env,
            paths=steps,
            expected=exp,
            agent_index=tok.index,
        )


def rec_extract_observation(obs):
    raise NotRecordable("checks sensor observations (extract_observation), not rewards")


def rec_assert_close_lists(self, list0, list1, msg=None):
    raise NotRecordable("assert_close_lists called directly on non-reward values")


def rec_compute_agent_reward(env, agent_id):
    raise NotRecordable("compute_agent_reward")


def install_stubs(lab_src):
    """Stub the lab's C++ core, createEnv and pandas, then patch the lab's test helpers."""
    cppyy = types.ModuleType("cppyy")
    cppyy.gbl = _Anything()
    cppyy.add_include_path = cppyy.include = cppyy.cppdef = lambda *a, **k: None
    librovers = types.ModuleType("influence.librovers")
    librovers.rovers = librovers.eigen = librovers.thyme = librovers.std = _Anything()
    custom_env = types.ModuleType("influence.custom_env")
    custom_env.createEnv = FakeEnv
    pandas = types.ModuleType("pandas")
    pandas.read_csv = _read_csv
    sys.modules.update(
        {
            "cppyy": cppyy,
            "influence.librovers": librovers,
            "influence.custom_env": custom_env,
            "pandas": pandas,
        }
    )
    sys.path.insert(0, lab_src)
    from influence.testing import InfluenceTestCase, TestEnv  # the lab's real module

    TestEnv.assert_correct_rewards = rec_assert_correct_rewards
    TestEnv.assert_path_rewards = rec_assert_path_rewards
    TestEnv.assert_final_rewards = rec_assert_final_rewards
    TestEnv.assert_close_lists = rec_assert_close_lists
    InfluenceTestCase.assert_np_close = rec_assert_np_close
    InfluenceTestCase.compute_G = staticmethod(rec_compute_G)
    InfluenceTestCase.extract_observation = staticmethod(rec_extract_observation)
    InfluenceTestCase.compute_agent_reward = staticmethod(rec_compute_agent_reward)


# ---------------------------------------------------------------- runner
def load_module(fname):
    name = "labtest_" + fname[:-3]
    spec = importlib.util.spec_from_file_location(name, os.path.join(REC.test_dir, fname))
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod
    spec.loader.exec_module(mod)
    return mod


def shadowed_defs(fname):
    """[(class, method, lineno, FunctionDef)] for method defs overridden later in the same class."""
    tree = ast.parse(Path(REC.test_dir, fname).read_text())
    out = []
    for node in tree.body:
        if isinstance(node, ast.ClassDef):
            fdefs = [n for n in node.body if isinstance(n, ast.FunctionDef)]
            for k, fd in enumerate(fdefs):
                if any(g.name == fd.name for g in fdefs[k + 1 :]):
                    out.append((node.name, fd.name, fd.lineno, fd))
    return out


def run_one(test_id, fn, extra=None):
    REC.test_id, REC.n, REC.extra = test_id, 0, extra or {}
    status = "ok"
    try:
        fn()
    except NotRecordable as e:
        REC.not_recorded.append({"id": test_id, "reason": str(e), "recorded_before_stop": REC.n})
        status = "not_recorded"
    except Exception as e:
        REC.not_recorded.append(
            {
                "id": test_id,
                "reason": f"could not run: {type(e).__name__}: {e}",
                "recorded_before_stop": REC.n,
            }
        )
        status = "error"
    if status == "ok" and REC.n == 0:
        REC.not_recorded.append({"id": test_id, "reason": "ran but made no reward assertion"})
    return status, REC.n


def record_all():
    """Run every test of FILES (plus shadowed defs); return [(test id, status, n recorded)]."""
    loader = unittest.TestLoader()
    log = []
    for fname in FILES:
        mod = load_module(fname)
        classes = [
            c
            for c in vars(mod).values()
            if inspect.isclass(c)
            and issubclass(c, unittest.TestCase)
            and c.__module__ == mod.__name__
        ]
        classes.sort(key=lambda c: inspect.getsourcelines(c)[1])
        for cls in classes:
            names = loader.getTestCaseNames(cls)
            names = sorted(names, key=lambda n, c=cls: inspect.getsourcelines(getattr(c, n))[1])
            for mname in names:
                inst = cls(mname)
                tid = f"{fname}::{cls.__name__}::{mname}"
                log.append((tid,) + run_one(tid, getattr(inst, mname)))
        # methods shadowed by a later def of the same name: never run by unittest.
        for cname, mname, lineno, fd in shadowed_defs(fname):
            cls = getattr(mod, cname)
            modast = ast.Module(body=[fd], type_ignores=[])
            ns = {}
            exec(compile(modast, os.path.join(REC.test_dir, fname), "exec"), mod.__dict__, ns)
            bound = types.MethodType(ns[mname], cls(mname))
            tid = f"{fname}::{cname}::{mname}[shadowed_def_line_{lineno}]"
            extra = {
                "shadowed_in_lab": True,
                "note": f"first definition (line {lineno}) is overridden by a later def with the "
                "same name in the same class, so the lab never runs it",
            }
            log.append((tid,) + run_one(tid, bound, extra=extra))
    return log


def extract_lab(lab, dest):
    """Extract src/ and test/ of the lab's HEAD into dest; return the HEAD commit."""
    git = ["git", "-C", lab]
    commit = subprocess.check_output([*git, "rev-parse", "HEAD"], text=True).strip()
    archive = subprocess.run(
        [*git, "archive", "--format=tar", commit, "src", "test"], check=True, capture_output=True
    ).stdout
    subprocess.run(["tar", "-x", "-C", dest], input=archive, check=True)
    return commit


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("lab", help="git repository of AADILab/influence-shaping (checkout/mirror)")
    parser.add_argument(
        "-o",
        "--output",
        default=str(Path(__file__).resolve().parent / "cases.json"),
        help="output path (default: cases.json next to this script)",
    )
    args = parser.parse_args()

    with tempfile.TemporaryDirectory(prefix="influence-shaping-") as tmp:
        tmp = os.path.realpath(tmp)
        commit = extract_lab(args.lab, tmp)
        REC.test_dir = os.path.join(tmp, *SOURCE.split("/"))
        install_stubs(os.path.join(tmp, "src"))
        log = record_all()
    for row in log:
        print(*row, sep="\t")

    out = {
        "lab_repo": "AADILab/influence-shaping",
        "lab_commit": commit,
        "source": SOURCE,
        "helpers": HELPERS,
        "notes": NOTES,
        "cases": REC.cases,
        "not_recorded": REC.not_recorded,
    }
    Path(args.output).write_text(json.dumps(out, indent=1) + "\n")
    print(f"{args.output}: {len(REC.cases)} cases, {len(REC.not_recorded)} not recorded")


if __name__ == "__main__":
    main()
