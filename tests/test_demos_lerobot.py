"""LeRobot v3.0 export, by lerobot's own writer (where it imports) and by pyarrow, read back
with pyarrow and ffmpeg: one row and one video frame per recorded step, actions equal to the
HDF5's, images within codec tolerance."""

from __future__ import annotations

import importlib.util
import json
import os
import shlex
import subprocess
import sys
from pathlib import Path

import imageio_ffmpeg
import numpy as np
import pyarrow.parquet as pq
import pytest
from conftest import EXTRAS, ROOT, franka_sim, menagerie, needs_extra
from demo_envs import CAMERA
from test_demos_hdf5 import PICK, REACH, cli

from mjkdl.demos import DemoFile, EpisodeWriter, ExportError, collect, export_lerobot

# CI sets it in lerobot's own environment, where these tests must run, not skip.
REQUIRE_LEROBOT = os.environ.get("MJKDL_REQUIRE_LEROBOT") == "1"


def lerobot_imports() -> bool:
    try:
        import lerobot.datasets.lerobot_dataset  # noqa: F401
    except Exception:  # absent, or beside a torch it was not built for
        return False
    return True


NO_LEROBOT = pytest.mark.skipif(
    not REQUIRE_LEROBOT and not lerobot_imports(),
    reason=EXTRAS["lerobot"].reason,
)
WRITERS = ["pyarrow", pytest.param("lerobot", marks=NO_LEROBOT)]


@pytest.fixture(scope="module")
def demos(tmp_path_factory: pytest.TempPathFactory) -> Path:
    menagerie("franka_emika_panda")
    path = tmp_path_factory.mktemp("lerobot") / "cam.hdf5"
    collect(PICK, "demo_envs:approach", path, episodes=3, seed=1, keep_failures=True,
            env_kwargs={**CAMERA, "max_episode_steps": 7}, progress=False)  # fmt: skip
    return path


@pytest.fixture(scope="module", params=WRITERS)
def exported(request: pytest.FixtureRequest, demos: Path) -> tuple[Path, Path]:
    writer = request.param
    root = demos.parent / f"ds_{writer}"
    r = cli("export-lerobot", str(demos), "--root", str(root), "--repo-id", "me/pick",
            "--writer", writer)  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == f"{root}: 3 episodes, 21 frames (written by {writer})"
    return demos, root


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    mse = np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2)
    return float("inf") if mse == 0 else 10 * np.log10(255.0**2 / mse)


def test_info_tasks_and_stats(exported: tuple[Path, Path]) -> None:
    _, root = exported
    info = json.loads((root / "meta/info.json").read_text())
    assert info["codebase_version"] == "v3.0" and info["fps"] == 10
    assert (info["total_episodes"], info["total_frames"], info["total_tasks"]) == (3, 21, 1)
    assert info["splits"] == {"train": "0:3"}
    feats = info["features"]
    assert feats["observation.images.front"]["shape"] == [48, 64, 3]
    assert feats["observation.images.front"]["dtype"] == "video"
    assert feats["action"] == {"dtype": "float32", "shape": [7], "names": None}
    assert feats["observation.state"]["shape"][0] == len(feats["observation.state"]["names"])
    names = feats["observation.state"]["names"]
    assert "panda_tcp_pos.2" in names and "panda_joint_pos.6" in names
    assert not [n for n in names if n.startswith("cube")]  # privileged: only when asked
    # lerobot reads the task from the pandas index, wherever the writer put it
    tasks = pq.read_table(root / "meta/tasks.parquet")
    index = json.loads(tasks.schema.metadata[b"pandas"])["index_columns"]
    assert tasks.column(index[0]).to_pylist() == [PICK]
    assert tasks.column("task_index").to_pylist() == [0]
    stats = json.loads((root / "meta/stats.json").read_text())
    assert stats["action"]["count"] == [21]
    assert np.array(stats["observation.images.front"]["mean"]).shape == (3, 1, 1)


def test_rows_equal_the_hdf5(exported: tuple[Path, Path]) -> None:
    demos, root = exported
    table = pq.read_table(root / "data/chunk-000/file-000.parquet")
    assert table.num_rows == 21
    assert set(table.column_names) == {
        "observation.state", "action", "next.reward", "next.done", "timestamp",
        "frame_index", "episode_index", "index", "task_index",
    }  # fmt: skip
    rows = table.to_pydict()
    episodes = pq.read_table(root / "meta/episodes/chunk-000/file-000.parquet").to_pylist()
    with DemoFile(demos) as f:
        for ep, demo in enumerate(f):
            meta = episodes[ep]
            lo, hi = meta["dataset_from_index"], meta["dataset_to_index"]
            assert (meta["episode_index"], meta["length"], hi - lo) == (ep, 7, 7)
            assert np.array_equal(np.array(rows["action"][lo:hi], np.float32), demo.actions)
            assert rows["frame_index"][lo:hi] == list(range(7))
            assert rows["episode_index"][lo:hi] == [ep] * 7 and rows["index"][lo:hi] == list(
                range(lo, hi)
            )
            assert rows["timestamp"][lo:hi] == pytest.approx([t / 10 for t in range(7)])
            assert rows["next.done"][lo:hi] == [False] * 6 + [True]
            assert rows["next.reward"][lo:hi] == pytest.approx(demo.rewards.tolist(), rel=1e-6)
            tcp = np.array(rows["observation.state"][lo:hi])
            assert tcp.shape[0] == 7
            assert meta["videos/observation.images.front/from_timestamp"] == pytest.approx(lo / 10)
            assert meta["videos/observation.images.front/to_timestamp"] == pytest.approx(hi / 10)


def test_video_has_one_frame_per_row_within_codec_tolerance(exported: tuple[Path, Path]) -> None:
    demos, root = exported
    reader = imageio_ffmpeg.read_frames(
        str(root / "videos/observation.images.front/chunk-000/file-000.mp4")
    )
    meta = next(reader)
    assert meta["size"] == (64, 48) and meta["fps"] == 10
    decoded = [np.frombuffer(b, np.uint8).reshape(48, 64, 3) for b in reader]
    assert len(decoded) == 21
    with DemoFile(demos) as f:
        recorded = np.concatenate([d.obs["front_rgb"] for d in f])
    quality = [psnr(a, b) for a, b in zip(decoded, recorded, strict=True)]
    worst, median = BOUNDS[root.name.removeprefix("ds_")]
    assert min(quality) >= worst and np.median(quality) >= median, quality


# The fidelity docs/demos.md states per writer (PSNR against the recorded frames, dB): worst
# frame and median. pyarrow: H.264 at CRF 16, full-resolution colour (measured 38.8 / 41.6 on
# 84x84 wrist frames of 20 expert demos); lerobot: its fixed SVT-AV1 at CRF 30 (31.1 / 34.8).
BOUNDS = {"pyarrow": (38.5, 41.0), "lerobot": (31.0, 34.5)}


@pytest.mark.parametrize("writer", WRITERS)
def test_frame_fidelity_is_what_the_docs_state(writer: str, tmp_path: Path) -> None:
    menagerie("franka_emika_panda")
    path = tmp_path / "wrist.hdf5"
    collect(PICK, "expert", path, episodes=5, seed=0, progress=False,
            env_kwargs={"camera_names": ["wrist"], "camera_size": [84, 84]})  # fmt: skip
    root = export_lerobot(path, tmp_path / "ds", repo_id="me/pick", writer=writer).root
    reader = imageio_ffmpeg.read_frames(
        str(root / "videos/observation.images.wrist/chunk-000/file-000.mp4")
    )
    next(reader)
    decoded = [np.frombuffer(b, np.uint8).reshape(84, 84, 3) for b in reader]
    with DemoFile(path) as f:
        recorded = np.concatenate([d.obs["wrist_rgb"] for d in f])
    quality = [psnr(a, b) for a, b in zip(decoded, recorded, strict=True)]
    assert len(quality) == len(recorded) > 100
    worst, median = BOUNDS[writer]
    assert min(quality) >= worst and np.median(quality) >= median, (min(quality), quality)


def docs_train_line() -> list[str]:
    """The `lerobot-train` command of docs/demos.md, as arguments."""
    text = (ROOT / "docs" / "demos.md").read_text()
    start = text.index("lerobot-train --")
    return shlex.split(text[start : text.index("```", start)].replace("\\\n", " "))


def test_the_documented_training_line_runs_offline() -> None:
    """lerobot's default decoder (torchcodec) fails offline without the system's FFmpeg
    libraries; the documented line picks PyAV and downloads no weights."""
    line = docs_train_line()
    assert line[0] == "lerobot-train"
    for flag in ("--dataset.video_backend=pyav", "--policy.pretrained_backbone_weights=null",
                 "--policy.push_to_hub=false"):  # fmt: skip
        assert flag in line, line


def test_bad_exports(exported: tuple[Path, Path], tmp_path: Path) -> None:
    demos, root = exported
    with pytest.raises(ExportError, match="exists and is not empty; pick a new folder"):
        export_lerobot(demos, root)
    empty = tmp_path / "empty.hdf5"
    EpisodeWriter(empty, REACH).close()
    with pytest.raises(ExportError, match=r"empty\.hdf5 holds no finished demos to export"):
        export_lerobot(empty, tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_depth_is_refused_with_the_way_out(tmp_path: Path) -> None:
    demos = tmp_path / "depth.hdf5"
    collect(REACH, "random", demos, episodes=1, seed=0, keep_failures=True, progress=False,
            env_kwargs={**CAMERA, "camera_depth": True, "max_episode_steps": 2})  # fmt: skip
    with pytest.raises(
        ExportError,
        match=r"depth\.hdf5 holds depth images \['front_depth'\] \(float32 metres\): .*"
        r"convert IN OUT --env-kwargs '\{\"camera_depth\": false\}'",
    ):
        export_lerobot(demos, tmp_path / "out", writer="pyarrow")
    assert not (tmp_path / "out").exists()


@NO_LEROBOT
def test_lerobots_own_loader_reads_the_export(exported: tuple[Path, Path]) -> None:
    """Where lerobot imports (0.4 pins torch < 2.11; CI has a newer torch, so this skips
    there): its `LeRobotDataset` reads either writer's metadata, tasks and rows."""
    from lerobot.datasets import lerobot_dataset

    demos, root = exported
    # pyav decodes here; lerobot's default torchcodec needs the system's FFmpeg libraries
    ds = lerobot_dataset.LeRobotDataset("me/pick", root=root, video_backend="pyav")
    assert (ds.num_episodes, ds.num_frames, ds.fps) == (3, 21, 10)
    assert ds.meta.video_keys == ["observation.images.front"]
    assert ds.meta.get_task_index(PICK) == 0
    with DemoFile(demos) as f:
        actions = np.concatenate([d.actions for d in f])
        frames = np.concatenate([d.obs["front_rgb"] for d in f])
    assert np.array_equal(np.stack([np.asarray(a) for a in ds.hf_dataset["action"]]), actions)
    for i in (0, 9, 20):  # the first frame, one inside the second episode, the last
        item = ds[i]
        assert np.array_equal(item["action"].numpy(), actions[i])
        image = item["observation.images.front"].numpy()  # C x H x W in [0, 1]
        assert image.shape == (3, 48, 64)
        decoded = np.round(image.transpose(1, 2, 0) * 255).astype(np.uint8)
        assert psnr(decoded, frames[i]) >= 30.0, (i, psnr(decoded, frames[i]))


def test_writer_choice(demos: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    with pytest.raises(ExportError, match="writer must be one of auto, lerobot, pyarrow; got 'x'"):
        export_lerobot(demos, tmp_path / "x", writer="x")
    # A lerobot that is installed but does not import (the wrong torch): "lerobot" says why,
    # "auto" warns and writes with pyarrow.
    monkeypatch.setitem(sys.modules, "lerobot.datasets.lerobot_dataset", None)
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: object())
    with pytest.raises(ImportError, match=r"writer='lerobot' needs lerobot 0\.4 .* does not"):
        export_lerobot(demos, tmp_path / "y", writer="lerobot")
    assert not (tmp_path / "y").exists()
    with pytest.warns(UserWarning, match="lerobot does not import .*; exporting with pyarrow"):
        out = export_lerobot(demos, tmp_path / "z", writer="auto")
    assert (out.writer, out.frames) == ("pyarrow", 21)


def test_every_camera_keeps_35_db_on_84x84_frames(tmp_path: Path) -> None:
    """The pyarrow writer's worst frame, each camera, on an expert demo seen by the front and
    the wrist camera at 84×84."""
    path = tmp_path / "two.hdf5"
    collect(PICK, "expert", path, episodes=1, seed=5, progress=False,
            env_kwargs={"camera_names": ["front", "wrist"], "camera_size": [84, 84]})  # fmt: skip
    root = export_lerobot(path, tmp_path / "ds", writer="pyarrow").root
    with DemoFile(path) as f:
        for cam in ("front", "wrist"):
            recorded = np.concatenate([d.obs[f"{cam}_rgb"] for d in f])
            video = root / f"videos/observation.images.{cam}/chunk-000/file-000.mp4"
            reader = imageio_ffmpeg.read_frames(str(video))
            next(reader)
            decoded = [np.frombuffer(b, np.uint8).reshape(84, 84, 3) for b in reader]
            assert len(decoded) == len(recorded)
            worst = min(psnr(a, b) for a, b in zip(decoded, recorded, strict=True))
            assert worst >= 35.0, (cam, worst)


def test_state_keys_choose_what_observation_state_holds(demos: Path, tmp_path: Path) -> None:
    root = tmp_path / "privileged"
    r = cli("export-lerobot", str(demos), "--root", str(root), "--writer", "pyarrow",
            "--state-keys", "cube_pose,panda_tcp_pos")  # fmt: skip
    assert r.returncode == 0, r.stderr
    info = json.loads((root / "meta/info.json").read_text())
    names = info["features"]["observation.state"]["names"]
    assert names == [f"cube_pose.{i}" for i in range(7)] + [f"panda_tcp_pos.{i}" for i in range(3)]
    rows = pq.read_table(root / "data/chunk-000/file-000.parquet").to_pydict()
    with DemoFile(demos) as f:
        d = f.demo(0)
        expected = np.hstack([d.obs["cube_pose"], d.obs["panda_tcp_pos"]]).astype(np.float32)
    assert np.array_equal(np.array(rows["observation.state"][:7], np.float32), expected)
    bad = r"--state-keys: .*cam\.hdf5 has no vector observation 'front_rgb'; it has cube_contacts, "
    with pytest.raises(ExportError, match=bad):
        export_lerobot(demos, tmp_path / "bad", writer="pyarrow", state_keys=["front_rgb"])
    assert not (tmp_path / "bad").exists()


# Sized for 7-step episodes of 48x64 frames; diffusion denoises in 2 steps to run quickly.
POLICIES = {
    "act": ["--policy.chunk_size=4", "--policy.n_action_steps=4"],
    "diffusion": ["--policy.horizon=8", "--policy.n_action_steps=4",
                  "--policy.drop_n_last_frames=0", "--policy.crop_shape=[40,56]",
                  "--policy.num_inference_steps=2"],
}  # fmt: skip


@pytest.fixture(scope="module", params=list(POLICIES))
def trained(request: pytest.FixtureRequest, demos: Path) -> tuple[Path, Path]:
    """A tiny ACT or diffusion policy trained offline for 2 steps by lerobot-train on the
    pyarrow export (no downloads: `--policy.pretrained_backbone_weights=null`)."""
    kind = request.param
    root = demos.parent / "ds_train"
    if not root.exists():
        export_lerobot(demos, root, repo_id="me/pick", writer="pyarrow")
    out = demos.parent / kind
    env = {**os.environ, "HF_HUB_OFFLINE": "1", "WANDB_MODE": "disabled"}
    given = {  # the documented line's flags, its folders and policy type replaced
        "--dataset.root": str(root), "--policy.type": kind, "--output_dir": str(out),
    }  # fmt: skip
    line = [a if a.split("=")[0] not in given else f"{a.split('=')[0]}={given[a.split('=')[0]]}"
            for a in docs_train_line()[1:]]  # fmt: skip
    r = subprocess.run(
        [sys.executable, "-m", "lerobot.scripts.lerobot_train", *line, "--policy.device=cpu",
         *POLICIES[kind], "--steps=2", "--batch_size=2", "--save_freq=2", "--num_workers=0",
         "--wandb.enable=false"],
        capture_output=True, text=True, env=env, timeout=900,
    )  # fmt: skip
    assert r.returncode == 0, (r.stdout + r.stderr)[-3000:]
    return root, out / "checkpoints" / "last" / "pretrained_model"


@NO_LEROBOT
def test_a_lerobot_policy_acts_with_the_exports_observations(
    demos: Path, trained: tuple[Path, Path]
) -> None:
    from lerobot.datasets import lerobot_dataset

    from mjkdl.demos import make_env
    from mjkdl.demos.lerobot_policy import LeRobotPolicy

    root, model = trained
    env = make_env(PICK, {**CAMERA, "max_episode_steps": 7})
    policy = LeRobotPolicy(model, env)
    ds = lerobot_dataset.LeRobotDataset("me/pick", root=root, video_backend="pyav")
    with DemoFile(demos) as f:
        demo = f.demo(0)
    for t in (0, 6):  # the batch from the env's observation is the dataset's item
        obs = {k: v[t] for k, v in demo.obs.items()}
        batch, item = policy.batch(obs), ds[t]
        assert np.array_equal(batch["observation.state"][0].numpy(), item["observation.state"])
        ours = batch["observation.images.front"][0].numpy().transpose(1, 2, 0)
        theirs = item["observation.images.front"].numpy().transpose(1, 2, 0)
        assert psnr(np.round(ours * 255), np.round(theirs * 255)) >= 35.0
    obs, _ = env.reset(seed=0)
    policy.reset()
    action = policy(obs)
    assert action.shape == (7,) and np.isfinite(action).all()
    env.close()


@NO_LEROBOT
def test_evaluate_runs_a_lerobot_policy(trained: tuple[Path, Path]) -> None:
    _, model = trained
    kwargs = json.dumps({**CAMERA, "max_episode_steps": 6})
    r = cli("evaluate", PICK, "--policy", f"lerobot:{model}", "--episodes", "2",
            "--env-kwargs", kwargs)  # fmt: skip
    assert r.returncode == 0, r.stderr
    lines = [ln for ln in r.stdout.splitlines() if ln.startswith(("seed ", "success: "))]
    assert lines[0].startswith("seed 0: success=") and lines[0].endswith("length=6")
    assert lines[1].startswith("seed 1: success=") and lines[1].endswith("length=6")
    assert lines[2].startswith("success: ") and "/2)" in lines[2]
    r = cli("evaluate", PICK, "--policy", f"lerobot:{model}", "--episodes", "1")  # no camera
    assert r.returncode == 2
    assert "looks at observation.images.front; this env has no front_rgb observation" in r.stderr
    r = cli("evaluate", PICK, "--policy", f"lerobot:{model}", "--episodes", "1", "--env-kwargs",
            kwargs, "--state-keys", "cube_pose")  # fmt: skip
    assert r.returncode == 2 and "takes an observation.state of 28 numbers; cube_pose give 7" in (
        r.stderr
    )


@NO_LEROBOT
def test_a_lerobot_checkpoint_drives_the_arm_in_the_loop(trained: tuple[Path, Path]) -> None:
    """`evaluate --policy lerobot:... --robot-ip` as a Franka user runs it, against the
    lockstep simulated arm: whole episodes at the policy's rate, the arm left at rest."""
    needs_extra("franka")
    from mjkdl.hw.connection import ArmConnection

    _, model = trained
    kwargs = json.dumps({**CAMERA, "max_episode_steps": 5, "lockstep": True})
    with franka_sim("--lockstep", "--scene", "empty", "--command-timeout", "10") as server:
        r = cli("evaluate", PICK, "--policy", f"lerobot:{model}", "--episodes", "2",
                "--env-kwargs", kwargs, "--robot-ip", server.host)  # fmt: skip
        assert r.returncode == 0, r.stderr[-3000:]
        lines = [ln for ln in r.stdout.splitlines() if ln.startswith(("seed ", "success: "))]
        assert [ln.split(": ")[0] for ln in lines] == ["seed 0", "seed 1", "success"]
        assert lines[0].endswith("length=5") and lines[1].endswith("length=5")
        conn = ArmConnection(server.host, "panda")
        try:
            state = conn.state()
        finally:
            conn.close()
        assert np.abs(state.dq).max() < 0.01


@NO_LEROBOT
def test_the_state_keys_come_from_the_policys_dataset(
    trained: tuple[Path, Path], tmp_path: Path
) -> None:
    """Its dataset's feature names choose the state (the loop's env has more proprioception);
    keys this env lacks are named."""
    import shutil

    from mjkdl.demos import make_env
    from mjkdl.demos.lerobot_policy import LeRobotPolicy, PolicyError

    root, model = trained
    env = make_env(PICK, {**CAMERA, "max_episode_steps": 7})
    try:
        assert LeRobotPolicy(model, env)._state[:2] == ["panda_gripper", "panda_joint_pos"]
        copy, meta = tmp_path / "model", tmp_path / "ds" / "meta"
        shutil.copytree(model, copy)
        meta.mkdir(parents=True)
        info = json.loads((root / "meta" / "info.json").read_text())
        info["features"]["observation.state"]["names"][0] = "panda_grip_force"
        (meta / "info.json").write_text(json.dumps(info))
        train = json.loads((copy / "train_config.json").read_text())
        train["dataset"]["root"] = str(meta.parent)
        (copy / "train_config.json").write_text(json.dumps(train))
        with pytest.raises(PolicyError, match=r"trained on observations \['panda_grip_force'\]"):
            LeRobotPolicy(copy, env)
    finally:
        env.close()


@NO_LEROBOT
def test_action_chunks_run_as_the_policys_config_says(
    trained: tuple[Path, Path], tmp_path: Path
) -> None:
    """LeRobot's own select_action executes the chunks; ours asks once per control step and
    resets its queues per episode, and the policy acts at its dataset's fps."""
    import shutil

    from mjkdl.demos import make_env, policy_rate
    from mjkdl.demos.lerobot_policy import LeRobotPolicy

    _, model = trained
    assert policy_rate(f"lerobot:{model}") == 10.0  # the export's fps: PickCube's 0.1 s period
    env = make_env(PICK, {**CAMERA, "max_episode_steps": 7})
    if "act" not in model.parts:
        policy = LeRobotPolicy(model, env)
        assert policy.execution == "chunk-wise: 4 actions of each chunk of 8, then a new chunk"
        env.close()
        return

    def counted(policy: LeRobotPolicy) -> list[int]:
        chunks, predict = [0], policy._policy.predict_action_chunk

        def counting(batch: object) -> object:
            chunks[0] += 1
            return predict(batch)

        policy._policy.predict_action_chunk = counting
        return chunks

    def run(policy: LeRobotPolicy, steps: int) -> None:
        obs, _ = env.reset(seed=0)
        policy.reset()
        for _ in range(steps):
            obs, *_ = env.step(policy(obs))

    policy = LeRobotPolicy(model, env)
    assert policy.execution == "chunk-wise: 4 actions of each chunk of 4, then a new chunk"
    chunks = counted(policy)
    run(policy, 6)
    assert chunks == [2]  # steps 0 and 4
    run(policy, 1)  # reset emptied the queue: a new chunk at once
    assert chunks == [3]
    ensembled = tmp_path / "te"
    shutil.copytree(model, ensembled)
    config = json.loads((ensembled / "config.json").read_text())
    config.update(temporal_ensemble_coeff=0.01, n_action_steps=1)
    (ensembled / "config.json").write_text(json.dumps(config))
    policy = LeRobotPolicy(ensembled, env)
    assert policy.execution == "temporal ensembling (coefficient 0.01, chunks of 4)"
    chunks = counted(policy)
    run(policy, 3)
    assert chunks == [3]  # a chunk every step, averaged with the earlier ones' predictions
    env.close()
