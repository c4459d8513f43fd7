"""Teleoperation: a device drives the task's Cartesian-velocity action in the viewer, and the
episodes it saves go to an HDF5 file (appended to when it exists)."""

from __future__ import annotations

import os
import time
from collections.abc import Mapping
from typing import Any

import gymnasium as gym
import mujoco
import numpy as np

from ..errors import SpecError
from ..scene import Scene
from ..task._check import integer
from ..viewer.overlays import Text
from ..viewer.window import Window
from .devices import KEYS_HELP, Command, KeyboardDevice, SpaceMouseDevice, open_device
from .episodes import make_env, scene_of, success_of
from .hdf5 import EpisodeBuffer, EpisodeWriter

__all__ = ["KEYS_HELP", "Teleop", "teleop"]

_FONT = int(mujoco.mjtFontScale.mjFONTSCALE_150)
_TOPLEFT = int(mujoco.mjtGridPos.mjGRID_TOPLEFT)


class Teleop:
    """One teleoperation session: env, device, window and writer, stepped at the control rate.

    The action is the device's twist times `speed` mapped onto the action space's twist
    entries (6 first, as the registered tasks order them), and the gripper entry at its high
    bound when closed, its low bound when open (both conventions, `[0, 1]` and `[-1, 1]`,
    close towards the high bound).
    """

    def __init__(
        self,
        env: gym.Env,
        device: KeyboardDevice | SpaceMouseDevice,
        writer: EpisodeWriter,
        *,
        seed: int = 0,
        speed: float = 1.0,
    ) -> None:
        space = env.action_space
        if not isinstance(space, gym.spaces.Box) or space.shape is None or space.shape[0] != 7:
            raise SpecError(
                f"teleop drives a Cartesian-velocity arm with a gripper (7 actions), "
                f"this env's action space is {space}"
            )
        if not 0.0 < speed <= 1.0:
            raise SpecError(f"--speed must be in (0, 1], got {speed!r}")
        self.env, self.device, self.writer = env, device, writer
        self.seed, self.speed = seed, speed
        self._low = space.low.astype(np.float64)
        self._high = space.high.astype(np.float64)
        self._action = np.zeros(7, dtype=space.dtype)
        self._closed_gripper = False
        self._last_success = False
        self.saved = 0
        self._scene = scene_of(env)
        self._buffer = EpisodeBuffer(self._scene)
        self._obs: dict[str, np.ndarray] = {}
        self._status = ""

    @property
    def scene(self) -> Scene:
        """The mjkdl scene the session records."""
        return self._scene

    def action(self, twist: np.ndarray) -> np.ndarray:
        """The env action for a device twist in [-1, 1]^6 and the gripper state."""
        mid = (self._low + self._high) / 2
        half = (self._high - self._low) / 2
        a = self._action
        a[:6] = mid[:6] + self.speed * np.clip(twist, -1, 1) * half[:6]
        a[6] = self._high[6] if self._closed_gripper else self._low[6]
        return a

    def start(self) -> None:
        """Reset to the current seed (the next one the file does not hold) with a fresh
        buffer and the gripper open."""
        held = set(self.writer.seeds)
        while self.seed in held:
            self.seed += 1
        self._obs, _ = self.env.reset(seed=self.seed)
        self._buffer = EpisodeBuffer(self._scene)
        self._closed_gripper = self._last_success = False

    def _save(self, success: bool) -> None:
        if self._buffer.actions:
            self.writer.write(self._buffer.finish(self.seed, success))
            self.saved += 1
            self._status = f"saved demo {self.saved} (seed {self.seed})"
        self.seed += 1
        self.start()

    def tick(self) -> None:
        """One control period: read the device, act, record, handle its commands."""
        reading = self.device.read()
        for command in reading.commands:
            if command is Command.GRIPPER:
                self._closed_gripper = not self._closed_gripper
            elif command is Command.SAVE:
                return self._save(success=self._last_success)
            elif command is Command.DISCARD:
                self._status = f"discarded (seed {self.seed})"
                return self.start()
            elif command is Command.RESET:
                self._status = f"dropped seed {self.seed}"
                self.seed += 1
                return self.start()
        action = self.action(reading.twist)
        self._buffer.before_step(self._obs)
        self._obs, reward, terminated, truncated, info = self.env.step(action)
        done = bool(terminated or truncated)
        self._buffer.after_step(action, float(reward), done, self._obs)
        self._last_success = success_of(info)
        if done:
            if self._last_success:
                return self._save(success=True)
            self._status = f"seed {self.seed} ended unsuccessful: discarded"
            self.seed += 1
            self.start()
        return None

    def texts(self) -> list[Text]:
        """The overlay: keys, mode, gripper, seed, demos saved."""
        mode = getattr(self.device, "mode", "cap")
        rows = [
            ("device", f"{self.device.name} ({mode})"),
            ("gripper", "closed" if self._closed_gripper else "open"),
            ("seed", str(self.seed)),
            ("saved", f"{self.saved} demos to {self.writer.path.name}"),
            ("", self._status),
        ]
        keys = [ln[2:] for ln in KEYS_HELP.splitlines() if ln.startswith("  ")]
        left = "\n".join([r[0] for r in rows] + [""] + [k[:8].strip() for k in keys])
        right = "\n".join([r[1] for r in rows] + [""] + [k[8:].strip() for k in keys])
        return [(_FONT, _TOPLEFT, left, right)]


def teleop(
    env_id: str,
    out: str | os.PathLike[str],
    *,
    device: str = "keyboard",
    seed: int | None = None,
    env_kwargs: Mapping[str, Any] | None = None,
    speed: float = 1.0,
    deadzone: float = 0.1,
    demos: int | None = None,
) -> int:
    """Open the viewer on `env_id` and record what the device does until the window is
    closed (or `demos` demos are saved); the number of demos saved. Episodes start at `seed`
    (default: after the file's last seed) and skip the seeds the file holds."""
    if seed is not None:
        seed = integer(seed, "--seed", least=0)
    if demos is not None:
        demos = integer(demos, "--demos")
    kwargs = dict(env_kwargs or {})
    dev = open_device(device, deadzone)
    env = make_env(env_id, kwargs)
    try:
        with EpisodeWriter(out, env_id, kwargs, append=True) as writer:
            first = writer.next_seed if seed is None else seed
            session = Teleop(env, dev, writer, seed=first, speed=speed)
            session.start()
            scene = session.scene
            window = Window.launch(scene.model, scene.data, dev.on_key)
            period = float(getattr(env.unwrapped, "control_timestep", 0.1))
            try:
                next_tick = time.perf_counter()
                while window.is_running() and (demos is None or session.saved < demos):
                    session.tick()
                    window.sync(full=True)
                    window.show(session.texts(), [])
                    next_tick += period
                    time.sleep(max(0.0, next_tick - time.perf_counter()))
            finally:
                window.close()
            return session.saved
    finally:
        dev.close()
        env.close()
