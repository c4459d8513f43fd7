"""LeRobot v3.0 export of an HDF5 demonstration file.

Written by lerobot's own `LeRobotDataset` (`create`, `add_frame`, `save_episode`,
`finalize`) where lerobot imports, else by pyarrow and ffmpeg in the same layout: lerobot
0.4 pins torch below 2.11, so it cannot sit beside a newer torch. The layout::

    meta/info.json                         codebase_version "v3.0", fps, features, paths
    meta/tasks.parquet                     task, task_index
    meta/episodes/chunk-000/file-000.parquet   one row per episode: where its rows and video
                                           frames are, its length, tasks and stats
    meta/stats.json                        min, max, mean, std, count per feature
    data/chunk-000/file-000.parquet        one row per frame
    videos/observation.images.<camera>/chunk-000/file-000.mp4   every episode, one frame a row

`observation.state` concatenates the `state_keys` observations in alphabetical order: by
default the robot's proprioception (the observations of the task's arms, `{arm}_...`: joint
positions and velocities, TCP pose and twist, gripper); the others (the objects' poses and
contacts, e.g. `cube_pose`, `cube_rel`, `cube_contacts`) are privileged, which a real robot does
not observe, and go in only when named. `action` is the demo's action. Camera frames are H.264
in full-resolution colour (yuv444p): chroma subsampling alone caps small renders near 35 dB.
"""

from __future__ import annotations

import importlib.util
import json
import os
import shutil
import warnings
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import MjkdlError
from ..record import h264_writer
from .episodes import make_env
from .hdf5 import Demo, DemoFile

CODEBASE_VERSION = "v3.0"
CHUNKS_SIZE = 1000
DATA_PATH = "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
VIDEO_PATH = "videos/{video_key}/chunk-{chunk_index:03d}/file-{file_index:03d}.mp4"
# H.264 near-lossless for rendered images; a keyframe every 2 frames, as lerobot encodes, so
# a loader can seek to any frame cheaply.
_X264 = ["-preset", "veryfast", "-crf", "16", "-g", "2", "-bf", "0", "-pix_fmt", "yuv444p"]
_SKIPPED = ("time",)
WRITERS = ("auto", "lerobot", "pyarrow")


class ExportError(MjkdlError, ValueError):
    """The demonstration file cannot be exported as asked (no demos, ragged observations)."""


@dataclass(frozen=True)
class LeRobotExport:
    """What an export wrote."""

    root: Path
    episodes: int
    frames: int
    fps: float
    cameras: list[str]
    writer: str


def _need_pyarrow() -> Any:
    try:
        import pyarrow as pa
        import pyarrow.parquet
    except ImportError:
        raise ImportError(
            "export-lerobot needs pyarrow (pip install 'mjkdl[parquet]') or lerobot itself "
            "(pip install 'mjkdl[lerobot]', in an environment of its own)"
        ) from None
    return pa


def _lerobot_dataset(writer: str) -> Any:
    """lerobot's `LeRobotDataset` class for `writer` "lerobot" or "auto", else None; "auto"
    goes on without it when lerobot is absent or fails to import (said in a warning)."""
    if writer not in WRITERS:
        raise ExportError(f"writer must be one of {', '.join(WRITERS)}; got {writer!r}")
    if writer == "pyarrow" or (writer == "auto" and importlib.util.find_spec("lerobot") is None):
        return None
    try:
        from lerobot.datasets.lerobot_dataset import LeRobotDataset
    except Exception as err:  # an install beside the wrong torch fails in many ways
        why = f"lerobot does not import ({type(err).__name__}: {err})"
        if writer == "lerobot":
            raise ImportError(
                f"writer='lerobot' needs lerobot 0.4 and its torch: {why}; pip install "
                "'lerobot>=0.4,<0.5' in an environment of its own, or use writer='pyarrow'"
            ) from None
        warnings.warn(f"{why}; exporting with pyarrow instead", stacklevel=3)
        return None
    return LeRobotDataset


def observation_keys(obs: Mapping[str, np.ndarray], leading: int) -> tuple[list[str], list[str]]:
    """Sorted vector keys (1-D or scalar per step) and camera keys (`<camera>_rgb`, uint8
    H×W×3) of `obs`, whose arrays have `leading` extra dimensions (1 for a demo's rows)."""
    state, cams = [], []
    for key, value in obs.items():
        value = np.asarray(value)
        if key.endswith("_rgb") and value.dtype == np.uint8 and value.ndim == 3 + leading:
            cams.append(key)
        elif key not in _SKIPPED and not key.endswith("_intrinsics") and value.ndim <= 1 + leading:
            state.append(key)
    return sorted(state), sorted(cams)


def _split(demo: Demo) -> tuple[list[str], list[str]]:
    return observation_keys(demo.obs, leading=1)


def _state_matrix(demo: Demo, keys: list[str]) -> np.ndarray:
    n = demo.num_samples
    cols = [demo.obs[k].reshape(n, -1).astype(np.float32) for k in keys]
    return np.concatenate(cols, axis=1) if cols else np.zeros((n, 0), np.float32)


def _stats(x: np.ndarray) -> dict[str, Any]:
    x = x.astype(np.float64)
    return {
        "min": x.min(axis=0).tolist(),
        "max": x.max(axis=0).tolist(),
        "mean": x.mean(axis=0).tolist(),
        "std": x.std(axis=0).tolist(),
        "count": [len(x)],
    }


def _image_stats(frames: list[np.ndarray]) -> dict[str, Any]:
    """Per channel over every pixel, in [0, 1], shaped (3, 1, 1) as lerobot keeps them."""
    total = np.zeros(3)
    squares = np.zeros(3)
    lo, hi = np.full(3, 255.0), np.zeros(3)
    count = 0
    for f in frames:
        px = f.reshape(-1, 3).astype(np.float64)
        total += px.sum(0)
        squares += (px * px).sum(0)
        lo, hi = np.minimum(lo, px.min(0)), np.maximum(hi, px.max(0))
        count += len(px)
    mean = total / count
    std = np.sqrt(np.maximum(squares / count - mean * mean, 0.0))

    def shaped(v: np.ndarray) -> list[Any]:
        return (v / 255.0).reshape(3, 1, 1).tolist()

    return {
        "min": shaped(lo),
        "max": shaped(hi),
        "mean": shaped(mean),
        "std": shaped(std),
        "count": [sum(len(f) for f in frames)],
    }


def _names(demo: Demo, keys: list[str]) -> list[str]:
    out = []
    for k in keys:
        width = int(np.prod(demo.obs[k].shape[1:], dtype=int))
        out += [k] if width == 1 else [f"{k}.{i}" for i in range(width)]
    return out


def _env_facts(env_name: str, env_kwargs: dict[str, Any]) -> tuple[float, list[str]]:
    """The env's frames per second (1 / control period) and its arms' observation prefixes."""
    env = make_env(env_name, env_kwargs)
    try:
        period = getattr(env.unwrapped, "control_timestep", None)
        fps = 1.0 / float(period) if period else float(env.metadata.get("render_fps", 0))
        spec = getattr(env.unwrapped, "task_spec", None)
        arms = [f"{a.name}_" for a in getattr(spec, "arms", [])]
    finally:
        env.close()
    if not fps > 0:
        raise ExportError(f"{env_name} gives no control period (control_timestep or render_fps)")
    return (round(fps) if abs(fps - round(fps)) < 1e-9 else fps), arms


def proprioception(candidates: list[str], arm_prefixes: list[str]) -> list[str]:
    """The keys of `candidates` the arms observe of themselves (`{arm}_...`)."""
    return [k for k in candidates if any(k.startswith(p) for p in arm_prefixes)]


def _chosen_state_keys(
    first: Demo, arms: list[str], state_keys: Sequence[str] | None, path: Path
) -> list[str]:
    candidates = _split(first)[0]
    if state_keys is None:
        return proprioception(candidates, arms)
    keys = list(state_keys)
    for k in keys:
        if k not in candidates:
            raise ExportError(
                f"--state-keys: {path} has no vector observation {k!r}; it has "
                f"{', '.join(candidates)}"
            )
    # alphabetical, whatever order they were named in (as the policy evaluator takes them)
    return [k for k in candidates if k in keys]


def _tasks_table(pa: Any, tasks: list[str]) -> Any:
    """`meta/tasks.parquet`: `task_index` by task, with the pandas metadata that makes the task
    the frame's index when pandas reads it back, as lerobot's `load_tasks` expects."""
    pandas_meta = {
        "index_columns": ["task"],
        "column_indexes": [],
        "columns": [
            {"name": "task_index", "field_name": "task_index", "pandas_type": "int64",
             "numpy_type": "int64", "metadata": None},
            {"name": "task", "field_name": "task", "pandas_type": "unicode",
             "numpy_type": "object", "metadata": None},
        ],
    }  # fmt: skip
    table = pa.table({"task_index": pa.array(range(len(tasks)), pa.int64()), "task": tasks})
    return table.replace_schema_metadata({"pandas": json.dumps(pandas_meta)})


class _Video:
    """One camera's MP4 of every episode, one video frame per dataset frame."""

    def __init__(self, path: Path, width: int, height: int, fps: float) -> None:
        path.parent.mkdir(parents=True, exist_ok=True)
        self.frames = 0
        self._writer = h264_writer(path, width, height, fps, _X264)

    def put(self, frames: np.ndarray) -> None:
        for f in frames:
            self._writer.send(np.ascontiguousarray(f))
            self.frames += 1

    def close(self) -> None:
        self._writer.close()


def export_lerobot(
    path: str | os.PathLike[str],
    root: str | os.PathLike[str],
    *,
    repo_id: str = "",
    task: str = "",
    overwrite: bool = False,
    writer: str = "auto",
    state_keys: Sequence[str] | None = None,
) -> LeRobotExport:
    """Write the demos of `path` as a LeRobot v3.0 dataset in the new folder `root`.

    `writer`: "lerobot" (its own `LeRobotDataset`), "pyarrow", or "auto" (lerobot where it
    imports). `state_keys`: the observations `observation.state` concatenates (default: the
    robot's proprioception; privileged keys such as `cube_pose` only when named)."""
    dataset_cls = _lerobot_dataset(writer)
    if dataset_cls is None:
        _need_pyarrow()
    out = Path(root)
    if out.exists() and any(out.iterdir()):
        if not overwrite:
            raise ExportError(f"--root {out} exists and is not empty; pick a new folder")
        shutil.rmtree(out)
    with DemoFile(path) as demos:
        if len(demos) == 0:
            raise ExportError(f"{demos.path} holds no finished demos to export")
        fps, arms = _env_facts(demos.env_name, demos.env_kwargs)
        task = task or demos.env_name
        first = demos.demo(demos.names[0])
        depth = sorted(k for k, v in first.obs.items() if k.endswith("_depth") and v.ndim == 3)
        if depth:
            raise ExportError(
                f"{demos.path} holds depth images {depth} (float32 metres): LeRobot's video "
                "features hold 8-bit colour, which would quantise them; export a copy without "
                "them: python -m mjkdl.demos convert IN OUT --env-kwargs "
                "'{\"camera_depth\": false}'"
            )
        keys = _chosen_state_keys(first, arms, state_keys, demos.path)
        try:
            if dataset_cls is not None:
                return _write_with_lerobot(dataset_cls, demos, out, fps, task, repo_id, first, keys)
            return _write(demos, out, fps, task, repo_id, first, keys)
        except BaseException:
            shutil.rmtree(out, ignore_errors=True)  # no half-written dataset
            raise


def _episodes(
    demos: DemoFile, first: Demo, state_keys: list[str]
) -> Iterator[tuple[Demo, np.ndarray, np.ndarray]]:
    """Each demo with its `observation.state` and `action` rows; every demo must have the
    first one's observations."""
    every, cam_keys = _split(first)
    for demo in demos:
        keys, cams = _split(demo)
        if (keys, cams) != (every, cam_keys):
            raise ExportError(
                f"{demos.path}: {demo.name} has observations {keys + cams}, "
                f"the first demo {every + cam_keys}"
            )
        n = demo.num_samples
        yield demo, _state_matrix(demo, state_keys), demo.actions.astype(np.float32).reshape(n, -1)


def _video_keys(cam_keys: list[str]) -> dict[str, str]:
    """`<camera>_rgb` observation -> `observation.images.<camera>` feature."""
    return {k: f"observation.images.{k[: -len('_rgb')]}" for k in cam_keys}


def _write_with_lerobot(
    dataset_cls: Any,
    demos: DemoFile,
    out: Path,
    fps: float,
    task: str,
    repo_id: str,
    first: Demo,
    state_keys: list[str],
) -> LeRobotExport:
    """The dataset written frame by frame by lerobot's own `LeRobotDataset`."""
    if fps != int(fps):
        raise ExportError(
            f"lerobot's writer takes a whole number of frames per second; {demos.env_name}'s "
            f"control period gives {fps:g}: pass writer='pyarrow'"
        )
    cam_keys = _split(first)[1]
    video_key = _video_keys(cam_keys)
    names = _names(first, state_keys)
    features: dict[str, Any] = {
        "observation.state": {"dtype": "float32", "shape": (len(names),), "names": names},
        "action": {
            "dtype": "float32",
            "shape": (int(np.prod(first.actions.shape[1:], dtype=int)),),
            "names": None,
        },
        "next.reward": {"dtype": "float32", "shape": (1,), "names": None},
        "next.done": {"dtype": "bool", "shape": (1,), "names": None},
    }
    for k in cam_keys:
        features[video_key[k]] = {
            "dtype": "video",
            "shape": first.obs[k].shape[1:],
            "names": ["height", "width", "channels"],
        }
    if out.exists():
        out.rmdir()  # empty (checked): lerobot makes the folder itself
    dataset = dataset_cls.create(
        repo_id or f"local/{demos.path.stem}",
        fps=int(fps),
        features=features,
        root=out,
        use_videos=bool(cam_keys),
    )  # lerobot's own video settings: AV1 (SVT-AV1) at CRF 30
    frames = 0
    try:
        for demo, state, action in _episodes(demos, first, state_keys):
            reward = demo.rewards.astype(np.float32).reshape(-1, 1)
            done = demo.dones.astype(bool).reshape(-1, 1)
            for t in range(demo.num_samples):
                frame = {
                    "observation.state": state[t],
                    "action": action[t],
                    "next.reward": reward[t],
                    "next.done": done[t],
                    "task": task,
                }
                for k in cam_keys:
                    frame[video_key[k]] = demo.obs[k][t]
                dataset.add_frame(frame)
            dataset.save_episode()
            frames += demo.num_samples
    finally:
        dataset.finalize()  # parquet footers: without them nothing reads the files
    episodes = int(dataset.meta.total_episodes)
    return LeRobotExport(out, episodes, frames, fps, list(video_key.values()), "lerobot")


def _write(
    demos: DemoFile,
    out: Path,
    fps: float,
    task: str,
    repo_id: str,
    first: Demo,
    state_keys: list[str],
) -> LeRobotExport:
    """The dataset written column by column with pyarrow, its videos with ffmpeg."""
    pa = _need_pyarrow()
    import pyarrow.parquet as pq

    cam_keys = _split(first)[1]
    videos: dict[str, _Video] = {}
    video_key = _video_keys(cam_keys)
    for k in cam_keys:
        _, h, w, _ = first.obs[k].shape
        p = out / VIDEO_PATH.format(video_key=video_key[k], chunk_index=0, file_index=0)
        videos[k] = _Video(p, w, h, fps)
    columns: dict[str, list[Any]] = {
        c: []
        for c in (
            "observation.state",
            "action",
            "next.reward",
            "next.done",
            "timestamp",
            "frame_index",
            "episode_index",
            "index",
            "task_index",
        )
    }
    episodes: list[dict[str, Any]] = []
    all_state, all_action = [], []
    image_samples: dict[str, list[np.ndarray]] = {k: [] for k in cam_keys}
    index = 0
    try:
        for ep, (demo, state, action) in enumerate(_episodes(demos, first, state_keys)):
            n = demo.num_samples
            all_state.append(state)
            all_action.append(action)
            frame = np.arange(n)
            columns["observation.state"] += list(state)
            columns["action"] += list(action)
            columns["next.reward"] += demo.rewards.astype(np.float32).tolist()
            columns["next.done"] += [bool(d) for d in demo.dones]
            columns["timestamp"] += (frame / fps).astype(np.float32).tolist()
            columns["frame_index"] += frame.tolist()
            columns["episode_index"] += [ep] * n
            columns["index"] += list(range(index, index + n))
            columns["task_index"] += [0] * n
            row: dict[str, Any] = {
                "episode_index": ep,
                "tasks": [task],
                "length": n,
                "data/chunk_index": 0,
                "data/file_index": 0,
                "dataset_from_index": index,
                "dataset_to_index": index + n,
            }
            for k in cam_keys:
                start = videos[k].frames
                videos[k].put(demo.obs[k])
                row[f"videos/{video_key[k]}/chunk_index"] = 0
                row[f"videos/{video_key[k]}/file_index"] = 0
                row[f"videos/{video_key[k]}/from_timestamp"] = start / fps
                row[f"videos/{video_key[k]}/to_timestamp"] = (start + n) / fps
                image_samples[k].append(demo.obs[k][:: max(1, n // 10)])
            row["meta/episodes/chunk_index"] = 0
            row["meta/episodes/file_index"] = 0
            for name, values in (("observation.state", state), ("action", action)):
                for stat, value in _stats(values).items():
                    row[f"stats/{name}/{stat}"] = value
            episodes.append(row)
            index += n
    finally:
        for v in videos.values():
            v.close()

    vec = pa.list_(pa.float32())
    schema = pa.schema(
        [
            ("observation.state", vec),
            ("action", vec),
            ("next.reward", pa.float32()),
            ("next.done", pa.bool_()),
            ("timestamp", pa.float32()),
            ("frame_index", pa.int64()),
            ("episode_index", pa.int64()),
            ("index", pa.int64()),
            ("task_index", pa.int64()),
        ]
    )
    columns["observation.state"] = [r.tolist() for r in columns["observation.state"]]
    columns["action"] = [r.tolist() for r in columns["action"]]
    data_path = out / DATA_PATH.format(chunk_index=0, file_index=0)
    data_path.parent.mkdir(parents=True, exist_ok=True)
    pq.write_table(pa.table(columns, schema=schema), data_path)

    meta = out / "meta"
    (meta / "episodes" / "chunk-000").mkdir(parents=True, exist_ok=True)
    pq.write_table(pa.Table.from_pylist(episodes), meta / "episodes/chunk-000/file-000.parquet")
    pq.write_table(_tasks_table(pa, [task]), meta / "tasks.parquet")
    stats: dict[str, Any] = {
        "observation.state": _stats(np.concatenate(all_state)),
        "action": _stats(np.concatenate(all_action)),
    }
    for k in cam_keys:
        stats[video_key[k]] = _image_stats(image_samples[k])
    (meta / "stats.json").write_text(json.dumps(stats, indent=2))

    features: dict[str, Any] = {
        "observation.state": {
            "dtype": "float32",
            "shape": [len(_names(first, state_keys))],
            "names": _names(first, state_keys),
        },
        "action": {
            "dtype": "float32",
            "shape": [int(np.prod(first.actions.shape[1:], dtype=int))],
            "names": None,
        },
    }
    for k in cam_keys:
        _, h, w, c = first.obs[k].shape
        features[video_key[k]] = {
            "dtype": "video",
            "shape": [h, w, c],
            "names": ["height", "width", "channels"],
            "info": {
                "video.height": h,
                "video.width": w,
                "video.codec": "h264",
                "video.pix_fmt": "yuv420p",
                "video.is_depth_map": False,
                "video.fps": fps,
                "video.channels": c,
                "has_audio": False,
            },
        }
    for name, dtype in (
        ("next.reward", "float32"),
        ("next.done", "bool"),
        ("timestamp", "float32"),
        ("frame_index", "int64"),
        ("episode_index", "int64"),
        ("index", "int64"),
        ("task_index", "int64"),
    ):
        features[name] = {"dtype": dtype, "shape": [1], "names": None}
    info = {
        "codebase_version": CODEBASE_VERSION,
        "robot_type": None,
        "repo_id": repo_id or None,
        "total_episodes": len(episodes),
        "total_frames": index,
        "total_tasks": 1,
        "chunks_size": CHUNKS_SIZE,
        "data_files_size_in_mb": 100,
        "video_files_size_in_mb": 500,
        "fps": fps,
        "splits": {"train": f"0:{len(episodes)}"},
        "data_path": DATA_PATH,
        "video_path": VIDEO_PATH if cam_keys else None,
        "features": features,
    }
    (meta / "info.json").write_text(json.dumps(info, indent=2))
    return LeRobotExport(out, len(episodes), index, fps, list(video_key.values()), "pyarrow")
