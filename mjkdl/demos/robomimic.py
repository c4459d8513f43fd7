"""robomimic on mjkdl's files: an `EnvBase` that robomimic's `env_utils` builds for them, and
robomimic's own scripts run with it registered.

robomimic 0.3.0 builds an env from a file's `env_args` by its `type` (`EnvType`): robosuite,
its `EnvGym` (the old `gym` API: four-value `step`, and `reset` without a seed) or iGibson, with
no way to add one. `register()` makes `env_utils.get_env_class` answer `ENV_TYPE` (what mjkdl
writes) with `EnvMjkdl`, a Gymnasium task behind robomimic's env interface; everything else
is left to robomimic. `python -m mjkdl.demos.robomimic SCRIPT ARGS...` registers and runs
`robomimic/scripts/SCRIPT.py` itself (`train`, `playback_dataset`, `dataset_states_to_obs`,
`run_trained_agent`, ...).
"""

from __future__ import annotations

import io
import json
import os
import runpy
import sys
from collections.abc import Mapping, Sequence
from copy import deepcopy
from pathlib import Path
from typing import Any, TextIO

import gymnasium as gym
import mujoco
import numpy as np
import robomimic
import robomimic.envs.env_base as env_base
import robomimic.utils.env_utils as env_utils
import robomimic.utils.file_utils as file_utils
import robomimic.utils.obs_utils as obs_utils

# torchvision loads torch._dynamo, which loads Triton's LLVM: loaded after an EGL context of
# Mesa's llvmpipe (software rendering), it segfaults at import, so it comes before any env
# (robomimic's networks import it anyway).
import torchvision  # noqa: F401

from .. import __version__ as mjkdl_version
from ..errors import SpecError
from ..record import offscreen_renderer
from .episodes import file_env, make_env, restore, scene_of, success_of
from .hdf5 import ENV_TYPE, STATE, DemoFile, scene_model
from .robomimic_hook import LINES, MARK

_DATASETS: list[str] = []  # files robomimic read env metadata from (register), latest last


def _task_env(env_name: str, kwargs: dict[str, Any]) -> gym.Env:
    """The task, built on the stored model of the latest file robomimic read it from where
    its asset files are missing (`file_env`)."""
    for path in reversed(_DATASETS):
        with DemoFile(path) as f:
            if f.env_name == env_name:
                return file_env(f, kwargs)
    return make_env(env_name, kwargs)


class EnvMjkdl(env_base.EnvBase):
    """An mjkdl task (`gymnasium.make(env_name, **kwargs)`) as robomimic's `EnvBase`.

    Observations are the task's dict; camera keys robomimic knows as `rgb` come channel-first
    in [0, 1] when `postprocess_visual_obs` (as robomimic's networks take them). `reset_to`
    sets a recorded `mjSTATE_INTEGRATION` state and observes it."""

    def __init__(
        self,
        env_name: str,
        render: bool = False,
        render_offscreen: bool = False,
        use_image_obs: bool = False,
        postprocess_visual_obs: bool = True,
        **kwargs: Any,
    ) -> None:
        if render:
            raise SpecError(
                "EnvMjkdl renders off-screen only (render=False); watch an episode with "
                "python -m mjkdl.demos replay FILE --video out.mp4"
            )
        self._init_kwargs = deepcopy(kwargs)
        self._env_name = env_name
        self._postprocess = postprocess_visual_obs
        self.env = _task_env(env_name, kwargs)
        self._scene = scene_of(self.env)
        self._renderers: dict[tuple[int, int], mujoco.Renderer] = {}
        self._obs: dict[str, np.ndarray] = {}
        self._reward = 0.0
        self._done = False
        self._success = False

    # robomimic's interface ------------------------------------------------------------

    def step(self, action: np.ndarray) -> tuple[dict[str, np.ndarray], float, bool, dict]:
        """One control step: (observation, reward, done, info), done at the task's end."""
        obs, reward, terminated, truncated, info = self.env.step(np.asarray(action))
        self._obs, self._reward = obs, float(reward)
        self._done, self._success = bool(terminated or truncated), success_of(info)
        return self.get_observation(obs), self._reward, self._done, info

    def reset(self) -> dict[str, np.ndarray]:
        """A new episode (the env's generator continues: rollouts see fresh seeds)."""
        obs, info = self.env.reset()
        self._obs, self._reward, self._done, self._success = obs, 0.0, False, success_of(info)
        return self.get_observation(obs)

    def reset_to(self, state: Mapping[str, Any]) -> dict[str, np.ndarray]:
        """Set `state["states"]` (a row of a demo's `states`, which holds the controllers'
        commands and the episode's counters too) and observe it: the observation, reward and
        end recorded with it (`TaskEnv.observe`); a `model` entry (robosuite's) is not
        needed: the env builds its own. A randomised env needs the episode's draw with it,
        `state["randomization"]` (the demo's attribute of that name)."""
        flat = np.asarray(state["states"], dtype=np.float64)
        size = mujoco.mj_stateSize(self._scene.model, STATE)
        if flat.shape != (size,):
            raise SpecError(
                f"reset_to: states must have shape ({size},) (mjSTATE_INTEGRATION of "
                f"{self._env_name}), got {flat.shape}"
            )
        draw = state.get("randomization")
        obs, reward, terminated, truncated, info = restore(self.env, flat, draw)
        self._obs, self._reward = obs, float(reward)
        self._done, self._success = bool(terminated or truncated), success_of(info)
        return self.get_observation(obs)

    def render(
        self,
        mode: str = "human",
        height: int | None = None,
        width: int | None = None,
        camera_name: str | None = None,
        **kwargs: Any,
    ) -> np.ndarray:
        """`rgb_array` of `camera_name` (default: the task's render camera)."""
        if mode != "rgb_array":
            raise SpecError(f"EnvMjkdl renders mode='rgb_array' only, got {mode!r}")
        task: Any = self.env.unwrapped
        size = (int(width or 512), int(height or 512))
        r = self._renderers.get(size)
        if r is None:
            r = offscreen_renderer(self._scene.model, *size, shadows=False, reflections=False)
            self._renderers[size] = r
        camera = camera_name or task._render_camera  # a camera id or the free camera
        r.update_scene(self._scene.data, camera=camera)
        return np.asarray(r.render())

    def get_observation(self, obs: Mapping[str, np.ndarray] | None = None) -> dict:
        """The observation dict, camera frames as robomimic's networks take them."""
        obs = self._obs if obs is None else obs
        known = obs_utils.OBS_KEYS_TO_MODALITIES or {}
        out = {}
        for key, value in obs.items():
            if self._postprocess and known.get(key) in ("rgb", "depth"):
                out[key] = obs_utils.process_obs(obs=np.array(value), obs_key=key)
            else:
                out[key] = np.array(value)
        return out

    def get_state(self) -> dict[str, Any]:
        """The MuJoCo state (`states`, as files record it) and the model's MJCF (`model`)."""
        model, data = self._scene.model, self._scene.data
        flat = np.empty(mujoco.mj_stateSize(model, STATE))
        mujoco.mj_getState(model, data, flat, STATE)
        return {"model": scene_model(self._scene)[0], "states": flat}

    def get_reward(self) -> float:
        """The last step's reward (or the reward of the state `reset_to` set)."""
        return self._reward

    def get_goal(self) -> dict:
        raise NotImplementedError("mjkdl tasks have no goal observations")

    def set_goal(self, **kwargs: Any) -> None:
        raise NotImplementedError("mjkdl tasks have no goal observations")

    def is_done(self) -> bool:
        """Whether the episode ended (terminated or truncated)."""
        return self._done

    def is_success(self) -> dict[str, bool]:
        """`{"task": info["is_success"]}`."""
        return {"task": self._success}

    @property
    def action_dimension(self) -> int:
        space: Any = self.env.action_space
        return int(space.shape[0])

    @property
    def name(self) -> str:
        """The Gymnasium id with `/` as `_`: robomimic names rollout videos after it."""
        return self._env_name.replace("/", "_")

    @property
    def type(self) -> int:
        return ENV_TYPE

    @property
    def version(self) -> str:
        return mjkdl_version

    def serialize(self) -> dict[str, Any]:
        """The file's `env_args`: what `create_env_from_metadata` takes back."""
        kwargs = deepcopy(self._init_kwargs)
        return {"env_name": self._env_name, "type": self.type, "env_kwargs": kwargs}

    @classmethod
    def create_for_data_processing(
        cls,
        env_name: str,
        camera_names: Sequence[str],
        camera_height: int,
        camera_width: int,
        reward_shaping: bool,
        **kwargs: Any,
    ) -> EnvMjkdl:
        """The env `dataset_states_to_obs.py` observes with: `camera_names` at
        `camera_width`×`camera_height` (none: the file's own cameras)."""
        if camera_names:
            kwargs = {
                **kwargs,
                "camera_names": list(camera_names),
                "camera_size": [camera_height, camera_width],
            }
        env = cls(env_name, postprocess_visual_obs=False, **kwargs)
        space: Any = env.env.observation_space
        keys = list(space.spaces)
        rgb = [k for k in keys if k.endswith("_rgb")]
        depth = [k for k in keys if k.endswith("_depth")]
        low_dim = [k for k in keys if k not in rgb and k not in depth]
        obs_utils.initialize_obs_utils_with_obs_specs(
            {"obs": {"low_dim": low_dim, "rgb": rgb, "depth": depth}}
        )
        return env

    @property
    def rollout_exceptions(self) -> tuple[Any, ...]:
        return ()

    def __repr__(self) -> str:
        return self.name + "\n" + json.dumps(self._init_kwargs, sort_keys=True, indent=4)


def register() -> None:
    """Make robomimic's `env_utils` build `EnvMjkdl` for files of `ENV_TYPE`, and remember the
    files robomimic reads env metadata from (`EnvMjkdl` builds on one's stored model where
    the asset files are missing); idempotent."""
    read = file_utils.get_env_metadata_from_dataset
    if not getattr(read, "mjkdl", False):

        def get_env_metadata_from_dataset(dataset_path: str) -> dict:
            meta = read(dataset_path)
            if meta.get("type") == ENV_TYPE:
                _DATASETS.append(os.path.expanduser(dataset_path))
            return meta

        get_env_metadata_from_dataset.mjkdl = True  # type: ignore[attr-defined]
        file_utils.get_env_metadata_from_dataset = get_env_metadata_from_dataset
    original = env_utils.get_env_class
    if getattr(original, "mjkdl", False):
        return

    def get_env_class(env_meta: Any = None, env_type: Any = None, env: Any = None) -> type:
        kind = env_utils.get_env_type(env_meta=env_meta, env_type=env_type, env=env)
        if kind == ENV_TYPE:
            return EnvMjkdl
        return original(env_meta=env_meta, env_type=env_type, env=env)

    get_env_class.mjkdl = True  # type: ignore[attr-defined]
    env_utils.get_env_class = get_env_class


def install() -> Path:
    """Make robomimic's own scripts, run directly, build mjkdl's env type: add the call of
    `robomimic_hook.install` to robomimic's private macro file (created if absent, kept
    otherwise; idempotent). The file's path."""
    path = Path(robomimic.__file__).parent / "macros_private.py"
    text = path.read_text() if path.exists() else ""
    if MARK not in text:
        try:
            path.write_text(text + ("\n" if text and not text.endswith("\n") else "") + LINES)
        except OSError as err:
            raise SpecError(f"cannot add mjkdl's hook to {path}: {err}") from None
    return path


class _Watched(io.TextIOBase):
    """stdout, noting whether robomimic's train.py reported a failed run (it catches the
    error, prints it and exits 0)."""

    def __init__(self, out: TextIO) -> None:
        self.out, self.failed = out, False

    def write(self, text: str) -> int:
        self.failed = self.failed or "run failed with error" in text
        return self.out.write(text)

    def flush(self) -> None:
        self.out.flush()


def main(argv: Sequence[str] | None = None) -> None:
    """`python -m mjkdl.demos.robomimic SCRIPT ARGS...`: robomimic's `scripts/SCRIPT.py`
    with ARGS, mjkdl's env type registered; exits 1 when `train` reports a failed run.
    `python -m mjkdl.demos.robomimic install`: `install()`, so that the scripts run directly
    do the same."""
    args = list(sys.argv[1:] if argv is None else argv)
    if not args or args[0].startswith("-"):
        print(
            "usage: python -m mjkdl.demos.robomimic SCRIPT [ARGS...]  (SCRIPT: train, "
            "playback_dataset, dataset_states_to_obs, run_trained_agent, ...), or "
            "python -m mjkdl.demos.robomimic install",
            file=sys.stderr,
        )
        raise SystemExit(2)
    if args == ["install"]:
        print(f"{install()}: robomimic's scripts build mjkdl's env type")
        return
    script = args[0].removesuffix(".py")
    register()
    sys.argv = [f"robomimic/scripts/{script}.py", *args[1:]]
    watched, stderr = _Watched(sys.stdout), sys.stderr  # robomimic's logger replaces both
    sys.stdout = watched
    try:
        runpy.run_module(f"robomimic.scripts.{script}", run_name="__main__", alter_sys=True)
    except ImportError as err:
        if err.name == f"robomimic.scripts.{script}":
            print(f"error: robomimic has no script {script!r}", file=sys.stderr)
            raise SystemExit(2) from None
        raise
    finally:
        sys.stdout, sys.stderr = watched.out, stderr
    if watched.failed:
        print(f"error: robomimic's {script}.py reported a failed run (above)", file=stderr)
        raise SystemExit(1)


if __name__ == "__main__":
    main()
