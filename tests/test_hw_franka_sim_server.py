"""The simulated Franka driven by the real client libraries, each in its own process: the
unmodified pylibfranka examples and short pylibfranka programs, against a server run in
lockstep (deterministic: every state waits for its command, whatever the machine's load)."""

from __future__ import annotations

import json
import os
import re
import shutil
import socket
import struct
import subprocess
import sys
import textwrap
import time
from collections.abc import Iterator

import mujoco
import numpy as np
import pinocchio as pin
import pytest
from conftest import FRANKA_EXAMPLES, FrankaSim, franka_sim, needs_extra, run_franka_example

from mjkdl.errors import SpecError
from mjkdl.hw.franka_sim import AddressInUseError, FrankaSimServer, wire
from mjkdl.hw.franka_sim.arm import SUCCESS_WINDOW, SimulatedArm
from mjkdl.hw.franka_sim.limits import PANDA
from mjkdl.hw.franka_sim.scene import CUBE_AT, franka_scene
from mjkdl.hw.joint_impedance import START_Q

# pylibfranka and franky both bind a `Duration`: only one of them loads per process, so the
# test process loads neither; the clients run in their own.
needs_extra("franka")

PYLIBFRANKA = FRANKA_EXAMPLES / "pylibfranka"
FRANKY = FRANKA_EXAMPLES / "franky"

# A pylibfranka joint motion: cosine from the measured q to `goal` in `seconds`.
MOVE_TO = """
def move_to(goal, seconds):
    ctrl = robot.start_joint_position_control(plf.ControllerMode.JointImpedance)
    state, _ = ctrl.readOnce()
    q0, goal, t = np.array(state.q_d), np.array(goal), 0.0
    while True:
        state, period = ctrl.readOnce()
        t += period.to_sec()
        s = 0.5 * (1.0 - np.cos(np.pi * min(t / seconds, 1.0)))
        cmd = plf.JointPositions(list(q0 + s * (goal - q0)))
        cmd.motion_finished = t >= seconds
        ctrl.writeOnce(cmd)
        if t >= seconds:
            return
"""


@pytest.fixture(scope="module")
def sim_arm() -> Iterator[SimulatedArm]:
    """The server's arm, in this process: what the clients' numbers are checked against."""
    arm = SimulatedArm(franka_scene(), PANDA)
    yield arm
    arm.env.close()


@pytest.fixture(scope="module")
def sim() -> Iterator[FrankaSim]:
    with franka_sim("--lockstep", "--command-timeout", "10") as running:
        yield running


@pytest.fixture
def server(sim: FrankaSim) -> str:
    return sim.host


def mjk_se3(rotation: np.ndarray, translation: np.ndarray) -> pin.SE3:
    return pin.SE3(rotation, np.asarray(translation, dtype=float))


def client(host: str, body: str, timeout: float = 120) -> str:
    """A pylibfranka program in its own process: `robot` connected to `host`, `move_to`
    defined; its stdout."""
    code = "import numpy as np, pylibfranka as plf\n"
    code += f"robot = plf.Robot({host!r}, plf.RealtimeConfig.kIgnore)\n"
    code += MOVE_TO + textwrap.dedent(body)
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=timeout
    )
    assert done.returncode == 0, done.stdout + done.stderr
    return done.stdout


def client_raises(host: str) -> str:
    """What a pylibfranka client connecting to `host` raises: 'Type message'."""
    code = (
        "import pylibfranka as plf\n"
        f"try:\n    plf.Robot({host!r}, plf.RealtimeConfig.kIgnore)\n"
        "except Exception as e:\n    print(type(e).__name__, e)\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    return done.stdout.strip()


def state_q(host: str) -> np.ndarray:
    out = client(host, "print(list(robot.read_once().q))")
    return np.array(eval(out))


def test_print_robot_state_example_reads_the_start_pose(server):
    out = run_franka_example(PYLIBFRANKA / "print_robot_state.py", "--ip", server)
    assert "Robot Mode: Idle" in out, out
    # the example rounds to 4 decimals
    q = re.search(r"Joint Positions \(q\): (\[.*\])", out)
    position = re.search(r"Position: (\[.*\])", out)
    assert q is not None and position is not None, out
    np.testing.assert_allclose(json.loads(q.group(1)), START_Q, atol=1e-4)
    np.testing.assert_allclose(json.loads(position.group(1)), [0.3069, 0.0, 0.4869], atol=1e-4)


def ee_position(host: str, sim_arm: SimulatedArm) -> np.ndarray:
    """The hand's position the robot reports (O_T_EE), checked against mjkdl's kinematics."""
    got = json.loads(client(host, "s = robot.read_once()\nprint([list(s.q), list(s.O_T_EE)])"))
    pose = np.reshape(got[1], (4, 4), order="F")
    np.testing.assert_allclose(pose, sim_arm._ee_pose(np.array(got[0])), atol=1e-5)
    return pose[:3, 3]


def homed_width(out: str) -> float:
    """The width the gripper example prints after homing."""
    found = re.search(r"Gripper width: ([0-9.e-]+)", out)
    assert found is not None, out
    return float(found.group(1))


def home(host: str) -> None:
    """Back to the start pose (out of a reflex an earlier test may have left): the examples'
    motions are relative to where the arm is."""
    client(host, f"robot.automatic_error_recovery()\nmove_to({START_Q.tolist()}, 2.0)")


def test_joint_position_example_moves_and_returns(server):
    home(server)
    q0 = state_q(server)
    out = run_franka_example(PYLIBFRANKA / "joint_position_example.py", "--ip", server, stdin="\n")
    assert "Finished motion" in out and "Error" not in out, out
    # its cosine profile ends where it began, and the arm with it
    np.testing.assert_allclose(state_q(server), q0, atol=1e-3)


def test_move_gripper_example_finds_nothing_to_grasp_in_the_air(server):
    # at the start pose the hand is in the air: the fingers close past 4 cm ± 5 mm
    out = run_franka_example(PYLIBFRANKA / "move_gripper.py", "--ip", server, "--width", "0.04")
    assert homed_width(out) > 0.0799, out
    assert "Failed to grasp object." in out, out


def test_torque_control_holds_gravity_and_the_model_is_mujocos(server, sim_arm):
    """pylibfranka's model (its Pinocchio, from the URDF and hand the server reports) against
    MuJoCo's on the same compiled model; zero torques for 1 s: the robot holds gravity."""
    out = client(
        server,
        """
        import json
        move_to(START, 2.0)
        state = robot.read_once()
        model = robot.load_model()
        ctrl = robot.start_torque_control()
        for i in range(1000):
            ctrl.readOnce()
            tau = plf.Torques([0.0] * 7)
            tau.motion_finished = i == 999
            ctrl.writeOnce(tau)
        after = robot.read_once()
        print(json.dumps(dict(q=list(state.q), mass=list(model.mass(state)),
            gravity=list(model.gravity(state)), jac=list(model.zero_jacobian(state)),
            q_after=list(after.q), dq_after=list(after.dq))))
        """.replace("START", repr(START_Q.tolist())),
    )
    got = json.loads(out)
    q = np.array(got["q"], dtype=float)
    np.testing.assert_allclose(q, START_Q, atol=2e-4)
    sim_arm.robot.set_joint_pos(q)
    m, d = sim_arm.env.model, sim_arm.env.data
    full = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, full)
    dofs = sim_arm._dofs
    # MuJoCo adds the rotors' armature; libfranka's rigid-body model has none
    mass = full[np.ix_(dofs, dofs)] - np.diag(m.dof_armature[dofs])
    np.testing.assert_allclose(np.reshape(got["mass"], (7, 7), order="F"), mass, atol=1e-6)
    np.testing.assert_allclose(got["gravity"], d.qfrc_bias[dofs], atol=1e-5)
    jac = np.reshape(got["jac"], (6, 7), order="F")
    np.testing.assert_allclose(jac, sim_arm._ee_jacobian(q), atol=1e-6)
    # float32 on the wire: 1e-7 rad is its resolution here
    np.testing.assert_allclose(got["q_after"], q, atol=1e-6)
    np.testing.assert_allclose(got["dq_after"], 0.0, atol=1e-6)


def test_pick_the_cube_through_the_protocol(server, sim_arm):
    """Open the hand, move above the cube and down (pylibfranka), grasp with the unmodified
    gripper example, lift: the fingers stay on the 4 cm cube."""
    down = np.diag([1.0, -1.0, -1.0])
    grasp = sim_arm.robot.ik(mjk_se3(down, CUBE_AT + np.array([0.0, 0.0, 0.005])), q0=START_Q)
    above = sim_arm.robot.ik(mjk_se3(down, CUBE_AT + np.array([0.0, 0.0, 0.15])), q0=START_Q)
    assert grasp.success and above.success
    client(
        server,
        f"robot.automatic_error_recovery()\nplf.Gripper({server!r}).move(0.08, 0.1)\n"
        f"move_to({above.q.tolist()}, 2.0)\nmove_to({grasp.q.tolist()}, 1.5)\n",
    )
    out = run_franka_example(PYLIBFRANKA / "move_gripper.py", "--ip", server, "--width", "0.04")
    assert homed_width(out) > 0.0799, out
    assert "Grasped object, will release it now." in out, out
    lifted = client(
        server,
        f"""
        gripper = plf.Gripper({server!r})
        print(gripper.grasp(0.04, 0.1, 40.0))
        move_to({above.q.tolist()}, 1.5)
        state = gripper.read_once()
        print(state.is_grasped, round(state.width, 4))
        """,
    )
    grasped, still_grasped, width = lifted.split()
    assert grasped == still_grasped == "True", lifted
    assert abs(float(width) - 0.04) < 0.003, lifted  # the fingers press 1 mm into it


def test_franky_read_example(server):
    # the example prints the state every 50 ms until stopped
    out = run_franka_example(FRANKY / "read.py", "--host", server, timeout=8, stop=True)
    assert "Joints:" in out and "Elbow:" in out, out
    assert "FlipDirection.Negative" in out, out  # joint 4 is negative on both arms


def test_franky_linear_example_ends_where_it_began_its_line(server):
    out = run_franka_example(FRANKY / "linear.py", "--host", server)
    assert "Error" not in out and "Exception" not in out, out
    # JointMotion to its start, 20 cm along y and back: the arm ends at that start
    np.testing.assert_allclose(state_q(server), [0.0, 0.0, 0.0, -2.2, 0.0, 2.2, 0.7], atol=2e-3)


# ---------------------------------------------------------------------- faults


def test_a_step_in_the_command_is_the_robots_reflex_and_recovery_clears_it(sim):
    out = client(
        sim.host,
        """
        ctrl = robot.start_joint_position_control(plf.ControllerMode.JointImpedance)
        state, _ = ctrl.readOnce()
        jump = list(state.q_d)
        jump[0] += 0.05  # 50 rad/s for one cycle
        try:
            for _ in range(5):
                ctrl.writeOnce(plf.JointPositions(jump))
                ctrl.readOnce()
        except plf.ControlException as e:
            print("ControlException", e)
        print(robot.read_once().robot_mode)
        robot.automatic_error_recovery()
        print(robot.read_once().robot_mode)
        """,
    )
    assert "ControlException" in out and "joint_motion_generator_velocity_discontinuity" in out
    assert out.strip().splitlines()[-2:] == ["RobotMode.Reflex", "RobotMode.Idle"], out
    assert any("reflex, the arm stopped" in line for line in sim.log)


def test_a_second_client_is_refused_by_the_port(sim):
    holder = subprocess.Popen(
        [
            sys.executable,
            "-c",
            f"import time, pylibfranka as plf\n"
            f"robot = plf.Robot({sim.host!r}, plf.RealtimeConfig.kIgnore)\n"
            "print('connected', flush=True)\ntime.sleep(30)\n",
        ],
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert holder.stdout is not None and holder.stdout.readline() == "connected\n"
        out = client_raises(sim.host)
    finally:
        holder.kill()
        holder.wait()
    # the robot's port refuses others while one client holds it: libfranka names the refusal
    assert out.startswith("NetworkException libfranka: Connection to FCI refused"), out
    client(sim.host, "print(robot.read_once().robot_mode)")  # the next one is served


def test_a_client_killed_mid_motion_leaves_the_arm_still(sim):
    mover = subprocess.Popen(
        [
            sys.executable,
            "-c",
            f"import pylibfranka as plf\n"
            f"robot = plf.Robot({sim.host!r}, plf.RealtimeConfig.kIgnore)\n"
            "ctrl = robot.start_joint_velocity_control(plf.ControllerMode.JointImpedance)\n"
            "for i in range(100000):\n"
            "    ctrl.readOnce()\n"
            "    ctrl.writeOnce(plf.JointVelocities([0.0] * 6 + [min(i * 1e-3, 0.3)]))\n"
            "    if i == 500: print('moving', flush=True)\n",
        ],
        stdout=subprocess.PIPE,
        text=True,
    )
    assert mover.stdout is not None and mover.stdout.readline() == "moving\n"
    mover.kill()
    mover.wait()
    out = client(
        sim.host,
        """
        import time
        first = robot.read_once()
        time.sleep(0.2)
        later = robot.read_once()
        print(first.robot_mode, max(abs(v) for v in later.dq), later.q[6] - first.q[6])
        """,
    )
    mode, speed, moved = out.split()
    assert mode == "RobotMode.Idle", out
    assert float(speed) < 1e-4 and abs(float(moved)) < 1e-4, out
    sim.wait_for("mid-motion: the arm stops")
    client(sim.host, f"move_to({START_Q.tolist()}, 1.0)")


def connect_when_free(host: str, timeout: float = 10.0) -> socket.socket:
    """A TCP connection to the robot's port, once the server has seen the previous client
    leave: while a client holds the arm the port is closed, as the robot's is, and it opens
    again a moment after that client's process ends (sooner than a loaded machine may run)."""
    deadline = time.monotonic() + timeout
    while True:
        try:
            return socket.create_connection((host, wire.ROBOT_PORT), timeout=timeout)
        except ConnectionRefusedError:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.05)


def test_a_client_of_another_protocol_version_is_told_both(sim):
    with connect_when_free(sim.host) as sock:
        sock.sendall(wire.message(0, 1, struct.pack("<HH", 9, 50000)))
        reply = sock.recv(64)
    command, command_id, size = wire.HEADER.unpack_from(reply)
    status, version = struct.unpack_from("<BH", reply, wire.HEADER.size)
    # libfranka turns this into IncompatibleVersionException(server 10, library 9)
    assert (command, command_id, size, status, version) == (0, 1, 15, 1, 10)
    refusal = sim.wait_for("speaks robot protocol 9")
    assert "speaks 10" in refusal and "and 5" in refusal, refusal


def test_nothing_listening_is_the_clients_network_exception():
    out = client_raises(f"127.{os.getpid() % 250 + 1}.250.1")
    assert out.startswith("NetworkException libfranka: Connection to FCI refused"), out


def test_lost_commands_lower_the_success_rate_in_realtime():
    """A client answering every other state: the success rate the robot reports (over its last
    100 cycles) falls to 0.5 or below. A loaded machine also loses cycles of its own; 20 lost in
    a row stop the motion, as on the robot, with communication_constraints_violation."""
    with franka_sim("--realtime") as rt:
        out = client(
            rt.host,
            """
            import json
            ctrl = robot.start_joint_position_control(plf.ControllerMode.JointImpedance)
            rates, error = [], ""
            try:
                for i in range(300):
                    state, _ = ctrl.readOnce()
                    rates.append(state.control_command_success_rate)
                    hold = plf.JointPositions(list(state.q_d))  # where the generator is
                    if i % 2 == 0:  # every other cycle goes unanswered
                        ctrl.writeOnce(hold)
                hold.motion_finished = True
                ctrl.writeOnce(hold)
            except plf.ControlException as e:
                error = str(e)
            print(json.dumps(dict(rates=rates, error=error)))
            """,
        )
    got = json.loads(out)
    rates, error = np.array(got["rates"]), got["error"]
    assert error == "" or '["communication_constraints_violation"]' in error, error
    assert rates.min() > 0.0 and rates.max() <= 1.0, rates
    # a full window of every-other (the first states show the window filled with successes)
    late = rates[SUCCESS_WINDOW + 10 :]
    assert error or late.size > 0, rates
    assert np.all(late <= 0.5 + 0.02), late  # a state's own cycle may count before it is due


def test_cartesian_pose_example_draws_its_arc(server, sim_arm):
    home(server)
    out = run_franka_example(PYLIBFRANKA / "cartesian_pose_example.py", "--ip", server, stdin="\n")
    assert "Finished motion" in out and "Error" not in out, out
    # a quarter circle of 0.3 m in x-z in 5 s: the hand ends 0.3 m forward, 0.3 m down
    moved = ee_position(server, sim_arm) - sim_arm._ee_pose(START_Q)[:3, 3]
    np.testing.assert_allclose(moved, [0.3, 0.0, -0.3], atol=2e-3)


def test_the_same_arc_under_the_robots_cartesian_impedance(server, sim_arm):
    """The example's arc in ControllerMode.CartesianImpedance (the robot's Cartesian spring
    pulls the hand along it): it ends where mjkdl's kinematics put the commanded pose and
    follows it within a few millimetres (the spring lags the accelerating hand)."""
    home(server)
    out = client(
        server,
        """
        ctrl = robot.start_cartesian_pose_control(plf.ControllerMode.CartesianImpedance)
        state, _ = ctrl.readOnce()
        start, t, lag = np.array(state.O_T_EE_d), 0.0, 0.0
        while t < 5.0:
            state, period = ctrl.readOnce()
            lag = max(lag, np.linalg.norm(np.subtract(state.O_T_EE, state.O_T_EE_c)[12:15]))
            t += period.to_sec()
            angle = np.pi / 4 * (1 - np.cos(np.pi / 5.0 * t))
            pose = start.copy()
            pose[12] += 0.3 * np.sin(angle)
            pose[14] += 0.3 * (np.cos(angle) - 1)
            cmd = plf.CartesianPose(list(pose))
            cmd.motion_finished = t >= 5.0
            ctrl.writeOnce(cmd)
        print(lag)
        """,
    )
    assert float(out) < 0.005, out  # m
    moved = ee_position(server, sim_arm) - sim_arm._ee_pose(START_Q)[:3, 3]
    np.testing.assert_allclose(moved, [0.3, 0.0, -0.3], atol=2e-3)


def test_franky_velocity_control_example(server, sim_arm):
    out = run_franka_example(FRANKY / "velocity_control.py", "--host", server)
    assert "Cartesian velocity control stopped." in out and "Exception" not in out, out
    # last: from its start pose, a twist of 0.03 m/s along x, y and z alike for 3 s (franky
    # ramps in and out): the hand moved the same along all three
    start = sim_arm._ee_pose(np.array([0.0, 0.0, 0.0, -2.2, 0.0, 2.2, 0.7]))[:3, 3]
    moved = ee_position(server, sim_arm) - start
    assert moved.min() > 0.03 and moved.max() - moved.min() < 0.005, moved


PANDA_PY_PROGRAM = """
import json, time, numpy as np, panda_py
from panda_py import controllers, libfranka as lf
panda = panda_py.Panda(HOST)
out = {}
panda.move_to_start()
model, s = panda.get_model(), panda.get_state()
hand = (list(s.I_total), s.m_total, list(s.F_x_Ctotal))
out["model"] = []
for q in QS:
    out["model"].append(dict(
        mass=model.mass(q, *hand), coriolis=model.coriolis(q, DQ, *hand),
        gravity=model.gravity(q, hand[1], hand[2]),
        pose=model.pose(lf.Frame.kEndEffector, q, list(s.F_T_EE), list(s.EE_T_K)),
        jac=model.zero_jacobian(lf.Frame.kEndEffector, q, list(s.F_T_EE), list(s.EE_T_K)),
        body=model.body_jacobian(lf.Frame.kFlange, q, list(s.F_T_EE), list(s.EE_T_K))))
out["moved"] = panda.move_to_joint_position(GOAL)
out["q_goal"] = list(panda.q)
target = panda.get_pose()
target[2, 3] -= 0.05
out["posed"] = panda.move_to_pose(target)
s = panda.get_state()
out["q_pose"], out["O_T_EE"], out["target"] = list(s.q), list(s.O_T_EE), target.tolist()

def run(ctrl, set_control, seconds):
    panda.start_controller(ctrl)
    start = panda.get_state().time.to_sec()
    while panda.get_state().time.to_sec() - start < seconds:  # the arm's clock, not the wall's
        set_control()
        time.sleep(0.005)
    panda.stop_controller()

q0 = panda.q.copy()
ctrl = controllers.JointPosition()
run(ctrl, lambda: ctrl.set_control(q0 + STEP), 1.5)
out["q_joint"], out["q_joint_target"] = list(panda.q), list(q0 + STEP)
x0, o0 = panda.get_position().copy(), panda.get_orientation().copy()
ctrl = controllers.CartesianImpedance()
run(ctrl, lambda: ctrl.set_control(x0 + [0.0, 0.0, 0.03], o0), 2.0)
out["x_cart"], out["x_cart_target"] = list(panda.get_position()), list(x0 + [0.0, 0.0, 0.03])
q1 = panda.q.copy()
ctrl = controllers.AppliedTorque()
run(ctrl, lambda: ctrl.set_control(np.zeros(7)), 1.0)
out["q_torque"], out["q_torque_start"] = list(panda.q), list(q1)
print(json.dumps(out))
"""


@pytest.mark.skipif(
    shutil.which("cc") is None and shutil.which("gcc") is None,
    reason="the server compiles panda-py's model library with a C compiler (apt-get install gcc)",
)
def test_panda_py_model_and_controllers_on_the_served_model_library(sim, sim_arm):
    """panda-py (libfranka 0.9.2) downloads the model library the server compiles: its model
    equals MuJoCo's, and its own motions and controllers end where they aim."""
    qs = [START_Q.tolist(), (START_Q + np.array([0.3, 0.2, -0.4, 0.5, 0.6, -0.3, 0.9])).tolist()]
    dq = [0.5, -0.4, 0.3, -0.2, 0.6, -0.5, 0.4]
    goal = START_Q + np.array([0.2, -0.1, 0.1, 0.2, 0.1, 0.2, -0.2])
    step = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.1])
    code = PANDA_PY_PROGRAM
    for name, value in (("HOST", repr(sim.host)), ("QS", repr(qs)), ("DQ", repr(dq))):
        code = code.replace(name, value)
    code = code.replace("GOAL", repr(goal.tolist())).replace("STEP", repr(step.tolist()))
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=180)
    assert done.returncode == 0, done.stdout + done.stderr
    got = json.loads(done.stdout.strip().splitlines()[-1])
    m, d = sim_arm.env.model, sim_arm.env.data
    dofs = sim_arm._dofs
    for q, one in zip(qs, got["model"], strict=True):
        q = np.array(q)
        sim_arm.robot.set_joint_pos(q)
        full = np.zeros((m.nv, m.nv))
        mujoco.mj_fullM(m, d, full)
        mass = full[np.ix_(dofs, dofs)] - np.diag(m.dof_armature[dofs])  # no rotors in libfranka
        np.testing.assert_allclose(np.reshape(one["mass"], (7, 7), order="F"), mass, atol=1e-6)
        gravity = d.qfrc_bias[dofs].copy()
        np.testing.assert_allclose(one["gravity"], gravity, atol=1e-6)
        np.testing.assert_allclose(
            np.reshape(one["pose"], (4, 4), order="F"), sim_arm._ee_pose(q), atol=1e-6
        )
        jac = sim_arm._ee_jacobian(q)
        np.testing.assert_allclose(np.reshape(one["jac"], (6, 7), order="F"), jac, atol=1e-6)
        d.qvel[dofs] = dq
        mujoco.mj_forward(m, d)
        np.testing.assert_allclose(one["coriolis"], d.qfrc_bias[dofs] - gravity, atol=1e-6)
        d.qvel[:] = 0.0
        # the flange's body Jacobian: the EE's rotated into the flange, at the flange
        flange = sim_arm._flange_pose(q)
        offset = flange[:3, 3] - sim_arm._ee_pose(q)[:3, 3]
        at_flange = jac.copy()
        at_flange[:3] -= np.cross(offset, jac[3:].T).T
        body = np.vstack([flange[:3, :3].T @ at_flange[:3], flange[:3, :3].T @ at_flange[3:]])
        np.testing.assert_allclose(np.reshape(one["body"], (6, 7), order="F"), body, atol=1e-6)
    # move_to_joint_position: the robot's joint impedance behind panda-py's trajectory
    assert got["moved"] is True
    np.testing.assert_allclose(got["q_goal"], goal, atol=1e-3)
    # move_to_pose: panda-py's Cartesian impedance, done within its thresholds (2 cm, 0.1 rad);
    # the pose the arm reports is mjkdl's kinematics of where it stands
    assert got["posed"] is True
    reached = np.reshape(got["O_T_EE"], (4, 4), order="F")
    np.testing.assert_allclose(reached, sim_arm._ee_pose(np.array(got["q_pose"])), atol=1e-6)
    target = np.array(got["target"])
    assert np.linalg.norm(reached[:3, 3] - target[:3, 3]) < 0.02
    assert np.linalg.norm(pin.log3(reached[:3, :3].T @ target[:3, :3])) < 0.1
    np.testing.assert_allclose(got["q_joint"], got["q_joint_target"], atol=5e-3)
    np.testing.assert_allclose(got["x_cart"], got["x_cart_target"], atol=5e-3)
    # zero torques on top of the robot's gravity compensation: the arm stays
    np.testing.assert_allclose(got["q_torque"], got["q_torque_start"], atol=5e-3)
    assert any("robot protocol 5" in line for line in sim.log)


def test_without_a_c_compiler_panda_py_gets_libfrankas_error_and_the_log_the_fix(
    tmp_path, monkeypatch
):
    """No compiler (and nothing cached): the client fails with libfranka's own message, the
    server's log says what to install."""
    monkeypatch.setenv("CC", "no-such-compiler")
    monkeypatch.setenv("MJKDL_CACHE_DIR", str(tmp_path))
    code = (
        "import panda_py\n"
        "try:\n    panda_py.Panda(HOST)\n"
        "except Exception as e:\n    print(type(e).__name__, e)\n"
    )
    with franka_sim("--lockstep") as sim:
        code = code.replace("HOST", repr(sim.host))
        done = subprocess.run(
            [sys.executable, "-c", code], capture_output=True, text=True, timeout=60
        )
        assert done.stdout.strip() == (
            "RuntimeError libfranka: Server reports error when loading model library."
        ), done.stdout + done.stderr
        deadline = time.monotonic() + 10.0  # the log is read by a thread
        while time.monotonic() < deadline and not any(
            "no model library" in line for line in sim.log
        ):
            time.sleep(0.05)
        assert any(
            "no model library for the client" in line and "apt-get install gcc" in line
            for line in sim.log
        ), sim.log[-3:]
    assert list(tmp_path.iterdir()) == []


def test_an_unknown_model_names_the_ones_there_are():
    with pytest.raises(SpecError, match=r"model 'ur5': the simulator knows \['fr3', 'panda'\]"):
        FrankaSimServer("127.0.0.1", model="ur5")


def test_a_taken_address_says_so_before_building_anything():
    host = f"127.{os.getpid() % 250 + 1}.251.1"
    with socket.socket() as taken:
        taken.bind((host, wire.ROBOT_PORT))
        taken.listen()
        with pytest.raises(AddressInUseError, match=r"cannot listen on .*:1337.*--host"):
            FrankaSimServer(host)
