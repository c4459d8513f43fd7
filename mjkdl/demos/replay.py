"""Replay: a demo's actions in a fresh env (every recorded state again, exactly), or its
states set one by one (the camera observations rendered again)."""

from __future__ import annotations

import json
import os
import warnings
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import mujoco
import numpy as np

from ..errors import MjkdlError, SpecError
from ..record import VideoRecorder, offscreen_renderer
from ..scene import mujoco_version
from .episodes import Video, file_env, scene_of, success_of, video_recorder
from .hdf5 import STATE, Demo, DemoFile, mjkdl_version, scene_model

MODES = ("actions", "states")


class ReplayWarning(MjkdlError, UserWarning):
    """The file was recorded with another model or other versions: replay may differ."""


@dataclass(frozen=True)
class ReplayResult:
    """How a replay went. `actions`: the largest absolute difference between a recorded
    state and the replayed one (0.0 when exact) and the first step where they differ (-1
    when none). `states`: the largest difference of a re-rendered camera frame from the
    recorded one, in intensity levels (0-255; -1 without cameras)."""

    demo: str
    mode: str
    steps: int
    max_state_error: float
    first_mismatch: int
    max_pixel_error: int
    success: bool
    recorded_success: bool


def mismatches(demos: DemoFile, demo: Demo, env: gym.Env) -> list[str]:
    """Why a replay in `env` may not match what `demos` recorded; empty when nothing does."""
    out = []
    args = demos.env_args
    for key, now in (("mjkdl_version", mjkdl_version), ("mujoco_version", mujoco_version())):
        then = args.get(key)
        if then != now:
            name = "mjkdl" if key == "mjkdl_version" else "MuJoCo"
            out.append(f"{demos.path} was recorded with {name} {then}, this is {now}")
    scene = scene_of(env)
    if demo.model_hash and demo.model_hash != scene_model(scene)[1]:
        out.append(
            f"{demos.path}:{demo.name} was recorded with another model than "
            f"{demos.env_name} builds now (its model_file differs)"
        )
    return out


def replay(
    path: str | os.PathLike[str],
    demo: int | str = 0,
    *,
    mode: str = "actions",
    video: str | os.PathLike[str] | None = None,
    video_size: tuple[int, int] = (640, 480),
) -> ReplayResult:
    """Replay one demo of the file at `path` in a fresh `gymnasium.make(env_name,
    **env_kwargs)`; warns (`ReplayWarning`) first when the file was made with another model
    or version. `video`: an MP4 of the env's render camera, `video_size` (width, height)."""
    v = None if video is None else Video(Path(video), *video_size)
    return next(replay_all(path, [demo], mode=mode, video=v))


def replay_all(
    path: str | os.PathLike[str],
    demos: Sequence[int | str] | None = None,
    *,
    mode: str = "actions",
    video: Video | None = None,
) -> Iterator[ReplayResult]:
    """Replay `demos` (default: all) one after another in one env, built once (on the model
    the file stores where the asset files are missing: `file_env`): a result per demo as it
    finishes. `video` films the first."""
    if mode not in MODES:
        raise SpecError(f"--mode must be one of {', '.join(MODES)}, got {mode!r}")
    with DemoFile(path) as file:
        names = file.names if demos is None else [file.demo(d).name for d in demos]
        env = file_env(file)
        try:
            checked: set[str] = set()
            for name in names:
                d = file.demo(name)
                for message in mismatches(file, d, env):
                    if message not in checked:
                        warnings.warn(message, ReplayWarning, stacklevel=2)
                        checked.add(message)
                run = _replay_actions if mode == "actions" else _replay_states
                yield run(env, d, video)
                video = None
        finally:
            env.close()


def _state(scene: Any, out: np.ndarray) -> np.ndarray:
    mujoco.mj_getState(scene.model, scene.data, out, STATE)
    return out


def _reset(env: gym.Env, demo: Demo) -> None:
    """Reset as the demo was, its randomisation draw included (the same seed draws it again
    from the same description: a different one is refused by name)."""
    env.reset(seed=demo.seed)
    if not demo.randomization:
        return
    draw = getattr(env.unwrapped, "randomization_draw", None)
    recorded = json.loads(demo.randomization)
    if draw is None or draw.to_dict() != recorded:
        raise SpecError(
            f"{demo.name}: recorded with a domain-randomisation draw this env does not make "
            f"(its draw: {None if draw is None else draw.to_dict()}); make the env with the "
            "randomization= the demos were recorded with (data.attrs['env_args'])"
        )


def _replay_actions(env: gym.Env, demo: Demo, video: Video | None) -> ReplayResult:
    _reset(env, demo)
    scene = scene_of(env)
    state = np.empty(demo.states.shape[1])
    worst, first = 0.0, -1
    recorder = video_recorder(env, video) if video is not None else None
    info: dict[str, Any] = {}
    try:
        for t, action in enumerate(demo.actions):
            if recorder is not None:
                recorder.record_frame()
            err = float(np.max(np.abs(_state(scene, state) - demo.states[t]), initial=0.0))
            if err > 0 and first < 0:
                first = t
            worst = max(worst, err)
            _, _, terminated, truncated, info = env.step(action)
            if (terminated or truncated) and t < demo.num_samples - 1:
                first = t if first < 0 else first
                worst = max(worst, np.inf)
                break
        if recorder is not None:
            recorder.record_frame()
    finally:
        if recorder is not None:
            recorder.close()
    return ReplayResult(
        demo.name,
        "actions",
        demo.num_samples,
        worst,
        first,
        -1,
        success_of(info),
        demo.success,
    )


def _replay_states(env: gym.Env, demo: Demo, video: Video | None) -> ReplayResult:
    _reset(env, demo)
    scene = scene_of(env)
    model, data = scene.model, scene.data
    cameras = {
        key[: -len("_rgb")]: frames
        for key, frames in demo.obs.items()
        if key.endswith("_rgb") and frames.dtype == np.uint8 and frames.ndim == 4
    }
    renderers = {}
    for cam, frames in cameras.items():
        if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, cam) < 0:
            raise SpecError(f"{demo.name}: observation {cam}_rgb names no camera of the model")
        renderers[cam] = offscreen_renderer(
            model, frames.shape[2], frames.shape[1], shadows=False, reflections=False
        )
    recorder: VideoRecorder | None = video_recorder(env, video) if video is not None else None
    worst = -1 if not cameras else 0
    try:
        for t in range(demo.num_samples):
            mujoco.mj_setState(model, data, demo.states[t], STATE)
            mujoco.mj_forward(model, data)
            for cam, r in renderers.items():
                r.update_scene(data, camera=cam)
                frame = r.render()
                diff = np.abs(frame.astype(np.int16) - cameras[cam][t].astype(np.int16))
                worst = max(worst, int(diff.max()))
            if recorder is not None:
                recorder.record_frame()
    finally:
        for r in renderers.values():
            r.close()
        if recorder is not None:
            recorder.close()
    return ReplayResult(
        demo.name, "states", demo.num_samples, 0.0, -1, worst, demo.success, demo.success
    )
