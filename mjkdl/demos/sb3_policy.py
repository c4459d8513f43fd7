"""A policy trained with Stable-Baselines3 acting in an mjkdl task: `--policy sb3:PATH.zip`
(what `model.save(PATH)` wrote; the `rl` extra).

The algorithm is read from the file: SB3 stores the policy's class, whose module names it
(`stable_baselines3.sac.policies` is SAC's; PPO's and A2C's share `common.policies`, loaded
through PPO, which predicts the same). The model acts deterministically (`predict(obs,
deterministic=True)`), once per control step, on the env's observation: as it is where the
model's observation space is the env's, flattened where the model was trained on the flattened
observation (`gymnasium.wrappers.FlattenObservation`)."""

from __future__ import annotations

import importlib
import json
import zipfile
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from .policy import Obs, PolicyError, register_source

PREFIX = "sb3:"


def algorithm_of(path: Path) -> Any:
    """The SB3 (or sb3-contrib) algorithm class that saved `path`, from its policy's module."""
    try:
        with zipfile.ZipFile(path) as z:
            data = json.loads(z.read("data"))
        module = str(data["policy_class"]["__module__"])
    except (OSError, zipfile.BadZipFile, KeyError, ValueError, TypeError) as err:
        raise PolicyError(
            f"--policy sb3:{path}: not a model Stable-Baselines3 saved (model.save(PATH) "
            f"writes PATH.zip): {err}"
        ) from None
    package, _, rest = module.partition(".")
    algo = rest.split(".")[0]
    if package == "stable_baselines3" and algo == "common":  # PPO's and A2C's: one class,
        algo = "ppo"  # and PPO loads either to predict
    try:
        lib = importlib.import_module(package)
    except ImportError as err:
        raise PolicyError(
            f"--policy sb3:{path} was saved by {package}, which does not import: {err} "
            "(pip install 'mjkdl[rl]')"
        ) from None
    from stable_baselines3.common.base_class import BaseAlgorithm

    found = [
        c
        for c in vars(lib).values()
        if isinstance(c, type)
        and issubclass(c, BaseAlgorithm)
        and c.__module__.split(".")[1:2] == [algo]
    ]
    if not found:
        raise PolicyError(
            f"--policy sb3:{path}: its policy class comes from {module}, of no algorithm "
            f"{package} exports"
        )
    return found[0]


class SB3Policy:
    """`policy(obs) -> action` of a saved Stable-Baselines3 model (deterministic)."""

    def __init__(self, path: str | Path, env: gym.Env) -> None:
        try:
            import stable_baselines3  # noqa: F401
        except ImportError as err:
            raise PolicyError(
                f"--policy sb3:{path} needs Stable-Baselines3: pip install 'mjkdl[rl]' ({err})"
            ) from None
        folder = Path(path)
        if not folder.is_file():
            raise PolicyError(f"--policy sb3:{path}: no such file")
        algo = algorithm_of(folder)
        self.algorithm = algo.__name__
        self.model: Any = algo.load(folder, device="cpu")
        self._env_space = env.observation_space
        mine = self.model.observation_space
        self._flatten = False
        if mine != self._env_space:
            flat = isinstance(mine, gym.spaces.Box) and len(mine.shape) == 1
            if not flat or gym.spaces.flatdim(self._env_space) != mine.shape[0]:
                raise PolicyError(
                    f"--policy sb3:{path} ({self.algorithm}) takes observations {mine}; this env "
                    f"gives {self._env_space}: evaluate it on the env (and keywords) it was "
                    "trained on"
                )
            self._flatten = True
        if self.model.action_space.shape != env.action_space.shape:
            raise PolicyError(
                f"--policy sb3:{path} ({self.algorithm}) acts in {self.model.action_space}; this "
                f"env takes {env.action_space}"
            )

    def __call__(self, obs: Obs) -> np.ndarray:
        x: Any = gym.spaces.flatten(self._env_space, obs) if self._flatten else dict(obs)
        action, _ = self.model.predict(x, deterministic=True)
        return np.asarray(action)


def sb3_policy(source: str, env: gym.Env) -> SB3Policy:
    """The `SB3Policy` that `sb3:PATH.zip` names."""
    return SB3Policy(source.removeprefix(PREFIX), env)


register_source("sb3", sb3_policy)
