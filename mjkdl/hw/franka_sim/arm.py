"""The simulated arm behind the protocol: the robot's own controllers (joint and Cartesian
impedance behind the motion generators, torque control with gravity compensated), its reflexes,
and the robot state it reports, one 1 ms cycle at a time on an mjkdl `Env`/`Robot`."""

from __future__ import annotations

import mujoco
import numpy as np
import pinocchio as pin

from mjkdl.robot import Robot
from mjkdl.scene import Env
from mjkdl.spec import CtrlMode, SceneSpec, ToolFrameSpec

from ..joint_impedance import START_Q, JointImpedance
from . import wire
from .limits import ArmLimits
from .reality import Reality, StateLag, add_load, reality_from
from .scene import ARM_JOINTS, HAND_TCP, arm_urdf, hand_inertia

DT = 0.001
# The robot's defaults (Franka's documentation; libfranka's examples set the same).
CARTESIAN_STIFFNESS = np.array([3000.0, 3000.0, 3000.0, 300.0, 300.0, 300.0])
TORQUE_THRESHOLDS = np.array([20.0, 20.0, 18.0, 18.0, 16.0, 14.0, 12.0])
FORCE_THRESHOLDS = np.array([20.0, 20.0, 20.0, 25.0, 25.0, 25.0])
GRAVITY = np.array([0.0, 0.0, -9.81])
NULLSPACE_STIFFNESS = 10.0  # N·m/rad: the Cartesian impedance's hold of the elbow
LOST_CYCLES_LIMIT = 20  # consecutive cycles without a command before the robot stops
SUCCESS_WINDOW = 100  # cycles over which control_command_success_rate is reported
# Relative slack on the limit checks: libfranka's own rate limiter brings commands to the limits
# themselves, and backward differences of float64 commands carry rounding.
SLACK = 1.0 + 1e-3


def _hand_tcp() -> np.ndarray:
    """F_T_EE of a Panda with the Franka Hand: 0.1034 m out, turned -45° about z."""
    c = np.cos(-np.pi / 4)
    s = np.sin(-np.pi / 4)
    out = np.eye(4)
    out[:3, :3] = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
    out[2, 3] = HAND_TCP
    return out


def _col(mat: np.ndarray) -> np.ndarray:
    return mat.flatten(order="F")


def _from_col(values: np.ndarray) -> np.ndarray:
    return np.asarray(values, dtype=float).reshape(4, 4, order="F")


class SimulatedArm:
    """Menagerie's Panda in an mjkdl `Env`, driven as the robot drives itself; `reality`:
    how it differs from the nominal simulation (joint friction, the measured state's noise
    and latency)."""

    def __init__(self, spec: SceneSpec, limits: ArmLimits, reality: Reality | None = None) -> None:
        self.limits = limits
        self.reality = reality_from(reality)
        self._friction = self.reality.friction
        self._lag = StateLag(self.reality)
        self.env = Env.build(spec)
        self.robot: Robot = self.env.create_robot(
            "link0", "hand", tool=ToolFrameSpec(tcp_pos=[0.0, 0.0, HAND_TCP])
        )
        self.robot.set_joint_pos(START_Q)
        self.robot.ctrl_mode = CtrlMode.TORQUE
        self.robot.gravity_compensation = True
        m, d = self.env.model, self.env.data
        self._finger_qpos = [
            m.jnt_qposadr[m.joint(n).id] for n in ("finger_joint1", "finger_joint2")
        ]
        d.qpos[self._finger_qpos] = 0.04  # the hand starts open
        mujoco.mj_forward(m, d)
        self._dofs = np.array([m.jnt_dofadr[m.joint(n).id] for n in ARM_JOINTS])
        self._qfrc = np.zeros(m.nv)
        self.urdf = arm_urdf(m, limits)
        self.hand = hand_inertia(m, d)
        self._tcp_of_flange = np.linalg.inv(_hand_tcp())  # mjkdl's TCP → the flange
        self.impedance = JointImpedance(np.diag(self.robot.mass_matrix()), limits.tau_max)
        if self.reality.load_mass:  # after what the robot knows of itself (URDF, hand, model)
            add_load(m, m.body("hand").id, self.reality.load_mass, self.reality.load_com)
            mujoco.mj_forward(m, d)
        # user settings (TCP service)
        self.K_x = CARTESIAN_STIFFNESS.copy()
        self.torque_upper = TORQUE_THRESHOLDS.copy()
        self.torque_lower = TORQUE_THRESHOLDS.copy()
        self.force_upper = FORCE_THRESHOLDS.copy()
        self.force_lower = FORCE_THRESHOLDS.copy()
        self.F_T_NE = _hand_tcp()
        self.NE_T_EE = np.eye(4)
        self.EE_T_K = np.eye(4)
        self.m_load = 0.0
        self.F_x_Cload = np.zeros(3)
        self.I_load = np.zeros(9)
        # motion
        self.generator = wire.MotionGenerator.IDLE
        self.controller = wire.ControllerMode.OTHER
        self.robot_mode = wire.RobotMode.IDLE
        self.errors = np.zeros(len(wire.ERRORS), dtype=np.uint8)
        self.last_motion_errors = np.zeros(len(wire.ERRORS), dtype=np.uint8)
        self.event = ""  # "finished" or "reflex" after the cycle that ended a motion
        q = self.q
        self.q_d = q.copy()
        self._seen_q, self._seen_dq = self._lag.read(q, self.dq)  # what the client reads
        self.dq_d = np.zeros(7)
        self.ddq_d = np.zeros(7)
        self._dq_c_prev = np.zeros(7)
        self._ddq_c_prev = np.zeros(7)
        self.tau_J_d = np.zeros(7)
        self.tau_J = np.zeros(7)
        self._tau_J_prev = np.zeros(7)
        self.dtau_J = np.zeros(7)
        self.tau_ext = np.zeros(7)
        self.F_ext = np.zeros(6)
        self.O_T_EE = self._ee_pose(q)
        self.O_T_EE_d = self.O_T_EE.copy()
        self.O_dP_EE_d = np.zeros(6)
        self._v_prev = np.zeros(6)
        self._a_prev = np.zeros(6)
        self.elbow_c = np.zeros(2)
        self._received = np.zeros(SUCCESS_WINDOW, dtype=bool)
        self.lost_in_a_row = 0
        self.motion_cycles = 0  # cycles of the current (or last) motion
        self.motion_missed = 0  # of which without a command

    # -- measured --------------------------------------------------------------------------
    @property
    def q(self) -> np.ndarray:
        return self.robot.jnt_pos_msr.copy()

    @property
    def dq(self) -> np.ndarray:
        return self.robot.jnt_vel_msr.copy()

    @property
    def moving(self) -> bool:
        return self.generator is not wire.MotionGenerator.IDLE

    def _flange_pose(self, q: np.ndarray) -> np.ndarray:
        return self.robot.fk_frame(q).homogeneous @ self._tcp_of_flange

    def _ee_pose(self, q: np.ndarray) -> np.ndarray:
        return self._flange_pose(q) @ self.F_T_NE @ self.NE_T_EE

    def _ee_jacobian(self, q: np.ndarray) -> np.ndarray:
        """World-aligned 6×7 Jacobian of the EE frame (mjkdl's is at the hand's TCP)."""
        jac = self.robot.jacobian(q)
        offset = self._ee_pose(q)[:3, 3] - self.robot.fk_frame(q).translation
        out = jac.copy()
        out[:3] -= np.cross(offset, jac[3:].T).T  # v_ee = v_tcp + w x offset
        return out

    # -- TCP service -------------------------------------------------------------------------
    def start_motion(self, controller: wire.ControllerMode, generator: wire.MotionGenerator) -> str:
        """Begin a motion; returns an error message when the robot refuses it."""
        if self.robot_mode is wire.RobotMode.REFLEX:
            return "the robot is in reflex mode: call automatic_error_recovery() first"
        if self.moving:
            return "a motion is already running"
        q = self.q
        self.controller, self.generator = controller, generator
        self.robot_mode = wire.RobotMode.MOVE
        self.q_d = q.copy()
        self.dq_d[:] = 0.0
        self.ddq_d[:] = 0.0
        self._dq_c_prev[:] = 0.0
        self._ddq_c_prev[:] = 0.0
        self.O_T_EE_d = self._ee_pose(q)
        self.O_dP_EE_d[:] = 0.0
        self._v_prev[:] = 0.0
        self._a_prev[:] = 0.0
        self.tau_J_d[:] = 0.0
        self.last_motion_errors[:] = 0
        self._received[:] = True
        self.lost_in_a_row = 0
        self.motion_cycles = self.motion_missed = 0
        return ""

    def stop_motion(self) -> None:
        """StopMove, a closed connection, a lost client: hold where the arm is."""
        self._end_motion()

    def _end_motion(self) -> None:
        self.generator = wire.MotionGenerator.IDLE
        self.controller = wire.ControllerMode.OTHER
        if self.robot_mode is wire.RobotMode.MOVE:
            self.robot_mode = wire.RobotMode.IDLE
        self.q_d = self.q
        self.dq_d[:] = 0.0
        self.ddq_d[:] = 0.0
        self.tau_J_d[:] = 0.0

    def reflex(self, *names: str) -> None:
        """Stop the arm and report `names` as the real robot would."""
        for name in names:
            self.errors[wire.ERROR_INDEX[name]] = 1
        self.last_motion_errors[:] = self.errors
        self._end_motion()
        self.robot_mode = wire.RobotMode.REFLEX
        self.event = "reflex"

    def recover(self) -> None:
        self.errors[:] = 0
        self.robot_mode = wire.RobotMode.IDLE
        self.q_d = self.q

    # -- one cycle ---------------------------------------------------------------------------
    def step(self, cmd: np.void | None, count_lost: bool = True) -> None:
        """Run the robot's controllers on `cmd` (None: no command arrived this cycle) for 1 ms;
        `count_lost`: a missing command counts against the communication limits."""
        self.event = ""
        q, dq = self.q, self.dq
        if self.moving and (count_lost or cmd is not None):
            self._received = np.roll(self._received, 1)
            self._received[0] = cmd is not None
            self.motion_cycles += 1
            if cmd is None:
                self.lost_in_a_row += 1
                self.motion_missed += 1
                if self.lost_in_a_row >= LOST_CYCLES_LIMIT:
                    self.reflex("communication_constraints_violation")
                else:
                    self._extrapolate()
            else:
                self.lost_in_a_row = 0
                self._command(cmd, q)
        tau = self._control(q, dq)
        self._check_measured(q, dq)
        # The torque sensor reads `tau`; the link gets it less what its joint loses to friction.
        self.robot.jnt_trq_cmd = tau if self._friction is None else tau - self._friction.torque(dq)
        self.robot.update()
        self.robot.step()
        self._measure(tau)
        self._seen_q, self._seen_dq = self._lag.read(self.q, self.dq)

    def _command(self, cmd: np.void, q: np.ndarray) -> None:
        gen = self.generator
        finished = bool(cmd["motion_generation_finished"]) or bool(
            "torque_command_finished" in (cmd.dtype.names or ()) and cmd["torque_command_finished"]
        )
        if self.controller is wire.ControllerMode.EXTERNAL:
            tau_d = np.array(cmd["tau_J_d"], dtype=float)
            if not np.all(np.isfinite(tau_d)):
                return
            rate = np.abs(tau_d - self.tau_J_d) / DT
            if np.any(rate > self.limits.dtau_max * SLACK) and np.any(self.tau_J_d):
                self.reflex("controller_torque_discontinuity")
                return
            if np.any(np.abs(tau_d) > self.limits.tau_max * SLACK):
                self.reflex("tau_j_range_violation")
                return
            self.tau_J_d = tau_d
        if gen in (wire.MotionGenerator.JOINT_POSITION, wire.MotionGenerator.JOINT_VELOCITY):
            if gen is wire.MotionGenerator.JOINT_POSITION:
                q_c = np.array(cmd["q_c"], dtype=float)
                dq_c = (q_c - self.q_d) / DT
            else:
                dq_c = np.array(cmd["dq_c"], dtype=float)
                q_c = self.q_d + dq_c * DT
            if not self._joint_signal_ok(q_c, dq_c, "joint_motion_generator"):
                return
        elif gen in (
            wire.MotionGenerator.CARTESIAN_POSITION,
            wire.MotionGenerator.CARTESIAN_VELOCITY,
        ) and not self._cartesian(cmd, gen):
            return
        if finished:
            self.q_d = self.q_d.copy()
            self._end_motion_hold()

    def _extrapolate(self) -> None:
        """A lost cycle: the robot carries the motion on at its last velocity, so the next
        command is judged against where the motion would be, not where it paused."""
        if self.generator in (wire.MotionGenerator.IDLE, wire.MotionGenerator.NONE):
            return
        self.q_d = self.q_d + self.dq_d * DT
        if self.generator in (
            wire.MotionGenerator.CARTESIAN_POSITION,
            wire.MotionGenerator.CARTESIAN_VELOCITY,
        ):
            pose = self.O_T_EE_d.copy()
            pose[:3, 3] += self.O_dP_EE_d[:3] * DT
            pose[:3, :3] = pin.exp3(self.O_dP_EE_d[3:] * DT) @ pose[:3, :3]
            self.O_T_EE_d = pose

    def _end_motion_hold(self) -> None:
        """A finished motion: the generator's last setpoint stays the hold target."""
        q_d = self.q_d.copy() if self.controller is not wire.ControllerMode.EXTERNAL else self.q
        self._end_motion()
        self.q_d = q_d
        self.event = "finished"

    def _joint_signal_ok(self, q_c: np.ndarray, dq_c: np.ndarray, prefix: str) -> bool:
        lim = self.limits
        if not (np.all(np.isfinite(q_c)) and np.all(np.isfinite(dq_c))):
            return False
        ddq_c = (dq_c - self._dq_c_prev) / DT
        dddq_c = (ddq_c - self._ddq_c_prev) / DT
        if np.any(q_c < lim.q_min) or np.any(q_c > lim.q_max):
            self.reflex(f"{prefix}_position_limits_violation")
            return False
        # A step in the signal breaks every derivative: the robot names the discontinuity.
        if np.any(np.abs(ddq_c) > lim.ddq_max * SLACK):
            self.reflex(f"{prefix}_velocity_discontinuity")
            return False
        if np.any(np.abs(dddq_c) > lim.dddq_max * SLACK):
            self.reflex(f"{prefix}_acceleration_discontinuity")
            return False
        if np.any(np.abs(dq_c) > lim.dq_max * SLACK):
            self.reflex(f"{prefix}_velocity_limits_violation")
            return False
        self.q_d, self.dq_d, self.ddq_d = q_c, dq_c, ddq_c
        self._dq_c_prev, self._ddq_c_prev = dq_c, ddq_c
        return True

    def _cartesian(self, cmd: np.void, gen: wire.MotionGenerator) -> bool:
        """A Cartesian generator: check the twist, then the joint motion it takes (one damped
        least-squares step from the last joint setpoint, which tracks it at 1 kHz)."""
        lim = self.limits
        pose = self.O_T_EE_d
        if gen is wire.MotionGenerator.CARTESIAN_POSITION:
            target = _from_col(cmd["O_T_EE_c"])
            if not np.all(np.isfinite(target)):
                return False
            twist = pin.log6(
                pin.SE3(pose[:3, :3], pose[:3, 3]).actInv(pin.SE3(target[:3, :3], target[:3, 3]))
            )
            v = np.concatenate([pose[:3, :3] @ twist.linear, pose[:3, :3] @ twist.angular]) / DT
        else:
            v = np.array(cmd["O_dP_EE_c"], dtype=float)
            if not np.all(np.isfinite(v)):
                return False
            target = pose.copy()
            target[:3, 3] += v[:3] * DT
            target[:3, :3] = pin.exp3(v[3:] * DT) @ pose[:3, :3]
        a = (v - self._v_prev) / DT
        j = (a - self._a_prev) / DT
        names = "cartesian_motion_generator"
        for part, sl in ((0, slice(0, 3)), (1, slice(3, 6))):
            if np.linalg.norm(a[sl]) > lim.a_max[part] * SLACK:
                self.reflex(f"{names}_velocity_discontinuity")
                return False
            if np.linalg.norm(j[sl]) > lim.j_max[part] * SLACK:
                self.reflex(f"{names}_acceleration_discontinuity")
                return False
            if np.linalg.norm(v[sl]) > lim.v_max[part] * SLACK:
                self.reflex(f"{names}_velocity_limits_violation")
                return False
        jac = self._ee_jacobian(self.q_d)
        here = self._ee_pose(self.q_d)
        err = np.concatenate(
            [
                target[:3, 3] - here[:3, 3],
                pin.log3(target[:3, :3] @ here[:3, :3].T),
            ]
        )
        step = jac.T @ np.linalg.solve(jac @ jac.T + 1e-6 * np.eye(6), err)
        q_c = self.q_d + step
        if not self._joint_signal_ok(q_c, step / DT, f"{names}_joint"):
            return False
        self.O_T_EE_d = target
        self.O_dP_EE_d = v
        self._v_prev, self._a_prev = v, a
        if bool(cmd["valid_elbow"]):
            self.elbow_c = np.array(cmd["elbow_c"], dtype=float)
        return True

    def _control(self, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        """The robot's torque (gravity is added by the Robot handle, as the robot adds it)."""
        if self.controller is wire.ControllerMode.EXTERNAL:
            return self.tau_J_d.copy()
        if self.controller is wire.ControllerMode.CARTESIAN_IMPEDANCE and self.generator in (
            wire.MotionGenerator.CARTESIAN_POSITION,
            wire.MotionGenerator.CARTESIAN_VELOCITY,
        ):
            tau = self._cartesian_impedance(q, dq)
            return np.clip(tau, -self.limits.tau_max, self.limits.tau_max)
        return self.impedance.torque(self.q_d, self.dq_d, q, dq)

    def _cartesian_impedance(self, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        """The robot's Cartesian impedance: a spring `K_x` (N/m, N·m/rad; axes of the stiffness
        frame K) with damping 2·sqrt(K) pulls the EE to the generator's pose and twist, plus
        Coriolis; the joint motion it leaves free (the nullspace) is held at the generator's
        joint setpoint (the elbow), softly."""
        pose = self._ee_pose(q)
        jac = self._ee_jacobian(q)
        target = self.O_T_EE_d
        axes = (pose @ self.EE_T_K)[:3, :3]
        err = np.concatenate(
            [pose[:3, 3] - target[:3, 3], pin.log3(pose[:3, :3] @ target[:3, :3].T)]
        )
        err_dot = jac @ dq - self.O_dP_EE_d
        force = np.empty(6)
        for sl in (slice(0, 3), slice(3, 6)):
            k = self.K_x[sl]
            # in the K frame's axes, then back to the base frame's
            force[sl] = axes @ (-k * (axes.T @ err[sl]) - 2.0 * np.sqrt(k) * (axes.T @ err_dot[sl]))
        jt_pinv = np.linalg.pinv(jac.T, rcond=1e-3)
        nullspace = np.eye(7) - jac.T @ jt_pinv
        hold = NULLSPACE_STIFFNESS * (self.q_d - q) - 2.0 * np.sqrt(NULLSPACE_STIFFNESS) * dq
        robot = self.robot
        coriolis = robot.nonlinear_effects(q, dq) - robot.nonlinear_effects(q, np.zeros_like(dq))
        return jac.T @ force + nullspace @ hold + coriolis

    def _check_measured(self, q: np.ndarray, dq: np.ndarray) -> None:
        """The safety controller and the collision reflexes, in every mode."""
        if not self.moving:
            return
        if np.any(np.abs(dq) > self.limits.dq_max * SLACK):
            self.reflex("joint_velocity_violation")
        elif np.any(np.abs(self.tau_ext) > self.torque_upper):
            self.reflex("joint_reflex")
        elif np.any(np.abs(self.F_ext) > self.force_upper):
            self.reflex("cartesian_reflex")

    def _measure(self, tau: np.ndarray) -> None:
        q = self.q
        self.tau_J = tau + self.robot.gravity_torques()
        self.dtau_J = (self.tau_J - self._tau_J_prev) / DT
        self._tau_J_prev = self.tau_J
        self.tau_ext = self._external_torques()
        jac = self._ee_jacobian(q)
        self.F_ext = np.linalg.lstsq(jac.T, self.tau_ext, rcond=1e-3)[0]
        self.O_T_EE = self._ee_pose(q)
        if not self.moving:
            self.O_T_EE_d = self.O_T_EE.copy()

    def _external_torques(self) -> np.ndarray:
        """The robot's estimate tau_ext_hat: its joint torque beyond what its model needs, which
        (libfranka's robot_state.h) is the torque the arm exerts on the environment: minus what
        the environment's forces do at the joints. Here those are contacts and applied forces
        (a push: `xfrc_applied`, the viewer's perturbation); MuJoCo's joint-limit and
        equality constraints, damping and armature are the arm's own, not external."""
        m, d = self.env.model, self.env.data
        qfrc = self._qfrc
        n = d.nefc
        contact = d.efc_type[:n] >= int(mujoco.mjtConstraint.mjCNSTR_CONTACT_FRICTIONLESS)
        mujoco.mj_mulJacTVec(m, d, qfrc, np.where(contact, d.efc_force[:n], 0.0))
        qfrc += d.qfrc_applied
        for b in np.flatnonzero(np.any(d.xfrc_applied, axis=1)):
            # at the body's centre of mass, as MuJoCo applies it
            wrench = d.xfrc_applied[b]
            mujoco.mj_applyFT(m, d, wrench[:3], wrench[3:], d.xipos[b], int(b), qfrc)
        return -qfrc[self._dofs]

    # -- the state the robot sends --------------------------------------------------------------
    def write_state(self, s: np.ndarray, message_id: int) -> None:
        """Fill the RobotState record `s` (a length-1 structured array)."""
        q = self.q
        s["message_id"] = message_id
        s["O_T_EE"] = _col(self.O_T_EE)
        s["O_T_EE_d"] = _col(self.O_T_EE_d)
        s["O_T_EE_c"] = _col(self.O_T_EE_d)
        s["F_T_EE"] = _col(self.F_T_NE @ self.NE_T_EE)
        s["F_T_NE"] = _col(self.F_T_NE)
        s["NE_T_EE"] = _col(self.NE_T_EE)
        s["EE_T_K"] = _col(self.EE_T_K)
        s["m_ee"] = self.hand.m_ee
        s["F_x_Cee"] = self.hand.F_x_Cee
        s["I_ee"] = self.hand.I_ee
        s["m_load"] = self.m_load
        s["F_x_Cload"] = self.F_x_Cload
        s["I_load"] = self.I_load
        elbow = [q[2], np.sign(q[3]) or -1.0]
        s["elbow"] = elbow
        s["elbow_d"] = elbow
        s["elbow_c"] = elbow
        s["tau_J"] = self.tau_J
        s["tau_J_d"] = self.tau_J_d
        s["dtau_J"] = self.dtau_J
        s["q"] = self._seen_q
        s["theta"] = self._seen_q
        s["q_d"] = self.q_d
        s["dq"] = self._seen_dq
        s["dtheta"] = self._seen_dq
        s["dq_d"] = self.dq_d
        s["ddq_d"] = self.ddq_d
        s["joint_contact"] = np.abs(self.tau_ext) > self.torque_lower
        s["joint_collision"] = np.abs(self.tau_ext) > self.torque_upper
        s["cartesian_contact"] = np.abs(self.F_ext) > self.force_lower
        s["cartesian_collision"] = np.abs(self.F_ext) > self.force_upper
        s["tau_ext_hat_filtered"] = self.tau_ext
        s["O_F_ext_hat_K"] = self.F_ext
        rot = self.O_T_EE[:3, :3]
        s["K_F_ext_hat_K"] = np.concatenate([rot.T @ self.F_ext[:3], rot.T @ self.F_ext[3:]])
        s["O_dP_EE_d"] = self.O_dP_EE_d
        s["O_dP_EE_c"] = self.O_dP_EE_d
        s["O_ddP_O"] = GRAVITY
        s["motion_generator_mode"] = int(self.generator)
        s["controller_mode"] = int(self.controller)
        s["errors"] = self.errors
        s["reflex_reason"] = self.last_motion_errors
        s["robot_mode"] = int(self.robot_mode)
        s["control_command_success_rate"] = self._received.mean() if self.moving else 0.0
