"""The HDF5 file: robomimic's layout, states before each action, nothing lost on a crash,
a full disk or a foreign file."""

from __future__ import annotations

import dataclasses
import json
import re
import resource
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import h5py
import mujoco
import numpy as np
import pytest
from conftest import ROOT, menagerie
from demo_envs import CAMERA, approach

import mjkdl as mjk
from mjkdl.demos import (
    DemoFile,
    DemoFileError,
    EpisodeData,
    EpisodeWriter,
    collect,
    make_env,
    run_episode,
)
from mjkdl.demos.hdf5 import scene_model

REACH = "mjkdl/PandaReach-v0"
PICK = "mjkdl/PandaPickCube-v0"


@pytest.fixture(autouse=True)
def _panda() -> None:
    menagerie("franka_emika_panda")


def cli(*args: str, **kw) -> subprocess.CompletedProcess:
    """`python -m mjkdl.demos ...` in a fresh process (tests/ importable for `demo_envs`)."""
    env = {**__import__("os").environ, "PYTHONPATH": f"{ROOT}:{ROOT / 'tests'}"}
    return subprocess.run(
        [sys.executable, "-m", "mjkdl.demos", *args],
        capture_output=True, text=True, env=env, timeout=600, **kw,
    )  # fmt: skip


def test_layout_is_robomimics(tmp_path: Path) -> None:
    env = make_env(PICK, {"max_episode_steps": 6})
    policy = approach(env)
    out = tmp_path / "demos.hdf5"
    with EpisodeWriter(out, PICK, {"max_episode_steps": 6}) as writer:
        for seed in range(11):
            ep = run_episode(env, policy, seed, record=True)
            assert ep.data is not None
            assert writer.write(ep.data) == f"demo_{seed}"
        assert writer.num_demos == 11
    nstate = mujoco.mj_stateSize(env.unwrapped.scene.model, mujoco.mjtState.mjSTATE_INTEGRATION)
    env.close()
    with h5py.File(out, "r") as f:
        args = json.loads(f["data"].attrs["env_args"])
        assert args["env_name"] == PICK and args["env_kwargs"] == {"max_episode_steps": 6}
        assert args["mjkdl_version"] == mjk.__version__
        assert args["mujoco_version"] == mujoco.__version__
        assert f["data"].attrs["total"] == 66
        d = f["data/demo_3"]
        assert d["actions"].shape == (6, 7) and d["actions"].dtype == np.float32
        assert d["rewards"].shape == (6,) and d["dones"][()].tolist() == [0] * 5 + [1]
        assert d["states"].shape == (6, nstate)
        assert set(d["obs"]) >= {"panda_tcp_pos", "cube_pose", "panda_joint_pos", "cube_rel"}
        assert d["obs/panda_tcp_pos"].shape == (6, 3)
        assert d.attrs["num_samples"] == 6 and d.attrs["seed"] == 3
        assert d.attrs["model_file"].startswith("<mujoco") and len(d.attrs["model_hash"]) == 64
        assert d.attrs["success"] in (True, False)
        assert [n.decode() for n in f["mask/valid"][()]] == ["demo_9"]
        assert len(f["mask/train"]) == 10
        assert args["type"] == 100 and args["env_version"] == mjk.__version__
        for key, rows in d["obs"].items():  # robomimic's next_obs: obs one step on
            nxt = d["next_obs"][key]
            assert nxt.shape == rows.shape and not nxt.is_virtual  # a camera's is (below)
            assert np.array_equal(nxt[:-1], rows[1:])
        assert list(f["models"]) == [d.attrs["model_hash"]]  # one model, stored once


def test_the_file_is_self_contained(tmp_path: Path) -> None:
    """The stored MJB loads with no asset files, in a process that cannot see them, and is
    the model the demos were recorded with; next_obs survives a move of the file."""
    out = tmp_path / "demos.hdf5"
    collect(PICK, "demo_envs:approach", out, episodes=2, keep_failures=True,
            env_kwargs={"max_episode_steps": 3}, progress=False)  # fmt: skip
    moved = tmp_path / "elsewhere" / "moved.hdf5"
    moved.parent.mkdir()
    out.rename(moved)
    code = f"""
import mujoco, numpy as np
from mjkdl.demos import DemoFile
from mjkdl.demos.hdf5 import model_hash
f = DemoFile({str(moved)!r})
m, d = f.model(1), f.demo(1)
data = mujoco.MjData(m)
mujoco.mj_setState(m, data, d.states[2], mujoco.mjtState.mjSTATE_INTEGRATION)
mujoco.mj_forward(m, data)
print(model_hash(m) == d.model_hash, m.nmesh, np.array_equal(data.body("cube").xpos,
      d.obs["cube_pose"][2][:3]))
"""
    env = {**__import__("os").environ, "PYTHONPATH": str(ROOT), "MENAGERIE_ROOT": "/nonexistent"}
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                       cwd=tmp_path, timeout=120)  # fmt: skip
    assert r.returncode == 0, r.stderr
    nmesh = r.stdout.split()[1]
    assert r.stdout.split() == ["True", nmesh, "True"] and int(nmesh) > 0
    with h5py.File(moved, "r") as f:
        g = f["data/demo_0"]
        assert np.array_equal(g["next_obs/cube_pose"][0], g["obs/cube_pose"][1])
    with h5py.File(moved, "a") as f:
        del f["models"]
    with DemoFile(moved) as f, pytest.raises(DemoFileError, match="demo_0 has no stored model"):
        f.model(0)


def test_states_are_taken_before_each_action(tmp_path: Path) -> None:
    env = make_env(REACH, {"max_episode_steps": 4})
    ep = run_episode(env, approach_reach(env), 5, record=True)
    data = ep.data
    assert data is not None
    scene = env.unwrapped.scene
    env.reset(seed=5)
    state = np.empty(data.states.shape[1])
    for t, action in enumerate(data.actions):
        mujoco.mj_getState(scene.model, scene.data, state, mujoco.mjtState.mjSTATE_INTEGRATION)
        assert np.array_equal(state, data.states[t]), t
        obs, *_ = env.step(action)
        if t + 1 < len(data.actions):
            assert np.array_equal(obs["panda_tcp_pos"], data.obs["panda_tcp_pos"][t + 1])
    env.close()


def approach_reach(env):
    return lambda obs: np.clip(
        np.r_[2 * (obs["goal_pose"][:3] - obs["panda_tcp_pos"]), 0, 0, 0, 0],
        env.action_space.low,
        env.action_space.high,
    ).astype(np.float32)


def test_camera_frames_are_chunked_and_compressed(tmp_path: Path) -> None:
    env = make_env(PICK, {**CAMERA, "max_episode_steps": 3})
    ep = run_episode(env, lambda obs: np.zeros(7, np.float32), 0, record=True)
    env.close()
    assert ep.data is not None
    with EpisodeWriter(tmp_path / "cam.hdf5", PICK, CAMERA) as writer:
        writer.write(ep.data)
    with h5py.File(tmp_path / "cam.hdf5", "r") as f:
        rgb = f["data/demo_0/obs/front_rgb"]
        assert rgb.shape == (3, 48, 64, 3) and rgb.dtype == np.uint8
        assert rgb.chunks == (1, 48, 64, 3) and rgb.compression == "gzip"
        assert f["data/demo_0/obs/panda_tcp_pos"].compression is None


def test_foreign_truncated_and_missing_files_are_refused(tmp_path: Path) -> None:
    with pytest.raises(DemoFileError, match="no such demonstration file"):
        DemoFile(tmp_path / "nope.hdf5")
    text = tmp_path / "text.hdf5"
    text.write_text("not hdf5")
    with pytest.raises(DemoFileError, match=r"text\.hdf5 is not a readable HDF5 file"):
        DemoFile(text)
    foreign = tmp_path / "foreign.hdf5"
    with h5py.File(foreign, "w") as f:
        f.create_dataset("x", data=[1, 2])
    with pytest.raises(
        DemoFileError,
        match=r"foreign.hdf5 is not a demonstration file: it has no data.attrs\['env_args'\]",
    ):
        DemoFile(foreign)
    good = tmp_path / "good.hdf5"
    env = make_env(REACH, {"max_episode_steps": 2})
    ep = run_episode(env, lambda obs: np.zeros(7, np.float32), 0, record=True)
    env.close()
    with EpisodeWriter(good, REACH) as writer:
        writer.write(ep.data)
    with DemoFile(good) as f:
        with pytest.raises(
            KeyError, match=r"no demo named 'demo_7' in .*good\.hdf5; close matches: demo_0"
        ):
            f.demo(7)
        assert f.demo(0).num_samples == 2
    cut = tmp_path / "cut.hdf5"
    cut.write_bytes(good.read_bytes()[: good.stat().st_size // 2])
    with pytest.raises(DemoFileError, match=r"cut\.hdf5 is not a readable HDF5 file"):
        DemoFile(cut)
    with pytest.raises(DemoFileError, match=rf"holds demos of {REACH}.*cannot append {PICK}"):
        EpisodeWriter(good, PICK, append=True)
    with pytest.raises(DemoFileError, match=r"foreign\.hdf5 is not a demonstration file"):
        EpisodeWriter(foreign, REACH, append=True)
    with pytest.raises(DemoFileError, match="JSON-serialisable"):
        EpisodeWriter(tmp_path / "x.hdf5", REACH, {"bad": object()})
    assert not (tmp_path / "x.hdf5").exists()


def test_append_continues_the_numbering(tmp_path: Path) -> None:
    env = make_env(REACH, {"max_episode_steps": 2})
    eps = [run_episode(env, lambda o: np.zeros(7, np.float32), s, record=True) for s in (0, 1)]
    env.close()
    path = tmp_path / "a.hdf5"
    with EpisodeWriter(path, REACH) as w:
        w.write(eps[0].data)
    with EpisodeWriter(path, REACH, append=True) as w:
        assert (w.seeds, w.next_seed) == ([0], 1)
        assert w.write(eps[1].data) == "demo_1"
        with pytest.raises(DemoFileError, match=r"a\.hdf5 already holds seed 0 \(demo_0\)"):
            w.write(eps[0].data)
    with DemoFile(path) as f:
        assert f.names == ["demo_0", "demo_1"] and f.seeds == [0, 1]
    w.close()  # idempotent
    with pytest.raises(RuntimeError, match="EpisodeWriter is closed"):
        w.write(eps[0].data)
    with pytest.raises(DemoFileError, match=r"a\.hdf5 exists: pass --append .* or --overwrite"):
        EpisodeWriter(path, REACH)
    with EpisodeWriter(path, REACH, overwrite=True) as w:
        assert w.num_demos == 0
    with DemoFile(path) as f:
        assert f.names == []


def test_masks_grow_in_place_and_take_over_fixed_size_ones(tmp_path: Path) -> None:
    env = make_env(REACH, {"max_episode_steps": 2})
    ep = run_episode(env, lambda o: np.zeros(7, np.float32), 0, record=True).data
    env.close()
    path = tmp_path / "m.hdf5"
    with EpisodeWriter(path, REACH) as w:
        for seed in range(3):
            w.write(dataclasses.replace(ep, seed=seed))
    with h5py.File(path, "a") as f:  # as robomimic's own scripts leave them: fixed-size "S"
        train = f["mask/train"][()]
        del f["mask/train"]
        f["mask"].create_dataset("train", data=np.array(train, dtype="S"))
    with EpisodeWriter(path, REACH, append=True) as w:
        for seed in range(3, 22):
            w.write(dataclasses.replace(ep, seed=seed))
    with h5py.File(path, "r") as f:
        train = [n.decode() for n in f["mask/train"][()]]
        valid = [n.decode() for n in f["mask/valid"][()]]
        assert f["mask/train"].maxshape == (None,)
    assert valid == ["demo_9", "demo_19"]
    assert train == [f"demo_{i}" for i in range(22) if i % 10 != 9]


def test_sigkill_loses_at_most_the_episode_in_progress(tmp_path: Path) -> None:
    out = tmp_path / "killed.hdf5"
    env = {**__import__("os").environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.Popen(
        [sys.executable, "-m", "mjkdl.demos", "collect", PICK, "--random", "--episodes", "500",
         "--keep-failures", "--out", str(out)],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env,
    )  # fmt: skip
    seen = bytearray()

    def read() -> None:
        while chunk := proc.stderr.read1(4096):  # type: ignore[union-attr]
            seen.extend(chunk)

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    deadline = time.monotonic() + 120
    while b"kept=4" not in seen and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.05)
    proc.send_signal(signal.SIGKILL)
    proc.wait(10)
    reader.join(5)
    assert b"kept=4" in seen, seen.decode(errors="replace")[-500:]
    with DemoFile(out) as f:
        assert len(f) >= 4
        for demo in f:
            assert demo.num_samples == 100 and demo.states.shape[0] == 100


def test_a_full_disk_keeps_the_finished_demos(tmp_path: Path) -> None:
    out = tmp_path / "full.hdf5"
    env = make_env(PICK)
    xml, fingerprint, mjb = scene_model(env.unwrapped.scene)
    env.close()
    with EpisodeWriter(tmp_path / "model.hdf5", PICK) as w:  # what the model takes alone
        w.add_model(EpisodeData(0, *[np.zeros(1)] * 4, {}, False, xml, fingerprint, {}, mjb))
    limit = (tmp_path / "model.hdf5").stat().st_size + 900_000  # and 3-4 demos of 100 steps

    def small_files() -> None:
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write past the limit fails (EFBIG)
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    r = cli("collect", PICK, "--random", "--episodes", "10", "--keep-failures", "--out",
            str(out), preexec_fn=small_files)  # fmt: skip
    assert r.returncode == 2
    kept = re.search(r"could not write demo_(\d+) to .*full\.hdf5 \(File too large: it needs "
                     r"about \d+ bytes, \d+ are left\); the file keeps its (\d+) finished demos",
                     r.stderr)  # fmt: skip
    assert kept is not None and kept[1] == kept[2], r.stderr
    n = int(kept[2])
    assert n >= 3  # refused before HDF5 wrote any of it: nothing lost, nothing broken
    with DemoFile(out) as f:
        assert f.names == [f"demo_{i}" for i in range(n)]
        assert all(d.num_samples == 100 for d in f)


def test_a_file_being_written_elsewhere_says_so(tmp_path: Path) -> None:
    path = tmp_path / "busy.hdf5"
    code = (
        "import sys, time\nfrom mjkdl.demos import EpisodeWriter\n"
        f"w = EpisodeWriter({str(path)!r}, {REACH!r})\nprint('open', flush=True)\ntime.sleep(60)"
    )
    env = {**__import__("os").environ, "PYTHONPATH": str(ROOT)}
    writer = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, env=env)
    try:
        assert writer.stdout is not None and writer.stdout.readline() == b"open\n"
        with pytest.raises(
            DemoFileError, match=r"busy\.hdf5 is open for writing in another process"
        ):
            DemoFile(path)
    finally:
        writer.kill()
        writer.wait(10)
    with DemoFile(path) as f:  # a writer killed before any demo leaves an empty, readable file
        assert len(f) == 0
