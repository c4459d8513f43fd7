"""Episodes from seeds, recorded or not, in this process or spread over worker processes.

Workers are processes started with `spawn` (each builds its own env and GL context: a fork of
a process holding one is unsafe); each runs whole episodes and sends them back, and results
come out in seed order whatever order they finish in, so a file written from them is the same
for any number of workers.
"""

from __future__ import annotations

import dataclasses
import json
import multiprocessing
import os
import warnings
from collections.abc import Iterator, Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import mujoco
import numpy as np

from ..compile import stand_in
from ..errors import SpecError, SpecTypeError, unknown_name
from ..record import VideoRecorder
from ..scene import Scene
from ..task import Draw, TaskEnv  # importing mjkdl.task registers the tasks with Gymnasium
from .hdf5 import (
    STATE,
    DemoFile,
    EpisodeBuffer,
    EpisodeData,
    StoredModelWarning,
    adopt_scene_model,
)
from .policy import Policy, PolicySource, checked_action, make_policy

MAX_WORKERS = 256


@dataclass(frozen=True)
class Video:
    """An MP4 of an episode through the env's render camera, one frame per control step
    (shadows and reflections off: software rendering makes them cost more than physics)."""

    path: Path
    width: int = 640
    height: int = 480


@dataclass(frozen=True)
class EpisodeResult:
    """How one episode went: success (the last step's `info["is_success"]`), summed reward,
    steps, and the recording when one was asked for."""

    seed: int
    success: bool
    total_reward: float
    length: int
    diverged: bool
    data: EpisodeData | None = None


def make_env(env_id: str, env_kwargs: Mapping[str, Any] | None = None) -> gym.Env:
    """`gymnasium.make(env_id, **env_kwargs)` with mjkdl's tasks registered; an unknown id
    lists the registered ones. `env_id` may be a demonstration file (`.hdf5`) instead: the env
    its demos were recorded in, the recorded keywords updated by `env_kwargs`, on the model
    it stores where the asset files are missing (`file_env`)."""
    if not isinstance(env_id, str):
        raise SpecTypeError(f"env id must be a string, got {env_id!r}")
    if is_demo_file(env_id):
        with DemoFile(env_id) as f:
            return file_env(f, {**f.env_kwargs, **dict(env_kwargs or {})})
    if ":" not in env_id and env_id not in gym.registry:  # "module:id" imports module first
        raise unknown_name("env id", env_id, list(gym.registry), "Gymnasium's registry")
    return gym.make(env_id, **dict(env_kwargs or {}))


def is_demo_file(env_id: str) -> bool:
    """Whether `env_id` names a demonstration file (`.hdf5`, existing) rather than an id."""
    return env_id.endswith(".hdf5") and Path(env_id).is_file()


def file_env(file: DemoFile, env_kwargs: Mapping[str, Any] | None = None) -> gym.Env:
    """`make_env(file.env_name, env_kwargs)` (default: the recorded keywords); where the
    scene's model or asset files are missing (no Menagerie here), built on the compiled model
    the file stores for its first demo, with a `StoredModelWarning` saying so."""
    kwargs = file.env_kwargs if env_kwargs is None else dict(env_kwargs)
    with stand_in(lambda: file.model(0)) as missing:
        env = make_env(file.env_name, kwargs)
    if missing:
        xml, fingerprint, mjb = file.stored_model(0)
        adopt_scene_model(scene_of(env), (xml, fingerprint, mjb))
        warnings.warn(
            f"{missing[0]}; {file.env_name} runs on the model {file.path} stores instead "
            f"(models/{fingerprint[:12]}..., recorded with MuJoCo "
            f"{file.env_args.get('mujoco_version')})",
            StoredModelWarning,
            stacklevel=2,
        )
    return env


def parse_env_kwargs(text: str | None) -> dict[str, Any]:
    """`--env-kwargs` JSON as a dict (the error names the flag)."""
    if not text:
        return {}
    try:
        value = json.loads(text)
    except ValueError as err:
        raise SpecError(f"--env-kwargs is not valid JSON: {err}") from None
    if not isinstance(value, dict):
        raise SpecError(f"--env-kwargs must be a JSON object, got {text}")
    return value


def success_of(info: Mapping[str, Any]) -> bool:
    """`info["is_success"]` (Gymnasium-Robotics' key); an env without it never succeeds: a
    termination alone may be a failure (a pole that fell)."""
    return bool(info.get("is_success", False))


def run_episode(
    env: gym.Env,
    policy: Policy,
    seed: int,
    *,
    record: bool = False,
    video: Video | None = None,
    source: PolicySource = "policy",
) -> EpisodeResult:
    """Reset with `seed` (the action space too, for random actions) and act to the end."""
    obs, info = env.reset(seed=seed)
    env.action_space.seed(seed)
    reset = getattr(policy, "reset", None)
    if callable(reset):
        reset()
    buffer = EpisodeBuffer(scene_of(env)) if record else None
    recorder = video_recorder(env, video) if video is not None else None
    space = env.action_space
    total, steps, done = 0.0, 0, False
    try:
        if recorder is not None:
            recorder.record_frame()
        while not done:
            action = checked_action(policy(obs), space, source, seed, steps)
            if buffer is not None:
                buffer.before_step(obs)
            obs, reward, terminated, truncated, info = env.step(action)
            done = bool(terminated or truncated)
            if buffer is not None:
                buffer.after_step(action, float(reward), done, obs)
            if recorder is not None:
                recorder.record_frame()
            total += float(reward)
            steps += 1
    finally:
        if recorder is not None:
            recorder.close()
    success = success_of(info)
    data = None
    if buffer is not None:
        draw = getattr(env.unwrapped, "randomization_draw", None)
        data = buffer.finish(seed, success, "" if draw is None else json.dumps(draw.to_dict()))
    return EpisodeResult(seed, success, total, steps, bool(info.get("diverged", False)), data)


def scene_of(env: gym.Env) -> Scene:
    """The mjkdl scene under `env` (`env.unwrapped.scene`), which recording and videos need."""
    scene = getattr(env.unwrapped, "scene", None)
    if not isinstance(scene, Scene):
        name = type(env.unwrapped).__name__
        raise SpecError(
            f"{name} is not an mjkdl task env (it has no .scene holding MuJoCo's model and "
            "data): recording states and filming need one; evaluate it without --video"
        )
    return scene


def restore(
    env: gym.Env, state: np.ndarray, draw: Draw | Mapping[str, Any] | str | None = None
) -> tuple[dict[str, np.ndarray], float, bool, bool, dict[str, Any]]:
    """Set a recorded `mjSTATE_INTEGRATION` row in `env` (after a reset) and return what
    `step` returned on reaching it (`TaskEnv.observe`): the controllers' commands, the
    episode's counters and the actions on their way come back with the physics, so `step`
    goes on as recorded. On a randomised env the state is of one episode's draw, which MuJoCo's
    state does not hold: `draw` is it (`demo.randomization`, its dict or the `Draw`), applied
    to the model; a randomised env without it, or a draw without a randomised env, is refused."""
    scene = scene_of(env)
    unwrapped = env.unwrapped
    if not isinstance(unwrapped, TaskEnv):
        raise SpecError(f"{type(unwrapped).__name__} is not a TaskEnv: it cannot restore a state")
    if isinstance(draw, str):
        draw = json.loads(draw) if draw else None
    if draw is not None and not isinstance(draw, Draw):
        try:
            draw = Draw.from_dict(draw)
        except (TypeError, KeyError, ValueError) as err:
            raise SpecError(f"restore: draw is not a Draw or its dict: {err}") from None
    if unwrapped.randomization_draw is None:
        if draw is not None:
            raise SpecError(
                "restore: the state comes with a domain-randomisation draw and this env has no "
                "randomization: make it with the randomization= the demos were recorded with "
                "(data.attrs['env_args'])"
            )
    elif draw is None:
        raise SpecError(
            "restore: this env is randomised (TaskSpec.randomization) and a state is of one "
            "episode's draw (masses, friction, latency, noise), which MuJoCo's state does not "
            "hold: pass it, restore(env, state, draw=demo.randomization)"
        )
    else:
        unwrapped.randomization_draw = draw
    mujoco.mj_setState(scene.model, scene.data, state, STATE)
    return unwrapped.observe()


def video_recorder(env: gym.Env, video: Video) -> VideoRecorder:
    """`video` of the env's render camera (`front` on the registered tasks)."""
    unwrapped: Any = env.unwrapped
    period = float(getattr(unwrapped, "control_timestep", 0.1))
    rec = VideoRecorder.open(
        scene_of(env),
        video.path,
        video.width,
        video.height,
        fps=1.0 / period,
        shadows=False,
        reflections=False,
    )
    camera = getattr(unwrapped, "_render_camera_name", "")
    if camera:
        rec.use_camera(camera)
    return rec


def check_workers(workers: object) -> int:
    """`--workers` as a count from 1 to `MAX_WORKERS`."""
    if not isinstance(workers, (int, np.integer)) or isinstance(workers, bool):
        raise SpecTypeError(f"--workers must be a positive integer, got {workers!r}")
    if not 1 <= workers <= MAX_WORKERS:
        raise SpecError(f"--workers must be from 1 to {MAX_WORKERS}, got {workers}")
    return int(workers)


# Worker state: one env and policy per process, built by `_init`.
_WORKER: dict[str, Any] = {}


def _init(env_id: str, env_kwargs: dict[str, Any], source: PolicySource) -> None:
    os.environ.setdefault("MUJOCO_GL", "egl")
    env = make_env(env_id, env_kwargs)
    _WORKER.update(env=env, policy=make_policy(source, env), source=source)


def _run(seed: int, record: bool, video: Video | None) -> EpisodeResult:
    w = _WORKER
    r = run_episode(w["env"], w["policy"], seed, record=record, video=video, source=w["source"])
    sent = w.setdefault("models", set())
    if r.data is not None and r.data.model_hash in sent:  # the writer has it: spare the pipe
        r = dataclasses.replace(r, data=dataclasses.replace(r.data, model_mjb=b""))
    elif r.data is not None:
        sent.add(r.data.model_hash)
    return r


def run_seeds(
    env_id: str,
    env_kwargs: Mapping[str, Any],
    source: PolicySource,
    seeds: Sequence[int],
    *,
    record: bool = False,
    videos: Mapping[int, Video] | None = None,
    workers: int = 1,
) -> Iterator[EpisodeResult]:
    """One episode per seed, yielded in seed order; `videos` maps seeds to MP4s.

    The env and the policy are built here, before the first episode, so a bad id, keyword
    or policy fails before anything is written."""
    workers = check_workers(workers)
    kwargs = dict(env_kwargs)
    videos = dict(videos or {})
    env = make_env(env_id, kwargs)
    try:
        if record or videos:
            scene_of(env)
        policy = make_policy(source, env)
    except BaseException:
        env.close()
        raise
    if workers == 1:
        return _in_process(env, policy, source, seeds, record, videos)
    env.close()
    return _in_workers(env_id, kwargs, source, seeds, record, videos, workers)


def _in_process(
    env: gym.Env,
    policy: Policy,
    source: PolicySource,
    seeds: Sequence[int],
    record: bool,
    videos: dict[int, Video],
) -> Iterator[EpisodeResult]:
    try:
        for s in seeds:
            yield run_episode(env, policy, s, record=record, video=videos.get(s), source=source)
    finally:
        env.close()


def _in_workers(
    env_id: str,
    kwargs: dict[str, Any],
    source: PolicySource,
    seeds: Sequence[int],
    record: bool,
    videos: dict[int, Video],
    workers: int,
) -> Iterator[EpisodeResult]:
    ctx = multiprocessing.get_context("spawn")
    init = (env_id, kwargs, source)
    with ProcessPoolExecutor(workers, ctx, initializer=_init, initargs=init) as pool:
        futures = [pool.submit(_run, s, record, videos.get(s)) for s in seeds]
        try:
            for future in futures:
                yield future.result()
        finally:
            for future in futures:
                future.cancel()
