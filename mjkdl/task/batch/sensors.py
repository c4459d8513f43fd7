"""A task's observations for every world at once, read from the engine's arrays.

Each source mirrors one of the CPU env's bound readers (`ArmReader`, `PoseReader`,
`RelativeReader`, `ContactReader`; `CameraReader`s through `BatchCameras`), built from the
same reader and sensor spec, so the keys and shapes are the CPU env's; values are float32
tensors with the worlds first (camera RGB: uint8).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import mujoco
import torch

from ...names import model_id
from ..sensors import ArmReader, CameraReader, ContactReader, PoseReader, RelativeReader
from ..spec import CameraSensor, ContactSensor, RelativePositionSensor
from .engine import Engine, Tcp, UnsupportedFeatureError, mat_to_quat
from .warp_engine import WarpEngine

if TYPE_CHECKING:
    from ..env import TaskEnv
    from .cameras import BatchCameras

Source = Callable[[], dict[str, torch.Tensor]]


def arm_tcp(reader: ArmReader, state: Engine, model: mujoco.MjModel) -> Tcp:
    """The TCP an `ArmReader` reads, as tensors of the engine's device and dtype."""
    kind, ref = reader.tcp_reference
    site = ref if kind == mujoco.mjtObj.mjOBJ_SITE else -1
    body = int(model.site_bodyid[site]) if site >= 0 else ref
    device, dtype = state.device, state.dtype
    pos, rot = reader.tcp_offset
    return Tcp(
        site=site,
        body=body,
        offset=torch.as_tensor(pos, device=device, dtype=dtype),
        rotation=torch.as_tensor(rot, device=device, dtype=dtype),
    )


class BatchObserver:
    """Reads every observation of the CPU env `host` (hidden ones too) for all worlds."""

    def __init__(self, host: TaskEnv, state: Engine) -> None:
        model = host.scene.model
        self._state = state
        self.tcps: dict[str, Tcp] = {}
        self._sources: list[Source] = []
        readers = host.readers
        n_arms = len(host.task_spec.arms)
        for arm, reader, eff in zip(
            host.task_spec.arms, readers[:n_arms], host.effectors, strict=True
        ):
            assert isinstance(reader, ArmReader)
            tcp = arm_tcp(reader, state, model)
            self.tcps[arm.name] = tcp
            self._sources.append(self._arm(reader, tcp, eff, model))
        cameras: list[tuple[CameraSensor, CameraReader, str]] = []
        for i, (sensor, reader) in enumerate(
            zip(host.task_spec.sensors, readers[n_arms:], strict=True)
        ):
            where = f"TaskSpec.sensors[{i}]"
            if isinstance(reader, CameraReader):
                assert isinstance(sensor, CameraSensor)
                cameras.append((sensor, reader, where))
            else:
                self._sources.append(self._sensor(sensor, reader, model, where))
        self.cameras: BatchCameras | None = None
        if cameras:
            if not isinstance(state, WarpEngine):
                raise UnsupportedFeatureError(
                    f"{cameras[0][2]} (CameraSensor): the {state.name!r} engine renders no "
                    "cameras; make_batch(..., engine='warp') renders them (MuJoCo Warp), or "
                    "use the CPU env"
                )
            from .cameras import BatchCameras

            self.cameras = BatchCameras(cameras, model, state)
            self._sources.append(self.cameras.read)

    def read(self) -> dict[str, torch.Tensor]:
        """Every observation, by name, in the CPU env's order (`time` last)."""
        out: dict[str, torch.Tensor] = {}
        for source in self._sources:
            out.update(source())
        out["time"] = self._state.time.reshape(-1, 1).clone()  # not the engine's live array
        return out

    def _arm(self, reader: ArmReader, tcp: Tcp, eff: object, model: mujoco.MjModel) -> Source:
        s, p = self._state, reader.arm
        dev = s.device
        qadr, dadr = (torch.as_tensor(a, device=dev) for a in reader.joint_addresses)
        cf = reader.in_control_frame
        cf_rot: Callable[[], torch.Tensor] | None = None
        if cf:
            arm = eff.arm  # type: ignore[attr-defined]
            site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, arm.control_frame)
            if site >= 0:
                cf_rot = lambda: s.site_xmat[:, site]  # noqa: E731
            else:
                body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, arm.control_frame)
                cf_rot = lambda: s.xmat[:, body]  # noqa: E731
        grip = eff.gripper  # type: ignore[attr-defined]
        grip_range = None
        if grip is not None:
            grip_range = (grip.actuator_id, *grip.length_range)
        for key in reader.buffers:
            if key.endswith("_wrench"):
                raise UnsupportedFeatureError(
                    f"observation {key!r}: F/T sensors are not read by the batched backend yet; "
                    "leave the tool's ft_sensors out or use the CPU env"
                )

        def read() -> dict[str, torch.Tensor]:
            pos = s.tcp_pos(tcp)
            vel = s.tcp_vel(tcp, pos)
            if cf_rot is not None:
                rot_t = cf_rot().transpose(1, 2)
                vel = torch.cat(
                    [(rot_t @ vel[:, :3, None])[..., 0], (rot_t @ vel[:, 3:, None])[..., 0]], 1
                )
            out = {
                f"{p}_joint_pos": s.qpos[:, qadr],
                f"{p}_joint_vel": s.qvel[:, dadr],
                f"{p}_joint_torques": s.qfrc_actuator[:, dadr],
                f"{p}_tcp_pos": pos,
                f"{p}_tcp_quat": mat_to_quat(s.tcp_rot(tcp)),
                f"{p}_tcp_vel": vel,
            }
            if grip_range is not None:
                gid, closed, open_ = grip_range
                length = s.actuator_length[:, gid : gid + 1]
                out[f"{p}_gripper"] = torch.clamp((length - closed) / (open_ - closed), 0.0, 1.0)
            return out

        return read

    def _sensor(self, sensor: object, reader: object, model: mujoco.MjModel, where: str) -> Source:
        s = self._state
        if isinstance(reader, PoseReader):
            (key,) = reader.buffers
            body = model_id(model, mujoco.mjtObj.mjOBJ_BODY, "body", sensor.body, where)  # type: ignore[attr-defined]
            return lambda: {key: torch.cat([s.xpos[:, body], s.xquat[:, body]], 1)}
        if isinstance(reader, RelativeReader):
            assert isinstance(sensor, RelativePositionSensor)
            (key,) = reader.buffers
            body = model_id(model, mujoco.mjtObj.mjOBJ_BODY, "body", sensor.body, where)
            tcp = self.tcps[sensor.arm]
            return lambda: {key: s.xpos[:, body] - s.tcp_pos(tcp)}
        if isinstance(reader, ContactReader):
            assert isinstance(sensor, ContactSensor)
            return self._contacts(sensor, reader, model, where)
        raise UnsupportedFeatureError(
            f"{where} ({type(sensor).__name__}): the batched backend reads arms, "
            "BodyPoseSensor, RelativePositionSensor, ContactSensor and CameraSensor; user "
            "Sensors are CPU-env only for now"
        )

    def _contacts(
        self, sensor: ContactSensor, reader: ContactReader, model: mujoco.MjModel, where: str
    ) -> Source:
        s = self._state
        (key,) = reader.buffers
        dev = s.device
        body, others = reader.body, reader.others
        # slot[b] = index of body b among `others`, -1 for the rest.
        slot = torch.full((model.nbody,), -1, dtype=torch.long, device=dev)
        for i, b in enumerate(others):
            slot[b] = i
        geom_body = torch.as_tensor(model.geom_bodyid, device=dev, dtype=torch.long)
        k = len(others)

        def read() -> dict[str, torch.Tensor]:
            out = torch.zeros(s.nworld * k, device=dev, dtype=s.dtype)
            world, g1, g2 = s.contacts(body, others)
            b1, b2 = geom_body[g1.long()], geom_body[g2.long()]
            world = world.long()
            for mine, other in ((b1, b2), (b2, b1)):
                idx = slot[other]
                hit = (mine == body) & (idx >= 0)
                out[world[hit] * k + idx[hit]] = 1.0
            return {key: out.reshape(s.nworld, k)}

        return read
