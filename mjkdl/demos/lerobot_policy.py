"""A policy trained with LeRobot (ACT, diffusion, ...) acting in an mjkdl task: `--policy
lerobot:PATH` (PATH: a `pretrained_model` folder that `lerobot-train` saved).

The observation reaches the policy as the export wrote it (`mjkdl.demos.lerobot`):
`observation.state` the same keys in the same order (those its dataset's `meta/info.json`
names, where it is on this machine; else the robot's proprioception, or what `state_keys`
names), `observation.images.<camera>` each `<camera>_rgb` frame as a
channel-first float image in [0, 1], what LeRobot's loader gives for a video frame. The policy's
own saved pre- and post-processors (normalisation) run around it, as in `lerobot-eval`.

The policy acts at its dataset's rate (`lerobot_fps`: the fps of the dataset it was trained on,
which `evaluate` makes the env's control period). Action chunks are LeRobot's to execute: one
`select_action` per control step, and `reset()` at each episode's start, which clears the
policy's queues, so ACT runs as its config says (`execution`): temporal ensembling where
`temporal_ensemble_coeff` is set, otherwise chunks of `n_action_steps` actions."""

from __future__ import annotations

import json
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from .lerobot import observation_keys, proprioception
from .policy import PolicyError, register_source

PREFIX = "lerobot:"


class LeRobotPolicy:
    """`policy(obs) -> action` of a saved LeRobot policy; `reset()` clears its action queue."""

    def __init__(
        self, path: str | Path, env: gym.Env, state_keys: Sequence[str] | None = None
    ) -> None:
        try:
            import torch
            from lerobot.configs.policies import PreTrainedConfig
            from lerobot.policies.factory import get_policy_class, make_pre_post_processors
        except Exception as err:  # absent, or beside a torch it was not built for
            raise PolicyError(
                f"--policy lerobot:{path} needs lerobot 0.4 (pip install 'mjkdl[lerobot]', in "
                f"an environment of its own: it pins torch < 2.11): {err}"
            ) from None
        folder = Path(path)
        if not (folder / "config.json").is_file():
            raise PolicyError(
                f"--policy lerobot:{path}: no config.json there; give the pretrained_model "
                "folder lerobot-train saved (outputs/.../checkpoints/last/pretrained_model)"
            )
        self._torch = torch
        config = PreTrainedConfig.from_pretrained(folder)
        config.device = "cpu" if not torch.cuda.is_available() else config.device
        self._policy = get_policy_class(config.type).from_pretrained(folder, config=config)
        self._policy.eval()
        self._pre, self._post = make_pre_post_processors(
            policy_cfg=config,
            pretrained_path=str(folder),
            preprocessor_overrides={"device_processor": {"device": str(config.device)}},
        )
        features = config.input_features
        obs, _ = env.reset()
        every, cams = observation_keys(obs, leading=0)
        exported = _exported_state_keys(folder) if state_keys is None else None
        if exported is not None:  # the dataset's own keys: an env in the loop has more
            missing = [k for k in exported if k not in every]
            if missing:
                raise PolicyError(
                    f"lerobot:{path} was trained on observations {missing} that this env "
                    f"does not give (it gives {', '.join(every)})"
                )
            self._state = exported
        elif state_keys is None:
            spec = getattr(env.unwrapped, "task_spec", None)
            arms = [f"{a.name}_" for a in getattr(spec, "arms", [])]
            self._state = proprioception(every, arms)
        else:
            missing = [k for k in state_keys if k not in every]
            if missing:
                raise PolicyError(f"--state-keys {missing} are not observations of this env")
            self._state = [k for k in every if k in state_keys]
        self._cams = {}
        for key in features:
            if key.startswith("observation.images."):
                cam = key.removeprefix("observation.images.") + "_rgb"
                if cam not in cams:
                    raise PolicyError(
                        f"lerobot:{path} looks at {key}; this env has no {cam} observation "
                        f"(it has {', '.join(cams) or 'no cameras'}): build it with "
                        "--env-kwargs '{\"camera_names\": [...]}' as the demos were recorded"
                    )
                self._cams[key] = cam
        if "observation.state" in features:
            want = int(features["observation.state"].shape[0])
            have = sum(int(np.prod(obs[k].shape)) for k in self._state)
            if want != have:
                raise PolicyError(
                    f"lerobot:{path} takes an observation.state of {want} numbers; "
                    f"{', '.join(self._state)} give {have}: pass the --state-keys the "
                    "export used"
                )
        else:
            self._state = []

    def batch(self, obs: Mapping[str, np.ndarray]) -> dict[str, Any]:
        """The observation as LeRobot's batch of one (before the policy's preprocessor)."""
        torch = self._torch
        out: dict[str, Any] = {}
        if self._state:
            vec = np.concatenate([np.asarray(obs[k], np.float32).ravel() for k in self._state])
            out["observation.state"] = torch.from_numpy(vec)[None]
        for key, cam in self._cams.items():
            img = torch.from_numpy(np.ascontiguousarray(obs[cam])).permute(2, 0, 1)
            out[key] = (img.float() / 255.0)[None]
        return out

    def __call__(self, obs: Mapping[str, np.ndarray]) -> np.ndarray:
        with self._torch.inference_mode():
            action = self._policy.select_action(self._pre(self.batch(obs)))
        return np.asarray(self._post(action).cpu().numpy()[0], dtype=np.float32)

    def reset(self) -> None:
        self._policy.reset()

    @property
    def execution(self) -> str:
        """How the policy's action chunks are executed, from its config (LeRobot does it)."""
        return chunk_execution(self._policy.config)


def chunk_execution(config: Any) -> str:
    """`config`'s way of executing action chunks, in words (ACT's two, diffusion's queue)."""
    coeff = getattr(config, "temporal_ensemble_coeff", None)
    chunk = getattr(config, "chunk_size", getattr(config, "horizon", None))
    if coeff is not None:
        return f"temporal ensembling (coefficient {coeff:g}, chunks of {chunk})"
    steps = getattr(config, "n_action_steps", None)
    if steps is None:
        return "one action per call"
    return f"chunk-wise: {steps} actions of each chunk of {chunk}, then a new chunk"


def _training(folder: Path) -> tuple[dict[str, Any], dict[str, Any]]:
    """(the `train_config.json` lerobot-train saved beside the policy, its dataset's
    `meta/info.json`), each {} where it is not there."""
    try:
        train = json.loads((folder / "train_config.json").read_text())
    except (OSError, ValueError):
        return {}, {}
    dataset = train.get("dataset") or {}
    root = dataset.get("root")
    if root is None and dataset.get("repo_id"):
        home = os.environ.get("HF_LEROBOT_HOME", "~/.cache/huggingface/lerobot")
        root = Path(home).expanduser() / dataset["repo_id"]
    if root is None:
        return train, {}
    try:
        info = json.loads((Path(root) / "meta" / "info.json").read_text())
    except (OSError, ValueError):
        return train, {}
    return train, info if isinstance(info, dict) else {}


def _exported_state_keys(folder: Path) -> list[str] | None:
    """The observation keys, in order, of the `observation.state` the policy was trained on
    (its dataset's feature names, `key` or `key.i`); None where the dataset is not here."""
    _, info = _training(folder)
    try:
        names = info["features"]["observation.state"]["names"]
    except (KeyError, TypeError):
        return None
    if not isinstance(names, list):
        return None
    keys: list[str] = []
    for name in map(str, names):
        key, _, index = name.rpartition(".")
        key = key if key and index.isdigit() else name
        if key not in keys:
            keys.append(key)
    return keys


def lerobot_fps(source: str) -> float | None:
    """The fps of the dataset the policy at `lerobot:PATH` was trained on (the
    `train_config.json` lerobot-train saved beside it: its env's fps, or its dataset's
    `meta/info.json`); None where neither is there."""
    train, info = _training(Path(source.removeprefix(PREFIX)))
    env = train.get("env") or {}
    if env.get("fps"):
        return float(env["fps"])
    try:
        return float(info["fps"])
    except (KeyError, TypeError, ValueError):
        return None


def lerobot_policy(source: str, env: gym.Env, state_keys: Sequence[str] | None = None) -> Any:
    """The `LeRobotPolicy` that `lerobot:PATH` names."""
    return LeRobotPolicy(source.removeprefix(PREFIX), env, state_keys)


register_source("lerobot", lerobot_policy, lerobot_fps)
