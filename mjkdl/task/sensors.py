"""Observation sources of a task: the arms' state, cameras, body poses and user sensors.

Each source is bound to the compiled model once and then copies MuJoCo's numbers into arrays
allocated at binding, so reading a step's observation allocates nothing but what the caller
returns. Everything is of the state the step reached: poses, velocities, images, contacts and
forces (joint torques, F/T wrenches) as `mj_forward` computes them there (see `TaskEnv.step`).
"""

from __future__ import annotations

import abc
import math
from collections.abc import Callable
from typing import TYPE_CHECKING

import mujoco
import numpy as np
from gymnasium import spaces

from ..compile import euler_quat, vector
from ..errors import SpecError, unknown_name
from ..names import find_id, model_id
from ..record import check_offscreen_size
from ..spec import ToolFrameSpec
from ..validate import flag, real, text
from ._check import integer, names
from .spec import ArmSpec, BodyPoseSensor, CameraSensor, ContactSensor, RelativePositionSensor

if TYPE_CHECKING:
    from ..control import Gripper
    from ..robot import Robot

_INF = np.inf


class Reader(abc.ABC):
    """A bound observation source: `spaces` by name, `read()` fills `buffers` in place."""

    def __init__(self, boxes: dict[str, spaces.Box]) -> None:
        self.spaces = boxes
        self.buffers = {k: np.zeros(b.shape, dtype=b.dtype) for k, b in boxes.items()}

    @abc.abstractmethod
    def read(self) -> None:
        """Copy the current values into `buffers`."""


def _box(
    shape: tuple[int, ...], low: float = -_INF, high: float = _INF, dtype: type = np.float64
) -> spaces.Box:
    return spaces.Box(low=low, high=high, shape=shape, dtype=dtype)


def _frame_id(model: mujoco.MjModel, name: str, where: str) -> tuple[mujoco.mjtObj, int]:
    """A site, else a body, called `name`: (`mjOBJ_SITE` or `mjOBJ_XBODY`, id)."""
    site = find_id(model, mujoco.mjtObj.mjOBJ_SITE, name)
    if site >= 0:
        return mujoco.mjtObj.mjOBJ_SITE, site
    body = model_id(model, mujoco.mjtObj.mjOBJ_BODY, "site or body", name, where)
    return mujoco.mjtObj.mjOBJ_XBODY, body


def _frame_views(data: mujoco.MjData, kind: mujoco.mjtObj, i: int) -> tuple[np.ndarray, np.ndarray]:
    """Views (position (3,), rotation (3, 3)) of a site's or body's world frame."""
    if kind == mujoco.mjtObj.mjOBJ_SITE:
        return data.site_xpos[i], data.site_xmat[i].reshape(3, 3)
    return data.xpos[i], data.xmat[i].reshape(3, 3)


class ArmReader(Reader):
    """`{arm}_joint_pos/_joint_vel/_joint_torques/_tcp_pos/_tcp_quat/_tcp_vel`, the gripper's
    opening and the tool's wrench(es), read from MuJoCo's data.

    The TCP is the tool's `tcp_site` (or the tip body) offset by `tcp_pos`/`tcp_euler`, as in
    `Robot.fk_frame`; its velocity is `[v, w]` relative to the world, expressed along the axes
    of the arm's control frame (the world when it has none), as the Cartesian action is.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        data: mujoco.MjData,
        arm: ArmSpec,
        robot: Robot,
        gripper: Gripper | None,
        where: str,
    ) -> None:
        n, p = robot.n_joints, arm.name
        tool = arm.tool if arm.tool is not None else ToolFrameSpec()
        boxes = {
            f"{p}_joint_pos": _box((n,)),
            f"{p}_joint_vel": _box((n,)),
            f"{p}_joint_torques": _box((n,)),
            f"{p}_tcp_pos": _box((3,)),
            f"{p}_tcp_quat": _box((4,), -1.0, 1.0),
            f"{p}_tcp_vel": _box((6,)),
        }
        if gripper is not None:
            boxes[f"{p}_gripper"] = _box((1,), 0.0, 1.0)
        ft = tool.ft_sensors
        for s in ft:
            boxes[f"{p}_wrench" if len(ft) == 1 else f"{p}_{s.name}_wrench"] = _box((6,))
        super().__init__(boxes)
        self.arm = p
        self._data, self._model = data, model
        self._gripper = gripper
        b = self.buffers
        self._pos, self._vel, self._trq = (b[f"{p}_joint_{k}"] for k in ("pos", "vel", "torques"))
        self._tcp_pos, self._tcp_quat, self._tcp_vel = (
            b[f"{p}_tcp_{k}"] for k in ("pos", "quat", "vel")
        )
        self._grip = b.get(f"{p}_gripper")
        jids = [model.joint(name).id for name in robot.joint_names]
        self._qadr = model.jnt_qposadr[jids].astype(np.intp)
        self._dadr = model.jnt_dofadr[jids].astype(np.intp)

        # The TCP's reference frame; `robot` resolved these names when it was created.
        if tool.tcp_site:
            self._ref_kind = mujoco.mjtObj.mjOBJ_SITE
            ref = find_id(model, mujoco.mjtObj.mjOBJ_SITE, arm.prefix + tool.tcp_site)
        else:
            self._ref_kind = mujoco.mjtObj.mjOBJ_XBODY
            ref = find_id(model, mujoco.mjtObj.mjOBJ_BODY, arm.prefix + arm.tip_body)
        self._ref = ref
        self._ref_pos, self._ref_mat = _frame_views(data, self._ref_kind, ref)
        self._off_pos = vector(tool.tcp_pos, 3, f"{where}.tool.tcp_pos")
        off_rot = np.empty(9)
        mujoco.mju_quat2Mat(off_rot, euler_quat(tool.tcp_euler, f"{where}.tool.tcp_euler"))
        self._off_rot = off_rot.reshape(3, 3)
        self._rot = np.empty((3, 3))
        self._rot_flat = self._rot.reshape(9)
        self._arm_vel = np.empty(6)  # [w, v] at the reference frame's origin, world axes
        self._lever = np.empty(3)
        self._cross = np.empty(3)
        self._lin = np.empty(3)
        if arm.control_frame:
            kind, cf = _frame_id(model, arm.control_frame, f"{where}.control_frame")
            self._cf_mat: np.ndarray | None = _frame_views(data, kind, cf)[1].reshape(9)
        else:
            self._cf_mat = None
        self._wrench = []
        for s in ft:
            key = f"{p}_wrench" if len(ft) == 1 else f"{p}_{s.name}_wrench"
            views = []
            for name in (s.force_sensor, s.torque_sensor):
                i = model_id(
                    model,
                    mujoco.mjtObj.mjOBJ_SENSOR,
                    "sensor",
                    arm.prefix + name,
                    f"{where}.tool.ft_sensors[{s.name!r}]",
                )
                adr = int(model.sensor_adr[i])
                views.append(data.sensordata[adr : adr + 3])
            self._wrench.append((b[key][:3], b[key][3:], *views))

    @property
    def tcp_reference(self) -> tuple[int, int]:
        """(MuJoCo object type, id) of the TCP's reference frame: the tool's `tcp_site`
        (`mjOBJ_SITE`) or the tip body (`mjOBJ_XBODY`)."""
        return int(self._ref_kind), int(self._ref)

    @property
    def tcp_offset(self) -> tuple[np.ndarray, np.ndarray]:
        """(position (3,), rotation (3, 3)) of the TCP in its reference frame (copies)."""
        return self._off_pos.copy(), self._off_rot.copy()

    @property
    def joint_addresses(self) -> tuple[np.ndarray, np.ndarray]:
        """(`qpos` addresses, `qvel` addresses) of the arm's joints, chain order (copies)."""
        return self._qadr.copy(), self._dadr.copy()

    @property
    def in_control_frame(self) -> bool:
        """Whether `{arm}_tcp_vel` is along a control frame's axes (else the world's)."""
        return self._cf_mat is not None

    def read(self) -> None:
        d = self._data
        np.take(d.qpos, self._qadr, out=self._pos)
        np.take(d.qvel, self._dadr, out=self._vel)
        np.take(d.qfrc_actuator, self._dadr, out=self._trq)
        # TCP = reference frame * offset.
        pos = self._tcp_pos
        np.dot(self._ref_mat, self._off_pos, out=pos)
        pos += self._ref_pos
        np.dot(self._ref_mat, self._off_rot, out=self._rot)
        mujoco.mju_mat2Quat(self._tcp_quat, self._rot_flat)
        # Velocity of the TCP point: that of the reference origin plus w x lever.
        mujoco.mj_objectVelocity(self._model, d, self._ref_kind, self._ref, self._arm_vel, 0)
        w = self._arm_vel[:3]
        np.subtract(pos, self._ref_pos, out=self._lever)
        mujoco.mju_cross(self._cross, w, self._lever)
        np.add(self._arm_vel[3:], self._cross, out=self._lin)
        vel = self._tcp_vel
        if self._cf_mat is None:
            vel[:3] = self._lin
            vel[3:] = w
        else:
            mujoco.mju_mulMatTVec3(vel[:3], self._cf_mat, self._lin)
            mujoco.mju_mulMatTVec3(vel[3:], self._cf_mat, w)
        if self._grip is not None and self._gripper is not None:
            self._grip[0] = self._gripper.opening()  # already clipped to [0, 1]
        for force, torque, f_view, t_view in self._wrench:
            force[:] = f_view
            torque[:] = t_view


class RelativeReader(Reader):
    """`{name}_rel`: a body's world position minus an arm's TCP position (world axes)."""

    def __init__(
        self,
        model: mujoco.MjModel,
        data: mujoco.MjData,
        s: RelativePositionSensor,
        arms: dict[str, ArmReader],
        where: str,
    ):
        body = model_id(model, mujoco.mjtObj.mjOBJ_BODY, "body", s.body, f"{where}.body")
        arm = text(s.arm, f"{where}.arm")
        if arm not in arms:
            raise unknown_name("arm", arm, arms, where=f"{where}.arm (TaskSpec.arms)")
        name = text(s.name, f"{where}.name") or s.body
        super().__init__({f"{name}_rel": _box((3,))})
        self._out = self.buffers[f"{name}_rel"]
        self._pos, self._tcp = data.xpos[body], arms[arm].buffers[f"{arm}_tcp_pos"]

    def read(self) -> None:
        """Runs after the arms' readers, whose TCP positions it reads."""
        np.subtract(self._pos, self._tcp, out=self._out)


class PoseReader(Reader):
    """`{name}_pose`: a body's world position and quaternion."""

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData, s: BodyPoseSensor, where: str):
        body = model_id(model, mujoco.mjtObj.mjOBJ_BODY, "body", s.body, f"{where}.body")
        name = text(s.name, f"{where}.name") or s.body
        super().__init__({f"{name}_pose": _box((7,))})
        self._out = self.buffers[f"{name}_pose"]
        self._pos, self._quat = data.xpos[body], data.xquat[body]

    def read(self) -> None:
        self._out[:3] = self._pos
        self._out[3:] = self._quat


def intrinsics(fovy_deg: float, width: int, height: int) -> np.ndarray:
    """Pinhole matrix of a MuJoCo camera rendered at `width`x`height`.

    MuJoCo's `fovy` is the vertical field of view and pixels are square, so
    fx = fy = (height / 2) / tan(fovy / 2). Pixel centres sit at integer coordinates (OpenCV's
    convention), so the principal point is ((width - 1) / 2, (height - 1) / 2); the matrix maps
    camera-frame points with x right, y down, z forward (MuJoCo's camera looks along its -z,
    with y up).
    """
    fovy = real(fovy_deg, "intrinsics: fovy_deg")
    if not 0.0 < fovy < 180.0:
        raise SpecError(f"intrinsics: fovy_deg must lie in (0, 180) degrees, got {fovy_deg!r}")
    width, height = (
        integer(width, "intrinsics: width"),
        integer(height, "intrinsics: height"),
    )
    f = 0.5 * height / math.tan(math.radians(fovy_deg) / 2.0)
    return np.array([[f, 0.0, (width - 1) / 2.0], [0.0, f, (height - 1) / 2.0], [0.0, 0.0, 1.0]])


class CameraReader(Reader):
    """`{name}_rgb`, `{name}_depth` (metres) and `{name}_intrinsics` of one camera.

    Renderers come from `renderer(width, height)`, shared by every camera of the same size
    and asked for at every frame, so the env makes its OpenGL context in the process that
    renders (after a fork, too).
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        data: mujoco.MjData,
        s: CameraSensor,
        renderer: Callable[[int, int], mujoco.Renderer],
        where: str,
    ) -> None:
        cam = model_id(model, mujoco.mjtObj.mjOBJ_CAMERA, "camera", s.camera, f"{where}.camera")
        w, h = integer(s.width, f"{where}.width"), integer(s.height, f"{where}.height")
        depth = flag(s.depth, f"{where}.depth")
        flags = (flag(s.shadows, f"{where}.shadows"), flag(s.reflections, f"{where}.reflections"))
        name = text(s.name, f"{where}.name") or s.camera
        boxes = {f"{name}_rgb": _box((h, w, 3), 0, 255, np.uint8)}
        if depth:
            boxes[f"{name}_depth"] = _box((h, w), 0.0, _INF, np.float32)
        boxes[f"{name}_intrinsics"] = _box((3, 3))
        super().__init__(boxes)
        try:
            check_offscreen_size(model, w, h)
        except SpecError as err:
            raise SpecError(f"{where}: {err}") from None
        self._renderer, self._size = renderer, (w, h)
        self._data, self._cam = data, cam
        self._flags = flags
        self._rgb = self.buffers[f"{name}_rgb"]
        self._depth = self.buffers.get(f"{name}_depth")
        self._warm = self._depth is None
        self.buffers[f"{name}_intrinsics"][:] = intrinsics(float(model.cam_fovy[cam]), w, h)

    def read(self) -> None:
        if not self._warm:
            # The first depth frame this camera renders differs from every later render of the
            # same state by one float32 step in places (EGL, measured): render it twice.
            self._warm = True
            self.read()
        r = self._renderer(*self._size)
        flags = r.scene.flags  # the renderer is shared: set this camera's look every time
        flags[mujoco.mjtRndFlag.mjRND_SHADOW], flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = (
            self._flags
        )
        r.update_scene(self._data, camera=self._cam)
        if self._depth is not None:  # the same scene, read as depth, then as colour
            r.enable_depth_rendering()
            r.render(out=self._depth)
            r.disable_depth_rendering()
        r.render(out=self._rgb)


class ContactReader(Reader):
    """`{name}_contacts`: 1.0 for each of `others` that `body` touches, else 0.0.

    A touch is a MuJoCo contact (of the state observed) at zero or negative distance
    between a geom of `body` and a geom of the other body; geoms of child bodies do not count.
    """

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData, s: ContactSensor, where: str):
        body = model_id(model, mujoco.mjtObj.mjOBJ_BODY, "body", s.body, f"{where}.body")
        others = [
            model_id(model, mujoco.mjtObj.mjOBJ_BODY, "body", name, f"{where}.others[{i}]")
            for i, name in enumerate(names(s.others, f"{where}.others"))
        ]
        if not others:
            raise SpecError(f"{where}.others must name at least one body")
        name = text(s.name, f"{where}.name") or s.body
        super().__init__({f"{name}_contacts": _box((len(others),), 0.0, 1.0)})
        self._out = self.buffers[f"{name}_contacts"]
        self._data, self._body = data, body
        self._slot = {b: i for i, b in enumerate(others)}
        self._geom_body = model.geom_bodyid

    @property
    def body(self) -> int:
        """MuJoCo id of the body whose contacts count."""
        return int(self._body)

    @property
    def others(self) -> list[int]:
        """MuJoCo ids of the bodies it may touch, in observation order."""
        return list(self._slot)

    def read(self) -> None:
        out, d = self._out, self._data
        out[:] = 0.0
        if d.ncon == 0:
            return
        con = d.contact
        pairs = self._geom_body[con.geom]
        for (a, b), dist in zip(pairs, con.dist, strict=True):
            if dist > 0.0:
                continue
            if a == self._body and b in self._slot:
                out[self._slot[b]] = 1.0
            elif b == self._body and a in self._slot:
                out[self._slot[a]] = 1.0
