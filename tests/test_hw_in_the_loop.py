"""Hardware in the loop: the arm at an address (the lockstep simulated Franka, in another
process) mirrored into an mjkdl scene whose other bodies are simulated; HAPTIC mode; task envs
with `robot_ip`."""

from __future__ import annotations

import gymnasium as gym
import mujoco
import numpy as np
import pytest
from conftest import panda_spec

import mjkdl as mjk
import mjkdl.task
from mjkdl.hw.in_the_loop import attach
from mjkdl.task.registry import PANDA_HOME

# libfranka's examples' start pose, where the simulated arm boots.
START = np.array([0.0, -np.pi / 4, 0.0, -3 * np.pi / 4, 0.0, np.pi / 2, np.pi / 4])


def _hand_at(q: np.ndarray) -> np.ndarray:
    env = mjk.Env.build(panda_spec())
    robot = env.create_robot("link0", "hand")
    robot.set_joint_pos(q)
    pos = env.body_frame("hand").translation.copy()
    env.close()
    return pos


def _box_beside_the_hand(dy: float) -> mjk.SceneSpec:
    """The Panda and a 4 cm box on a pedestal `dy` beside its hand at START (+y)."""
    hand = _hand_at(START)
    at = hand + np.array([0.0, dy, 0.0])
    return panda_spec(
        objects=[
            mjk.SceneObject(
                name="box", shape=mjk.Shape.BOX, size=[0.02] * 3, pos=at.tolist(), mass=0.05
            ),
            mjk.SceneObject(
                name="pedestal",
                shape=mjk.Shape.BOX,
                size=[0.03, 0.03, 0.01],
                pos=(at - [0.0, 0.0, 0.03]).tolist(),
                fixed=True,
            ),
        ],
    )


def test_the_scene_mirrors_the_arm_and_its_contacts_push_simulated_bodies(
    franka_server: str,
) -> None:
    env = mjk.Env.build(_box_beside_the_hand(0.09))
    try:
        robot = env.create_robot("link0", "hand", robot_ip=franka_server)
        link = env._link
        assert link is not None
        np.testing.assert_allclose(robot.jnt_pos_msr, START, atol=1e-4)
        box0 = env.body_frame("box").translation.copy()
        t0 = env.time()
        robot.ctrl_mode = mjk.CtrlMode.VELOCITY
        robot.jnt_vel_cmd = np.array([0.4, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])  # the hand sweeps +y
        for _ in range(5):
            env.step(50)  # 0.1 s of the arm's clock each
        robot.update()
        state = link.connection.state()
        # The simulated arm is where the arm is, and reads its measured torques.
        np.testing.assert_allclose(robot.jnt_pos_msr, state.q, atol=2e-3)
        np.testing.assert_allclose(robot.jnt_trq_msr, state.tau_J, atol=1.0)
        assert env.time() == pytest.approx(t0 + 0.5)
        assert robot.jnt_pos_msr[0] - START[0] > 0.12  # 0.4 rad/s for 0.5 s, less the ramp
        # The real arm hit nothing; the simulated hand knocked the simulated box along +y.
        mujoco.mj_forward(env.model, env.data)
        assert env.body_frame("box").translation[1] - box0[1] > 0.01
    finally:
        env.close()  # brings the arm to rest and closes the connection


def test_haptic_mode_renders_simulated_contacts_as_joint_torques(franka_server: str) -> None:
    # The box overlaps the hand: its contact pushes on the simulated arm, and in HAPTIC mode
    # those joint torques (x haptic_gain) go to the arm, which turns the way they push.
    env = mjk.Env.build(_box_beside_the_hand(0.04))
    try:
        robot = env.create_robot("link0", "hand")
        link = attach(env, robot, franka_server, haptic=True)
        link.move_to(START)  # an earlier test may have left the module's arm elsewhere
        env.step(5)
        dofs = [env.model.joint(n).dofadr[0] for n in robot.joint_names]
        push = env.data.qfrc_constraint[dofs[0]]
        assert abs(push) > 1.0  # N·m about the base axis, from the contact alone
        q0 = link.connection.state().q
        env.step(250)  # 0.5 s
        turned = link.connection.state().q[0] - q0[0]
        assert np.sign(turned) == np.sign(push) and abs(turned) > 1e-3
    finally:
        env.close()


def test_a_task_env_with_robot_ip_starts_its_episodes_on_the_arm(franka_server: str) -> None:
    env = gym.make("mjkdl/PandaPickCube-v0", robot_ip=franka_server)
    try:
        obs, _ = env.reset(seed=0)
        link = env.unwrapped.hardware
        # reset brought the arm home; the observation is the arm's, with its external forces.
        np.testing.assert_allclose(link.connection.state().q, PANDA_HOME, atol=3e-3)
        np.testing.assert_allclose(obs["panda_joint_pos"], PANDA_HOME, atol=3e-3)
        every = env.unwrapped._observe()
        assert every["panda_ext_torques"].shape == (7,)
        assert every["panda_ext_wrench"].shape == (6,)
        action = np.zeros(env.action_space.shape, dtype=np.float32)
        action[2] = -0.2  # the TCP down, slowly
        z0 = obs["panda_tcp_pos"][2]
        for _ in range(3):
            obs, *_ = env.step(action)
        assert obs["panda_tcp_pos"][2] < z0 - 0.01
        np.testing.assert_allclose(obs["panda_joint_pos"], link.connection.state().q, atol=3e-3)
    finally:
        env.close()


def test_robot_ip_refuses_what_it_cannot_mirror() -> None:
    with pytest.raises(mjk.SpecError, match="robot_ip must be a host name or IP address"):
        gym.make("mjkdl/PandaReach-v0", robot_ip="")


class _ClockArm:
    """An arm connection whose clock runs to whatever time is waited for; it records the arm
    time and target of every command sent (no server: what `ArmLink.step` sends, and when)."""

    def __init__(self, address: str, *args: object, **kw: object) -> None:
        from mjkdl.hw.connection import _S_LEN, _S_Q

        self.address = address
        self.block = np.zeros(_S_LEN)
        self.block[_S_Q : _S_Q + 7] = START
        self.sent: list[tuple[float, np.ndarray]] = []
        self.until: list[float] = []  # the arm time each command holds up to

    def read(self) -> np.ndarray:
        return self.block

    def check(self) -> None:
        pass

    def send(self, mode: int, command: np.ndarray, until: float = np.inf) -> None:
        from mjkdl.hw.connection import _S_TIME

        self.sent.append((float(self.block[_S_TIME]), np.array(command)))
        self.until.append(until)

    def wait_until(self, arm_time: float) -> np.ndarray:
        from mjkdl.hw.connection import _S_TIME

        self.block[_S_TIME] = max(self.block[_S_TIME], arm_time)
        return self.block

    def close(self) -> None:
        pass


def test_a_position_target_is_interpolated_once_per_arm_tick(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A 2 ms scene sends 2 targets per timestep: the linear path from the last target to the
    new one, one per 1 ms tick, each sent once the arm's clock reached its tick."""
    import mjkdl.hw.in_the_loop as loop

    monkeypatch.setattr(loop, "ArmConnection", _ClockArm)
    env = mjk.Env.build(panda_spec())
    try:
        robot = env.create_robot("link0", "hand", robot_ip="clock")
        conn = env._link.connection
        robot.ctrl_mode = mjk.CtrlMode.POSITION
        goal = START + np.array([0.1, -0.05, 0.0, 0.02, 0.0, 0.0, 0.01])
        robot.jnt_pos_cmd = goal
        env.step(5)  # 10 ms: 10 ticks
        times = np.array([t for t, _ in conn.sent])
        targets = np.array([c for _, c in conn.sent])
        np.testing.assert_allclose(times, np.arange(10) * 1e-3, atol=1e-12)
        # each target holds to the end of its own tick (what a lockstep arm waits for)
        np.testing.assert_allclose(conn.until, np.arange(1, 11) * 1e-3, atol=1e-12)
        share = np.arange(1, 11)[:, None] / 10
        np.testing.assert_allclose(targets, START + share * (goal - START), atol=1e-12)
        conn.sent.clear()
        env.step(1)  # held at the goal
        np.testing.assert_allclose([c for _, c in conn.sent], [goal, goal], atol=1e-12)
    finally:
        env.close()


@pytest.mark.parametrize("mode", [mjk.CtrlMode.POSITION, mjk.CtrlMode.TORQUE])
def test_between_mirrors_the_simulated_arm_coasts_on_the_measured_course(
    monkeypatch: pytest.MonkeyPatch, mode: mjk.CtrlMode
) -> None:
    """Within a step the simulated arm's actuators only cancel its bias forces: it does not
    lunge toward the command (the arm's to follow), which slid a held cube in the fingers."""
    import mjkdl.hw.in_the_loop as loop

    monkeypatch.setattr(loop, "ArmConnection", _ClockArm)
    env = mjk.Env.build(panda_spec())
    try:
        robot = env.create_robot("link0", "hand", robot_ip="clock")
        robot.ctrl_mode = mode
        if mode is mjk.CtrlMode.POSITION:
            robot.jnt_pos_cmd = START + 0.3  # the arm, held at START by the fake, lags far
        else:
            robot.jnt_trq_cmd = np.full(7, 5.0)
        env.step(3)
        dofs = [env.model.joint(n).dofadr[0] for n in robot.joint_names]
        mujoco.mj_forward(env.model, env.data)  # the controls the last step ran with
        assert np.abs(env.data.qacc[dofs]).max() < 1e-3  # rad/s², the bias a step old
        assert np.abs(env.data.actuator_force[: len(dofs)]).max() > 1.0  # gravity held
    finally:
        env.close()


def test_robot_ip_names_an_arm_joint_it_cannot_mirror(monkeypatch: pytest.MonkeyPatch) -> None:
    import mjkdl.hw.in_the_loop as loop

    monkeypatch.setattr(loop, "ArmConnection", _ClockArm)
    env = mjk.Env.build(panda_spec())
    try:
        env.model.actuator_trnid[3, 0] = env.model.joint("joint1").id  # joint4's, moved
        with pytest.raises(mjk.SpecError, match="joint 'joint1' has 2 actuators"):
            env.create_robot("link0", "hand", robot_ip="clock")
    finally:
        env.close()
