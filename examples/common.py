"""What the examples share: the tutorial's tabletop scene, the command line and the run loop.

Each example reads on its own; this module holds only the pieces several of them repeat:

* the scene of the tutorial: a Kinova Gen3 with a Robotiq 2F-85 on a table, a cube and a
  camera called ``task`` (`tutorial_spec`, `create_arm`);
* smooth joint-space targets (`JointMove`, `JointCycle`), the joint impedance law that
  tracks them (`impedance_torques`) and plain gravity compensation;
* `parse_args` (``--headless``, ``--duration``) and `run`, which drives one control loop either
  in the interactive viewer or headless.

Menagerie models are found as the tests find them: ``MENAGERIE_ROOT`` when set, else the
checkout next to this repository (``../shared/menagerie``) when there is one, else the
`mujoco-menagerie` package's cache (downloading once). When none has the model, the example
exits with one line saying how to point it at one.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin
from tqdm import tqdm

import mjkdl as mjk

REPO_ROOT = Path(__file__).resolve().parents[1]
_SHARED_MENAGERIE = REPO_ROOT.parent / "shared" / "menagerie"
if "MENAGERIE_ROOT" not in os.environ and _SHARED_MENAGERIE.is_dir():
    os.environ["MENAGERIE_ROOT"] = str(_SHARED_MENAGERIE)

# The Gen3's "home" keyframe, in chain order (radians).
HOME = np.array([0.0, 0.2618, 3.1416, -2.2689, 0.0, 0.9599, 1.5708])
TABLE_HEIGHT = 0.7  # the table asset has its surface at the model origin
CUBE_HALF = 0.025
CUBE_START = np.array([0.35, 0.10, TABLE_HEIGHT + CUBE_HALF])

GRIPPER_PREFIX = "g_"
GRIPPER_ACTUATOR = "fingers_actuator"  # Robotiq 2F-85: ctrl 0 (open) ... 255 (closed)
GRIPPER_OPEN = 0.0
GRIPPER_CLOSED = 255.0


# ---------------------------------------------------------------------- scene


def table() -> mjk.SceneObject:
    """The table asset, fixed, standing on the floor; its site `table_top` is the surface."""
    return mjk.SceneObject(
        name="table",
        mjcf_path=mjk.assets.path("table"),
        pos=[0.0, 0.0, TABLE_HEIGHT],
        fixed=True,
    )


def menagerie_model(name: str) -> str:
    """Path of Menagerie model `name`; when it is not available, exit with the one-line reason."""
    try:
        return mjk.menagerie.model_path(name)
    except mjk.ModelFileError as err:
        raise SystemExit(f"{Path(sys.argv[0]).name}: {err}") from None


def cube(pos: np.ndarray = CUBE_START) -> mjk.SceneObject:
    """A free 5 cm, 100 g cube with enough friction for the 2F-85 to hold it."""
    return mjk.SceneObject(
        name="cube",
        shape=mjk.Shape.BOX,
        size=[CUBE_HALF] * 3,
        pos=[float(v) for v in pos],
        rgba=[0.1, 0.25, 1.0, 1.0],
        mass=0.1,
        condim=mjk.Condim.Torsional,
        friction=[0.8, 0.02, 0.001],
    )


def gen3_with_gripper(
    prefix: str = "",
    attach_to: mjk.AttachTarget | None = None,
    pos: tuple[float, float, float] = (0.0, 0.0, 0.0),
    euler: tuple[float, float, float] = (0.0, 0.0, 0.0),
) -> mjk.RobotSpec:
    """A Gen3 from Menagerie with a 2F-85 on its `pinch_site` (gripper names get `g_`)."""
    gripper = mjk.AttachmentSpec(
        mjcf_path=menagerie_model("robotiq_2f85"),
        attach_to=mjk.AttachTarget(mjk.AttachKind.Site, "pinch_site"),
        prefix=GRIPPER_PREFIX,
    )
    return mjk.RobotSpec(
        path=menagerie_model("kinova_gen3"),
        prefix=prefix,
        attach_to=attach_to,
        pos=list(pos),
        euler=list(euler),
        attachments=[gripper],
    )


def task_camera() -> mjk.CameraSpec:
    """A fixed camera at the table's front corner, looking at the arm and the work area."""
    return mjk.CameraSpec(name="task", pos=[1.25, -1.05, 1.55], euler=[57.5, 40.2, 22.3], fovy=45.0)


def table_top() -> mjk.AttachTarget:
    """The table's surface site, where the arms are mounted."""
    return mjk.AttachTarget(mjk.AttachKind.Site, mjk.scene_object_site_name(table(), "table_top"))


def tabletop_spec(
    robots: list[mjk.RobotSpec], objects: Sequence[mjk.SceneObject] = ()
) -> mjk.SceneSpec:
    """The table, then `objects`, the `robots` and the `task` camera, at 2 ms steps."""
    return mjk.SceneSpec(
        timestep=0.002,
        add_floor=True,
        add_skybox=True,
        objects=[table(), *objects],
        robots=robots,
        cameras=[task_camera()],
    )


def tutorial_spec(cube_pos: np.ndarray = CUBE_START) -> mjk.SceneSpec:
    """Gen3 + 2F-85 mounted on the table's `table_top` site, a cube and the `task` camera."""
    return tabletop_spec([gen3_with_gripper(attach_to=table_top())], [cube(cube_pos)])


def gripper_tool() -> mjk.ToolFrameSpec:
    """The 2F-85 as the arm's tool: its inertia joins the chain, its pinch site is the TCP."""
    return mjk.ToolFrameSpec(tool_body=f"{GRIPPER_PREFIX}base", tcp_site=f"{GRIPPER_PREFIX}pinch")


def create_arm(env: mjk.Scene, prefix: str = "") -> mjk.Robot:
    """The Gen3 chain from `base_link` to `bracelet_link`, with the gripper as its tool."""
    return env.create_robot("base_link", "bracelet_link", prefix=prefix, tool=gripper_tool())


def set_gripper(env: mjk.Scene, value: float, prefix: str = "") -> None:
    """Command the 2F-85 of the arm with `prefix`: 0 open ... 255 closed."""
    env.set_actuator_ctrl(f"{prefix}{GRIPPER_PREFIX}{GRIPPER_ACTUATOR}", value)


# ---------------------------------------------------------------------- control


@dataclass(frozen=True)
class JointMove:
    """A minimum-jerk joint-space move from `start` to `goal` in `duration` s from `t0`."""

    start: np.ndarray
    goal: np.ndarray
    t0: float
    duration: float

    def sample(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Desired position, velocity and acceleration at time `t` (held at the ends)."""
        tau = min(max((t - self.t0) / self.duration, 0.0), 1.0)
        s = tau**3 * (10.0 - 15.0 * tau + 6.0 * tau**2)
        ds = 30.0 * tau**2 * (1.0 - tau) ** 2 / self.duration
        dds = 60.0 * tau * (1.0 - tau) * (1.0 - 2.0 * tau) / self.duration**2
        delta = self.goal - self.start
        return self.start + s * delta, ds * delta, dds * delta

    def finished(self, t: float) -> bool:
        return t >= self.t0 + self.duration


@dataclass(frozen=True)
class JointCycle:
    """Round and round `poses` (the last leads back to the first) from `t0` on.

    Each leg is a `JointMove` of `move` seconds followed by `dwell` seconds at rest. The
    target depends on the time alone, so it stays right when a reset sends the clock back.
    """

    poses: Sequence[np.ndarray]
    move: float
    dwell: float = 0.0
    t0: float = 0.0

    def leg(self, t: float) -> int:
        """Index of the leg under way at `t`: leg k leads to `poses[(k + 1) % len(poses)]`."""
        return max(0, math.floor((t - self.t0) / (self.move + self.dwell)))

    def sample(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Desired position, velocity and acceleration at time `t`."""
        k, n = self.leg(t), len(self.poses)
        start = self.t0 + k * (self.move + self.dwell)
        return JointMove(self.poses[k % n], self.poses[(k + 1) % n], start, self.move).sample(t)


def impedance_torques(
    robot: mjk.Robot,
    q_des: np.ndarray,
    v_des: np.ndarray | None = None,
    a_des: np.ndarray | None = None,
    stiffness_hz: float = 4.0,
) -> np.ndarray:
    """Joint impedance with gravity feed-forward: g(q) + M(q) (a_d + K e + D ė).

    The stiffness and damping act through the mass matrix, so every joint behaves like a
    critically damped spring of `stiffness_hz`, from the heavy shoulder to the light wrist.
    Plain per-joint gains cannot do that: damping that suits the shoulder makes the wrist
    (about 1e-3 kg m²) unstable at a 2 ms explicit step.
    """
    omega = 2.0 * math.pi * stiffness_hz
    accel = omega**2 * (q_des - robot.jnt_pos_msr) - 2.0 * omega * robot.jnt_vel_msr
    if v_des is not None:
        accel += 2.0 * omega * v_des
    if a_des is not None:
        accel += a_des
    return robot.gravity_torques() + robot.mass_matrix() @ accel


def top_down(pos: np.ndarray, yaw_deg: float = 0.0) -> pin.SE3:
    """A TCP pose at `pos` whose approach axis (z) points straight down, turned by `yaw_deg`."""
    yaw = math.radians(yaw_deg)
    c, s = math.cos(yaw), math.sin(yaw)
    turn = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    flip = np.diag([1.0, -1.0, -1.0])  # half a turn about x: z down
    return pin.SE3(turn @ flip, np.asarray(pos, dtype=float))


def gravity_compensation(robot: mjk.Robot) -> Callable[[], None]:
    """A TORQUE-mode controller that commands the gravity torques and nothing else."""

    def control() -> None:
        robot.update()
        robot.jnt_trq_cmd = robot.gravity_torques()

    return control


def tcp_drift(start: np.ndarray, robot: mjk.Robot) -> float:
    """Metres between `start` and the TCP as of the last `update()`."""
    return float(np.linalg.norm(robot.fk_frame().translation - start))


# ---------------------------------------------------------------------- running


def parse_args(
    description: str,
    duration: float,
    extra: Callable[[argparse.ArgumentParser], None] | None = None,
) -> argparse.Namespace:
    """``--headless`` and ``--duration`` (simulated seconds), plus the example's own options."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument(
        "--headless", action="store_true", help="run without a window and print the result"
    )
    parser.add_argument(
        "--duration",
        type=float,
        default=duration,
        help=f"simulated seconds to run headless (default {duration:g})",
    )
    if extra is not None:
        extra(parser)
    return parser.parse_args()


def run(
    env: mjk.Scene,
    control: Callable[[], None],
    args: argparse.Namespace,
    *,
    robot: mjk.Robot | None = None,
    title: str = "mjkdl",
    camera: str = "task",
    until: Callable[[], bool] | None = None,
    after_step: Callable[[], None] | None = None,
) -> int:
    """Call `control()` then advance one timestep, again and again; return the steps taken.

    `control` reads the state (`robot.update()`) and writes the commands; they apply in the
    step that follows. Steps go through `robot` when given (else through `env`).

    Headless, the loop stops after ``args.duration`` simulated seconds (counted in steps, so
    an `env.reset()` inside the loop does not extend it) or as soon as `until()` is true; a
    progress bar of simulated seconds shows on a terminal once the run takes over a second.
    Otherwise it runs in the interactive viewer, in real time, until the window is closed or
    Ctrl+C is pressed. A loop that ends before `until()` is true says "stopped after N s".
    """
    if args.headless:
        advance = robot.step if robot is not None else env.step
        dt = env.timestep()
        budget = round(args.duration / dt)
        every = max(1, round(0.1 / dt))  # the bar moves by 0.1 simulated seconds
        steps = 0
        # Without `until` the run's length is known; with it, the bar counts up to the end.
        bar = tqdm(
            total=None if until is not None else round(budget * dt, 3),
            desc=title,
            unit="sim s",
            bar_format="{desc}: {n:.1f}/{total} sim s |{bar}| {elapsed}<{remaining}"
            if until is None
            else "{desc}: {n:.1f} sim s {elapsed}",
            disable=None,  # only on a terminal
            delay=1.0,
        )
        with bar:
            while steps < budget and not (until is not None and until()):
                control()
                advance()
                steps += 1
                if after_step is not None:
                    after_step()
                if steps % every == 0:
                    bar.update(every * dt)
        if until is not None and not until():
            print(f"stopped after {steps * env.timestep():.1f} s (--duration), before the end")
        return steps

    from mjkdl import SimulateViewer  # only the interactive path needs a display

    viewer = SimulateViewer.open(robot if robot is not None else env, title)
    steps = 0
    try:
        if camera in env.camera_names():
            viewer.use_camera(camera)
        while viewer.is_running():
            control()
            if not viewer.step():
                break
            steps += 1
            if after_step is not None:
                after_step()
    finally:
        viewer.close()
    print(f"stopped after {steps * env.timestep():.1f} s (window closed or Ctrl+C)")
    return steps


# ---------------------------------------------------------------------- Panda (control layer)

# Menagerie's Panda "home" keyframe (arm joints), the TCP between the fingertips (0.1034 m
# below `hand`, which has no site there) and the hand's actuator: ctrl 255 open ... 0 closed.
PANDA_HOME = np.array([0.0, 0.0, 0.0, -1.57079, 0.0, 1.57079, -0.7853])
PANDA_TCP = [0.0, 0.0, 0.1034]
PANDA_HAND = "actuator8"


def panda(
    prefix: str = "",
    attach_to: mjk.AttachTarget | None = None,
    pos: Sequence[float] = (0.0, 0.0, 0.0),
    euler: Sequence[float] = (0.0, 0.0, 0.0),
    hand: bool = True,
) -> mjk.RobotSpec:
    """Menagerie's Panda, with its hand or without (`panda_nohand.xml`, for another gripper)."""
    path = Path(mjk.menagerie.model_path("franka_emika_panda"))
    if not hand:
        path = path.parent / "panda_nohand.xml"
    return mjk.RobotSpec(
        path=str(path), prefix=prefix, attach_to=attach_to, pos=list(pos), euler=list(euler)
    )


def look_at(name: str, eye: Sequence[float], target: Sequence[float], fovy: float = 45.0):
    """A fixed camera at `eye` looking at `target`, upright (world z up in the image)."""
    eye, target = np.asarray(eye, float), np.asarray(target, float)
    back = (eye - target) / np.linalg.norm(eye - target)  # cameras look along their -z
    right = np.cross([0.0, 0.0, 1.0], back)
    right /= np.linalg.norm(right)
    rot = np.column_stack([right, np.cross(back, right), back])
    # MuJoCo's intrinsic xyz Euler angles of rot = Rx(a) Ry(b) Rz(c).
    a = math.atan2(-rot[1, 2], rot[2, 2])
    b = math.asin(max(-1.0, min(1.0, rot[0, 2])))
    c = math.atan2(-rot[0, 1], rot[0, 0])
    euler = [math.degrees(x) for x in (a, b, c)]
    return mjk.CameraSpec(name=name, pos=list(eye), euler=euler, fovy=fovy)


def panda_scene(
    robots: list[mjk.RobotSpec],
    objects: Sequence[mjk.SceneObject] = (),
    camera: mjk.CameraSpec | None = None,
) -> mjk.SceneSpec:
    """Pandas on the floor at 2 ms steps, with a `task` camera (default: on the one at 0)."""
    view = camera or look_at("task", eye=[1.6, -1.2, 1.2], target=[0.3, 0.0, 0.4])
    return mjk.SceneSpec(
        timestep=0.002,
        add_floor=True,
        add_skybox=True,
        objects=list(objects),
        robots=robots,
        cameras=[view],
    )


def create_panda(
    env: mjk.Env,
    prefix: str = "",
    home: np.ndarray = PANDA_HOME,
    tip: str = "hand",
    tool: mjk.ToolFrameSpec | None = None,
) -> mjk.Robot:
    """The Panda chain `link0` -> `tip` (default: its hand and TCP); resets put it at `home`.

    The arm is in POSITION mode, on Menagerie's own position actuators. A Panda carrying
    another gripper passes its own `tip` and `tool`.
    """
    tool = tool if tool is not None else mjk.ToolFrameSpec(tcp_pos=PANDA_TCP)
    robot = env.create_robot("link0", tip, prefix=prefix, tool=tool)
    robot.ctrl_mode = mjk.CtrlMode.POSITION
    previous = env.on_reset

    def place(ctx: mjk.ResetContext) -> None:
        if previous is not None:
            previous(ctx)
        robot.set_joint_pos(home, call_forward=False)

    env.on_reset = place
    return robot
