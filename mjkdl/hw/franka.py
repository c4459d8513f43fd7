"""A Franka arm at an address, as a `Robot`: the same ports, modes and kinematics.

`FrankaArm("172.16.0.2")` connects through the vendor client (pylibfranka) and builds a
MuJoCo twin of the arm (Menagerie's Panda, a 1 ms timestep: one tick of the arm's control
interface) mirrored from the arm (`in_the_loop`). Its ports are those of the twin's `Robot`,
with the same semantics: `update()` reads the measured state (`jnt_pos_msr`, `jnt_vel_msr`,
`jnt_trq_msr` = the arm's measured joint torques tau_J; always the arm's latest state, also
after a stall of the user's loop), the command port of `ctrl_mode` is
sent by `step()`, which returns once the arm's clock advanced one tick, and every kinematics
and dynamics method (`fk_frame`, `jacobian`, `mass_matrix`, `gravity_torques`, `ik`, ...)
works on the measured state. `ext_trq_msr` and `ext_wrench_msr` are the arm's estimates of
the external torques and of the wrench at its end effector.

`fk_frame()` is the hand body's frame (Menagerie's `hand`, mjkdl's tip; the TCP when `tool`
sets one); libfranka's frames differ: the flange F is the hand turned +45° about z, and
`O_T_EE` (the hand's TCP between the fingertips, libfranka's default F_T_EE) lies 0.1034 m
out along the hand's z.
`frame(name)` gives each of them by name (`FRAMES`).

The 1 kHz loop itself runs in a process of its own (`connection`), rate-limited and guarded
by a watchdog; `close()` (or leaving a `with` block, or Ctrl+C) brings the arm to rest.
"""

from __future__ import annotations

from types import TracebackType
from typing import Any

import numpy as np
import pinocchio as pin

from .. import menagerie
from ..errors import SpecError
from ..robot import Robot
from ..scene import Env
from ..spec import RobotSpec, SceneSpec, ToolFrameSpec
from ..validate import vector
from .franka_sim.scene import HAND_TCP
from .in_the_loop import ArmLink

# libfranka's frames as placements in the hand body's frame (what `fk_frame()` gives).
FRAMES: dict[str, pin.SE3] = {
    "hand": pin.SE3.Identity(),
    "flange": pin.SE3(pin.utils.rotate("z", np.pi / 4), np.zeros(3)),
    "O_T_EE": pin.SE3(np.eye(3), np.array([0.0, 0.0, HAND_TCP])),
}

# What the handle forwards to its twin Robot for writing (reading forwards everything).
_WRITABLE = frozenset(
    {
        "jnt_pos_cmd",
        "jnt_vel_cmd",
        "jnt_trq_cmd",
        "ctrl_mode",
        "gravity_compensation",
        "gravity_feedforward",
    }
)


def arm_scene(timestep: float = 0.001) -> SceneSpec:
    """The twin: Menagerie's Panda with its hand, nothing else, one arm tick per timestep."""
    return SceneSpec(
        timestep=timestep,
        add_floor=False,
        add_skybox=False,
        robots=[RobotSpec(path=menagerie.model_path("franka_emika_panda"))],
    )


class FrankaArm:
    """The `Robot` ports and methods of the Franka arm at `robot_ip` (see the module doc).

    `model` picks the limits the commands are held to ("panda" or "fr3") and the client it
    is driven through (`client`: "pylibfranka" for FR3, "panda-py" for Panda); `watchdog` is how
    long (s) the arm keeps executing the last command when no new one comes before the
    watchdog brings it to rest; `realtime=True` asks libfranka for real-time scheduling (a
    PREEMPT_RT kernel), as a real arm wants; `collision_thresholds` (torque N·m, force N) set
    the robot's collision reflexes (None: the robot's own).
    """

    robot: Robot
    scene: Env
    link: ArmLink
    _frame_data: pin.Data

    def __init__(
        self,
        robot_ip: str,
        model: str = "panda",
        *,
        tool: ToolFrameSpec | None = None,
        client: str | None = None,
        watchdog: float = 0.2,
        realtime: bool = False,
        collision_thresholds: tuple[float, float] | None = None,
    ) -> None:
        if model not in ("panda", "fr3"):
            raise SpecError(f"model must be 'panda' or 'fr3', got {model!r}")
        scene = Env.build(arm_scene())
        try:
            robot = scene.create_robot("link0", "hand", tool=tool)
            link = ArmLink(
                scene,
                robot,
                robot_ip,
                model=model,
                client=client,
                watchdog=watchdog,
                realtime=realtime,
                collision_thresholds=collision_thresholds,
            )
        except BaseException:
            scene.close()
            raise
        object.__setattr__(self, "scene", scene)
        object.__setattr__(self, "robot", robot)
        object.__setattr__(self, "link", link)
        object.__setattr__(self, "_frame_data", robot.model.createData())
        robot.update()

    def __getattr__(self, name: str) -> Any:  # the Robot's ports and methods
        if name.startswith("__"):
            raise AttributeError(name)
        return getattr(self.__dict__["robot"], name)

    def __setattr__(self, name: str, value: Any) -> None:
        if name not in _WRITABLE:
            raise AttributeError(f"FrankaArm has no writable attribute {name!r}")
        setattr(self.robot, name, value)

    def update(self) -> None:
        """Read the arm's latest measured state into the ports (raises a fault the loop
        reported, warns `WatchdogWarning` after a stall), then apply the command ports."""
        self.link.refresh()
        self.robot.update()

    def frame(self, name: str, q: np.ndarray | None = None) -> pin.SE3:
        """World pose of a frame libfranka names (`FRAMES`: "hand", "flange", "O_T_EE") at the
        joint positions `q` (the measured ones when None)."""
        offset = FRAMES.get(name) if isinstance(name, str) else None
        if offset is None:
            raise SpecError(f"frame: no frame {name!r}; FrankaArm names {sorted(FRAMES)}")
        robot = self.robot
        full = robot.q.copy()
        if q is not None:
            full[robot.arm_q] = vector(q, 7, "frame: q")
        model = robot.model
        data = self._frame_data
        pin.framesForwardKinematics(model, data, full)
        return data.oMf[model.getFrameId("hand")] * offset

    @property
    def address(self) -> str:
        return self.link.address

    @property
    def ext_trq_msr(self) -> np.ndarray:
        """External joint torques the arm estimates (tau_ext_hat_filtered, N·m)."""
        return self.link.external_forces()[0]

    @property
    def ext_wrench_msr(self) -> np.ndarray:
        """External wrench at the end effector (O_F_ext_hat_K: force, torque; base frame)."""
        return self.link.external_forces()[1]

    def move_to(self, q: np.ndarray, timeout: float = 30.0) -> None:
        """Bring the arm to joint positions `q` (rate-limited); POSITION mode holds there."""
        self.link.move_to(np.asarray(q, dtype=float), timeout)
        self.robot.update()

    @property
    def closed(self) -> bool:
        return self.scene.closed

    def close(self) -> None:
        """Bring the arm to rest, finish the motion and close the connection (idempotent)."""
        if not self.scene.closed:
            self.scene.close()

    def __enter__(self) -> FrankaArm:
        return self

    def __exit__(
        self,
        kind: type[BaseException] | None,
        err: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()
