"""A policy trained with robomimic (BC, BC-RNN, ...) acting in an mjkdl task: `--policy
robomimic:CKPT` (CKPT: a `model_epoch_*.pth` checkpoint that robomimic's `train.py` saved).

The policy is robomimic's own `RolloutPolicy` (`policy_from_checkpoint`: the trained networks
with the observation normalisation of its training run); it sees the observation keys it was
trained on, as the task env gives them, camera frames processed the way `EnvMjkdl` gives them
to robomimic's rollouts (channel-first, in [0, 1]). Needs robomimic 0.3 in the environment
(`mjkdl.demos.robomimic`)."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from .policy import PolicyError, register_source

PREFIX = "robomimic:"


class RobomimicPolicy:
    """`policy(obs) -> action` of a saved robomimic checkpoint; `reset()` starts an episode
    (robomimic's `start_episode`: a recurrent policy's hidden state is cleared)."""

    def __init__(self, path: str | Path, env: gym.Env) -> None:
        try:
            import robomimic.utils.file_utils as file_utils
            import robomimic.utils.obs_utils as obs_utils
            import torch

            from . import robomimic as _  # noqa: F401  (torchvision before any EGL context)
        except Exception as err:  # absent, or without torch/torchvision
            raise PolicyError(
                f"--policy robomimic:{path} needs robomimic 0.3 with torch and torchvision "
                f"(pip install robomimic==0.3.0): {err}"
            ) from None
        ckpt = Path(path)
        if not ckpt.is_file():
            raise PolicyError(
                f"--policy robomimic:{path}: no such checkpoint; give a model_epoch_*.pth that "
                "robomimic's train.py saved (RUN/models/)"
            )
        try:
            policy, data = file_utils.policy_from_checkpoint(
                ckpt_path=str(ckpt), device=torch.device("cpu")
            )
        except Exception as err:  # not a checkpoint, or one of another robomimic
            raise PolicyError(
                f"--policy robomimic:{path}: not a robomimic checkpoint: {err}"
            ) from None
        self._policy, self._process = policy, obs_utils.process_obs
        self._modality = dict(obs_utils.OBS_KEYS_TO_MODALITIES or {})
        shapes = data["shape_metadata"]["all_shapes"]
        space: Any = env.observation_space
        have = list(getattr(space, "spaces", {}))
        missing = [k for k in shapes if k not in have]
        if missing:
            raise PolicyError(
                f"robomimic:{path} looks at {', '.join(missing)}, which this env does not "
                f"observe (it has {', '.join(have)}): build it with the --env-kwargs the "
                "demos were recorded with"
            )
        for key, shape in shapes.items():
            own = tuple(space[key].shape)
            if self._modality.get(key) in ("rgb", "depth"):
                own = (own[-1], *own[:-1])  # robomimic's networks take channels first
            if own != tuple(shape):
                raise PolicyError(
                    f"robomimic:{path} takes {key} of shape {tuple(shape)}; this env gives "
                    f"{tuple(space[key].shape)}: build it with the --env-kwargs the demos were "
                    "recorded with"
                )
        self._keys = list(shapes)

    def observation(self, obs: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        """The policy's observation keys of `obs`, as robomimic's rollouts give them."""
        out = {}
        for key in self._keys:
            value = np.array(obs[key])
            if self._modality.get(key) in ("rgb", "depth"):
                value = self._process(obs=value, obs_key=key)
            out[key] = value
        return out

    def __call__(self, obs: Mapping[str, np.ndarray]) -> np.ndarray:
        return np.asarray(self._policy(ob=self.observation(obs)), dtype=np.float32)

    def reset(self) -> None:
        self._policy.start_episode()


def robomimic_policy(source: str, env: gym.Env) -> RobomimicPolicy:
    """The `RobomimicPolicy` that `robomimic:CKPT` names."""
    return RobomimicPolicy(source.removeprefix(PREFIX), env)


register_source("robomimic", robomimic_policy)
