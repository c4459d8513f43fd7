"""Collection: seeds in order, failures dropped unless kept, workers give the same file, and
bad input fails before anything is written."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import menagerie
from test_demos_hdf5 import PICK, REACH, cli

from mjkdl.demos import DemoFile, collect


@pytest.fixture(autouse=True)
def _panda() -> None:
    menagerie("franka_emika_panda")


def test_two_workers_write_the_file_one_writes(tmp_path: Path) -> None:
    kwargs = {"max_episode_steps": 15}
    one = collect(PICK, "demo_envs:approach", tmp_path / "one.hdf5", episodes=5, seed=7,
                  env_kwargs=kwargs, keep_failures=True, progress=False)  # fmt: skip
    r = cli("collect", PICK, "--policy", "demo_envs:approach", "--episodes", "5", "--seed", "7",
            "--env-kwargs", '{"max_episode_steps": 15}', "--keep-failures", "--workers", "2",
            "--out", str(tmp_path / "two.hdf5"))  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert one.kept == 5 and one.episodes == 5
    with DemoFile(one.path) as a, DemoFile(tmp_path / "two.hdf5") as b:
        assert a.env_kwargs == b.env_kwargs == kwargs
        assert [d.seed for d in b] == [7, 8, 9, 10, 11]
        for da, db in zip(a, b, strict=True):
            assert np.array_equal(da.states, db.states) and np.array_equal(da.actions, db.actions)
            assert da.obs.keys() == db.obs.keys()


def test_only_successes_are_kept_unless_asked(tmp_path: Path) -> None:
    out = tmp_path / "random.hdf5"
    r = collect(REACH, "random", out, episodes=3, env_kwargs={"max_episode_steps": 3},
                progress=False)  # fmt: skip
    assert (r.episodes, r.kept, r.successes) == (3, 0, 0)
    with DemoFile(out) as f:
        assert len(f) == 0
    r = cli("collect", REACH, "--random", "--episodes", "3", "--env-kwargs",
            '{"max_episode_steps": 3}', "--keep-failures", "--out", str(out))  # fmt: skip
    assert r.returncode == 2
    assert f"error: {out} exists: pass --append to add demos to it or --overwrite" in r.stderr
    with DemoFile(out) as f:
        assert len(f) == 0  # untouched
    r = cli("collect", REACH, "--random", "--episodes", "3", "--env-kwargs",
            '{"max_episode_steps": 3}', "--keep-failures", "--overwrite",
            "--out", str(out))  # fmt: skip
    assert r.returncode == 0 and "kept 3 of 3 episodes (0 successful)" in r.stdout
    assert "collect mjkdl/PandaReach-v0: 100%" in r.stderr  # the progress bar


def test_random_actions_depend_on_the_seed_alone(tmp_path: Path) -> None:
    kw = {"max_episode_steps": 4}
    a = collect(REACH, "random", tmp_path / "a.hdf5", episodes=2, seed=3, env_kwargs=kw,
                keep_failures=True, progress=False)  # fmt: skip
    b = collect(REACH, "random", tmp_path / "b.hdf5", episodes=1, seed=4, env_kwargs=kw,
                keep_failures=True, progress=False)  # fmt: skip
    with DemoFile(a.path) as fa, DemoFile(b.path) as fb:
        assert np.array_equal(fa.demo(1).actions, fb.demo(0).actions)
        assert not np.array_equal(fa.demo(0).actions, fb.demo(0).actions)


def test_the_policys_reset_runs_at_every_episode() -> None:
    from demo_envs import Approach

    from mjkdl.demos import make_env, make_policy, run_episode

    env = make_env(PICK, {"max_episode_steps": 2})
    policy = make_policy("demo_envs:approach", env)
    assert isinstance(policy, Approach)
    for s in range(3):
        run_episode(env, policy, s)
    env.close()
    assert policy.resets == 3


BAD = [
    (["mjkdl/PandaPik-v0", "--random"], "no env id named 'mjkdl/PandaPik-v0' in Gymnasium's "
     "registry; close matches: mjkdl/PandaPickCube-v0"),
    ([PICK, "--random", "--workers", "0"], "--workers must be from 1 to 256, got 0"),
    ([PICK, "--policy", "demo_envs:wrong_shape"], "policy demo_envs:wrong_shape (seed 0, step 0) "
     "returned an action of shape (3,); the env takes (7,)"),
    ([PICK, "--policy", "demo_envs:nan_after_two_steps"], "policy "
     "demo_envs:nan_after_two_steps (seed 0, step 2) returned non-finite entries at [1]"),
    ([PICK, "--policy", "no_such_module:fn"], "--policy no_such_module:fn: cannot import "
     "module 'no_such_module'"),
    ([PICK, "--policy", "demo_envs:nope"], "--policy demo_envs:nope: module 'demo_envs' has no "
     "callable 'nope'; it has: "),
    ([PICK, "--policy", "demo_envs"], "--policy must look like module:fn"),
    ([PICK, "--policy", "demo_envs:not_callable"], "demo_envs:not_callable(env) must return a "
     "callable policy(obs) -> action, got int"),
    ([PICK, "--random", "--env-kwargs", "{oops"], "--env-kwargs is not valid JSON"),
    ([PICK, "--random", "--env-kwargs", "[1]"], "--env-kwargs must be a JSON object, got [1]"),
    ([PICK, "--random", "--episodes", "0"], "--episodes must be a positive integer, got 0"),
    (["CartPole-v1", "--random"], "CartPoleEnv is not an mjkdl task env (it has no .scene"),
]  # fmt: skip


@pytest.mark.parametrize(("args", "message"), BAD)
def test_bad_input_names_itself_and_writes_nothing(
    tmp_path: Path, args: list[str], message: str
) -> None:
    out = tmp_path / "never.hdf5"
    argv = ["collect", *args, "--out", str(out)]
    if "--episodes" not in args:
        argv += ["--episodes", "3"]
    r = cli(*argv)
    assert r.returncode == 2, r.stderr
    assert f"error: {message}" in r.stderr, r.stderr
    if "(seed 0, step" in message:  # that episode is lost; the file stays, readable and empty
        with DemoFile(out) as f:
            assert len(f) == 0
    else:
        assert not out.exists()


def test_expert_demos_are_successes_and_other_envs_have_none(tmp_path: Path) -> None:
    r = collect(PICK, "expert", tmp_path / "e.hdf5", episodes=3, seed=0, progress=False)
    assert (r.successes, r.kept) == (3, 3)
    with DemoFile(r.path) as f:
        assert all(d.success and d.dones[-1] == 1 and d.num_samples < 100 for d in f)
        grip = f.demo(0).actions[:, 6]
        assert grip[0] == -1.0 and grip[-1] == 1.0  # opens, then closes on the cube
    r2 = cli("evaluate", "CartPole-v1", "--expert", "--episodes", "1")
    assert r2.returncode == 2
    assert "error: no expert for CartPoleEnv; experts exist for mjkdl/PandaReach-v0" in r2.stderr


def test_append_continues_after_the_last_seed_and_refuses_held_ones(tmp_path: Path) -> None:
    out = tmp_path / "more.hdf5"
    kw = ["--env-kwargs", '{"max_episode_steps": 2}', "--keep-failures", "--out", str(out)]
    collect(REACH, "random", out, episodes=2, seed=5, env_kwargs={"max_episode_steps": 2},
            keep_failures=True, progress=False)  # fmt: skip
    r = cli("collect", REACH, "--random", "--episodes", "2", "--append", *kw)
    assert r.returncode == 0, r.stderr
    with DemoFile(out) as f:
        assert f.seeds == [5, 6, 7, 8] and f.names == [f"demo_{i}" for i in range(4)]
    r = cli("collect", REACH, "--random", "--episodes", "3", "--seed", "4", "--append", *kw)
    assert r.returncode == 2
    assert f"error: {out} already holds seeds [5, 6]: the same seed twice" in r.stderr
    assert "leave out --seed to continue at 9" in r.stderr
    with DemoFile(out) as f:
        assert f.seeds == [5, 6, 7, 8]  # untouched
