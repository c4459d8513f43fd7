"""LeRobot v3.0 export, read back with pyarrow and ffmpeg: one row and one video frame per
recorded step, actions equal to the HDF5's, images within codec tolerance."""

from __future__ import annotations

import json
from pathlib import Path

import imageio_ffmpeg
import numpy as np
import pyarrow.parquet as pq
import pytest
from conftest import menagerie
from demo_envs import CAMERA
from test_demos_hdf5 import PICK, REACH, cli

from mjkdl.demos import DemoFile, EpisodeWriter, ExportError, collect, export_lerobot


@pytest.fixture(scope="module")
def exported(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    menagerie("franka_emika_panda")
    folder = tmp_path_factory.mktemp("lerobot")
    demos = folder / "cam.hdf5"
    collect(PICK, "demo_envs:approach", demos, episodes=3, seed=1, keep_failures=True,
            env_kwargs={**CAMERA, "max_episode_steps": 7}, progress=False)  # fmt: skip
    r = cli("export-lerobot", str(demos), "--root", str(folder / "ds"), "--repo-id", "me/pick")
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == f"{folder / 'ds'}: 3 episodes, 21 frames"
    return demos, folder / "ds"


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    mse = np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2)
    return float("inf") if mse == 0 else 10 * np.log10(255.0**2 / mse)


def test_info_tasks_and_stats(exported: tuple[Path, Path]) -> None:
    _, root = exported
    info = json.loads((root / "meta/info.json").read_text())
    assert info["codebase_version"] == "v3.0" and info["fps"] == 10
    assert (info["total_episodes"], info["total_frames"], info["total_tasks"]) == (3, 21, 1)
    assert info["repo_id"] == "me/pick" and info["splits"] == {"train": "0:3"}
    feats = info["features"]
    assert feats["observation.images.front"]["shape"] == [48, 64, 3]
    assert feats["observation.images.front"]["dtype"] == "video"
    assert feats["action"] == {"dtype": "float32", "shape": [7], "names": None}
    assert feats["observation.state"]["shape"][0] == len(feats["observation.state"]["names"])
    assert "panda_tcp_pos.2" in feats["observation.state"]["names"]
    tasks = pq.read_table(root / "meta/tasks.parquet").to_pylist()
    assert tasks == [{"task_index": 0, "task": PICK}]
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
    worst = min(psnr(a, b) for a, b in zip(decoded, recorded, strict=True))
    assert worst >= 35.0, worst


def test_bad_exports(exported: tuple[Path, Path], tmp_path: Path) -> None:
    demos, root = exported
    with pytest.raises(ExportError, match="exists and is not empty; pick a new folder"):
        export_lerobot(demos, root)
    empty = tmp_path / "empty.hdf5"
    EpisodeWriter(empty, REACH).close()
    with pytest.raises(ExportError, match=r"empty\.hdf5 holds no finished demos to export"):
        export_lerobot(empty, tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_lerobots_own_loader_reads_the_export(exported: tuple[Path, Path]) -> None:
    """Where lerobot installs (0.4 pins torch < 2.11; CI has a newer torch, so this skips
    there): its `LeRobotDataset` reads the metadata, tasks and rows."""
    lerobot_dataset = pytest.importorskip("lerobot.datasets.lerobot_dataset")
    demos, root = exported
    ds = lerobot_dataset.LeRobotDataset("me/pick", root=root)
    assert (ds.num_episodes, ds.num_frames, ds.fps) == (3, 21, 10)
    assert ds.meta.video_keys == ["observation.images.front"]
    assert ds.meta.get_task_index(PICK) == 0
    with DemoFile(demos) as f:
        actions = np.concatenate([d.actions for d in f])
    assert np.array_equal(np.stack([np.asarray(a) for a in ds.hf_dataset["action"]]), actions)
