"""Pick and place: a state machine over IK waypoints, joint impedance and the 2F-85.

Before the loop, the cube's pose is read from the scene and `robot.ik` turns a handful of
top-down TCP poses (above the cube, at it, lifted, above the place spot, at it) into joint
positions. The loop then walks through the states

    HOME -> PRE-GRASP -> GRASP -> CLOSE -> LIFT -> CARRY -> PLACE -> RELEASE -> RETREAT -> DONE

each moving the joint target along a minimum-jerk path to its waypoint, tracked by joint
impedance with gravity feed-forward (`common.impedance_torques`), while the gripper actuator is
driven open (0) or closed (255). A state ends when its move is over and the arm has settled
(or after a timeout).

Why joint space: the waypoints already are joint positions, the legs are short, so the joint
paths between IK solutions seeded one from the other stay close to straight lines; the
inertia-shaped joint spring is stable on every joint, from shoulder to wrist, and compliant
when the fingers touch the cube. A task-space impedance would buy exactly straight TCP paths,
which this task does not need, for a Jacobian and task inertia every step.

The Env's reset hook puts the arm at home, the cube back on its start and the state machine
back to HOME, so a reset at any time (the viewer's, or `--reset-at` headless) starts the task
over. Headless, the script reports the lift height, the distance from the cube to the place
spot and whether the task succeeded.

    python examples/pick_place.py
    python examples/pick_place.py --headless --seed 3
"""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin
from common import (
    CUBE_START,
    GRIPPER_CLOSED,
    GRIPPER_OPEN,
    HOME,
    JointMove,
    create_arm,
    impedance_torques,
    parse_args,
    run,
    set_gripper,
    top_down,
    tutorial_spec,
)

import mjkdl as mjk

PLACE_SPOT = np.array([0.35, -0.15])  # x, y on the table, in metres
HOVER = 0.10  # pre-grasp height of the TCP above the grasp point
LIFT = 0.15  # carrying height of the TCP above the grasp point
PLACE_CLEARANCE = 0.003  # the held cube hangs a few mm below the TCP: release it this high
SETTLE_TOL = 0.03  # rad: a state's move has settled when every joint is this close
SETTLE_TIME = 0.3  # s to wait after a move before testing that it settled
TIMEOUT = 1.5  # s after the move after which a state ends anyway
PLACE_TOL = 0.02  # m: success when the cube rests this close to the place spot
MIN_LIFT = 0.05  # m: and had been lifted at least this high


@dataclass(frozen=True)
class State:
    """One step of the task: a joint waypoint reached in `duration` s, a gripper command."""

    name: str
    goal: np.ndarray
    duration: float
    gripper: float


def grasp_yaw(cube_rotation: np.ndarray) -> float:
    """The cube's yaw folded into [-45°, 45°): any face pair can be gripped."""
    yaw = math.degrees(math.atan2(cube_rotation[1, 0], cube_rotation[0, 0]))
    return (yaw + 45.0) % 90.0 - 45.0


def plan(robot: mjk.Robot, cube: pin.SE3, place_xy: np.ndarray) -> list[State]:
    """IK for every waypoint, each seeded with the previous solution; raises if one fails."""
    grasp = cube.translation.copy()
    place = np.array([place_xy[0], place_xy[1], grasp[2] + PLACE_CLEARANCE])
    yaw = grasp_yaw(cube.rotation)
    up = np.array([0.0, 0.0, 1.0])
    tcp_targets = {
        "PRE-GRASP": grasp + HOVER * up,
        "GRASP": grasp,
        "LIFT": grasp + LIFT * up,
        "CARRY": place + (LIFT - PLACE_CLEARANCE) * up,
        "PLACE": place,
        "RETREAT": place + HOVER * up,
    }
    q, joints = HOME, {}
    for name, target in tcp_targets.items():
        result = robot.ik(top_down(target, yaw), q)
        if not result.success:
            raise RuntimeError(f"IK failed for {name} at {np.round(target, 3)}")
        q = joints[name] = result.q
    return [
        State("HOME", HOME, 0.5, GRIPPER_OPEN),
        State("PRE-GRASP", joints["PRE-GRASP"], 1.5, GRIPPER_OPEN),
        State("GRASP", joints["GRASP"], 1.0, GRIPPER_OPEN),
        State("CLOSE", joints["GRASP"], 0.8, GRIPPER_CLOSED),
        State("LIFT", joints["LIFT"], 1.0, GRIPPER_CLOSED),
        State("CARRY", joints["CARRY"], 1.5, GRIPPER_CLOSED),
        State("PLACE", joints["PLACE"], 1.0, GRIPPER_CLOSED),
        State("RELEASE", joints["PLACE"], 0.6, GRIPPER_OPEN),
        State("RETREAT", joints["RETREAT"], 0.8, GRIPPER_OPEN),
    ]


@dataclass
class PickPlace:
    """The task's state machine and what it measured since it last started."""

    env: mjk.Env
    robot: mjk.Robot
    states: list[State]
    cube_start: np.ndarray
    index: int = 0
    move: JointMove | None = None
    cube_max_z: float = 0.0
    trace: list[tuple[str, float]] = field(default_factory=list)  # (state, entered at)

    @property
    def state(self) -> str:
        return self.states[self.index].name if self.index < len(self.states) else "DONE"

    @property
    def done(self) -> bool:
        return self.index >= len(self.states)

    def restart(self) -> None:
        """Back to HOME, from the home pose, now (call it from the reset hook)."""
        self.index = 0
        self.move = JointMove(HOME, self.states[0].goal, self.env.time(), self.states[0].duration)
        self.cube_max_z = float(self.cube_start[2])
        self.trace = [(self.state, self.env.time())]

    def cube_position(self) -> np.ndarray:
        return self.env.body_frame("cube").translation

    def control(self) -> None:
        """Read the state, move on when the current state is over, command arm and gripper."""
        robot, t = self.robot, self.env.time()
        robot.update()
        self.cube_max_z = max(self.cube_max_z, float(self.cube_position()[2]))
        if not self.done and self._state_over(t):
            self.index += 1
            if not self.done:
                goal, duration = self.states[self.index].goal, self.states[self.index].duration
                self.move = JointMove(self.move.goal, goal, t, duration)
            self.trace.append((self.state, t))
        q_des, v_des, a_des = self.move.sample(t)
        robot.jnt_trq_cmd = impedance_torques(robot, q_des, v_des, a_des)
        current = self.states[min(self.index, len(self.states) - 1)]  # DONE keeps the last
        set_gripper(self.env, current.gripper)

    def _state_over(self, t: float) -> bool:
        elapsed = t - self.move.t0 - self.move.duration
        if elapsed < SETTLE_TIME:
            return False
        settled = np.abs(self.move.goal - self.robot.jnt_pos_msr).max() < SETTLE_TOL
        return settled or elapsed >= TIMEOUT

    def lift(self) -> float:
        """How high the cube has been above its start since the task (re)started."""
        return self.cube_max_z - float(self.cube_start[2])


def options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--seed", type=int, default=None, help="jitter the cube start by up to ±2 cm in x and y"
    )
    parser.add_argument(
        "--reset-at",
        type=float,
        default=6.0,
        help="headless: call env.reset() once at this simulated time (default 6; <0: never)",
    )


def cube_start(seed: int | None) -> np.ndarray:
    """The tutorial's cube position, moved by up to ±2 cm in x and y when `seed` is given."""
    if seed is None:
        return CUBE_START.copy()
    jitter = np.random.default_rng(seed).uniform(-0.02, 0.02, 2)
    return CUBE_START + np.array([jitter[0], jitter[1], 0.0])


def setup(seed: int | None) -> tuple[mjk.Env, mjk.Robot, PickPlace]:
    """Build the scene, the robot, the reset hook and the plan; the task starts at HOME."""
    start = cube_start(seed)
    env = mjk.Env.build(tutorial_spec(cube_pos=start))
    robot = create_arm(env)
    robot.ctrl_mode = mjk.CtrlMode.TORQUE
    states = plan(robot, env.body_frame("cube"), PLACE_SPOT)  # the cube as built, at rest
    task = PickPlace(env, robot, states, cube_start=start)

    def on_reset(ctx: mjk.ResetContext) -> None:
        robot.set_joint_pos(HOME, call_forward=False)
        env.set_body_pose("cube", start, [1.0, 0.0, 0.0, 0.0])
        task.restart()

    env.on_reset = on_reset
    env.reset()
    return env, robot, task


def report(task: PickPlace) -> bool:
    """Print the outcome of the last attempt; True on success."""
    cube = task.cube_position()
    error = float(np.linalg.norm(cube[:2] - PLACE_SPOT))
    resting = abs(cube[2] - task.cube_start[2]) < 0.005
    success = task.done and resting and error <= PLACE_TOL and task.lift() >= MIN_LIFT
    print("states: " + " > ".join(f"{name} {t:.1f}" for name, t in task.trace))
    print(
        f"place spot: ({PLACE_SPOT[0]:.3f}, {PLACE_SPOT[1]:.3f}) m, "
        f"cube at ({cube[0]:.3f}, {cube[1]:.3f}, {cube[2]:.3f}) m"
    )
    print(f"lifted: {task.lift():.3f} m")
    print(f"place error: {error:.4f} m")
    if not task.done:  # stopped early (--duration, window closed, Ctrl+C): not a failure
        print(f"result: not finished (stopped in state {task.state})")
    else:
        print(f"result: {'success' if success else 'FAILURE'}")
    return success


def main() -> int:
    args = parse_args(__doc__.splitlines()[0], duration=30.0, extra=options)
    env, robot, task = setup(args.seed)
    with env:
        start = task.cube_start
        print(f"cube start: ({start[0]:.3f}, {start[1]:.3f}) m, seed {args.seed}")
        reset_at = args.reset_at if args.headless and args.reset_at >= 0 else None

        def reset_once() -> None:
            nonlocal reset_at
            if reset_at is not None and env.time() >= reset_at:
                print(
                    f"reset at t={env.time():.2f} s in state {task.state}, cube "
                    f"{task.lift():.3f} m up: starting over"
                )
                reset_at = None
                env.reset()

        run(
            env,
            task.control,
            args,
            robot=robot,
            title="pick and place",
            until=lambda: task.done,
            after_step=reset_once,
        )
        print(f"simulated: {env.time():.2f} s since the last reset")
        success = report(task)
    return 0 if success or not task.done or not args.headless else 1


if __name__ == "__main__":
    raise SystemExit(main())
