"""The Franka joint-impedance law, one implementation for the simulated arm behind the protocol
and for the task env's `arm_drive="franka_impedance"`: its numbers, the task env's Panda with it
against the same actions in the loop, and what it refuses."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from conftest import franka_sim, needs_extra

import mjkdl as mjk
import mjkdl.task
from mjkdl.demos.episodes import run_episode
from mjkdl.demos.policy import make_policy
from mjkdl.hw.franka_sim.arm import SimulatedArm
from mjkdl.hw.franka_sim.limits import PANDA
from mjkdl.hw.franka_sim.scene import franka_scene
from mjkdl.hw.joint_impedance import JOINT_STIFFNESS, START_Q, TAU_MAX, JointImpedance
from mjkdl.task.experts import FRANKA_GAIN, expert_for
from mjkdl.task.registry import TASKS

TASK = "mjkdl/PandaPickCube-v0"


def test_the_law_is_a_critically_damped_spring_within_the_torque_limits() -> None:
    mass = np.array([0.5, 1.0, 0.2, 0.8, 0.1, 0.05, 0.02])
    law = JointImpedance(mass)
    q_d = np.array([0.01, -0.02, 0.0, 0.005, 0.0, 0.0, 1.0])
    dq_d = np.array([0.1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    q, dq = np.zeros(7), np.array([0.0, 0.0, 0.0, 0.0, 0.2, 0.0, 0.0])
    tau = law.torque(q_d, dq_d, q, dq)
    np.testing.assert_allclose(tau[:2], [30.0 + 0.1 * 2 * np.sqrt(1500.0), -60.0])
    assert tau[3] == pytest.approx(12.5)
    assert tau[4] == pytest.approx(-0.2 * 2 * np.sqrt(250.0))
    assert tau[6] == TAU_MAX[6] == 12.0  # 2000 N·m clipped to the wrist's limit
    np.testing.assert_array_equal(law.stiffness, JOINT_STIFFNESS)


def test_the_simulated_arm_gives_way_by_torque_over_its_joint_stiffness() -> None:
    arm = SimulatedArm(franka_scene("empty"), PANDA)
    try:
        dof = arm.env.model.joint("joint4").dofadr[0]
        arm.env.data.qfrc_applied[dof] = 5.0  # N·m on the elbow, the arm at rest at START_Q
        for stiffness in (2500.0, 500.0):  # the default, then as setJointImpedance sets it
            arm.impedance.stiffness[3] = stiffness
            for _ in range(1500):
                arm.step(None, count_lost=False)
            assert arm.q[3] - START_Q[3] == pytest.approx(5.0 / stiffness, rel=0.03)
    finally:
        arm.env.close()


def _episode(env: gym.Env, seed: int, actions: list[np.ndarray] | None = None):
    """(actions, TCP after each step, success): the expert's, or `actions` replayed."""
    obs, _ = env.reset(seed=seed)
    expert = expert_for(env)
    expert.reset()
    taken, tcp, done, info = [], [], False, {}
    while not done and (actions is None or len(tcp) < len(actions)):
        action = expert(obs) if actions is None else actions[len(tcp)]
        obs, _, terminated, truncated, info = env.step(action)
        taken.append(action)
        tcp.append(obs["panda_tcp_pos"].copy())
        done = terminated or truncated
    return taken, np.array(tcp), bool(info["is_success"])


def test_the_same_actions_move_the_impedance_driven_panda_as_the_arm_in_the_loop() -> None:
    needs_extra("franka")
    sim = gym.make(TASK, arm_drive="franka_impedance")
    assert expert_for(sim)._gain == FRANKA_GAIN  # not the servos' 5/s: it overshoots the grasp
    assert sim.unwrapped.scene.timestep() == 0.001
    assert sim.unwrapped.control_substeps == 100
    actions, tcp_sim, ok_sim = _episode(sim, 0)
    sim.close()
    with franka_sim("--lockstep", "--scene", "empty", "--command-timeout", "10") as server:
        loop = gym.make(TASK, robot_ip=server.host, lockstep=True)
        try:
            _, tcp_loop, ok_loop = _episode(loop, 0, actions)
        finally:
            loop.close()
    assert ok_sim and ok_loop
    # as long in both: success (held 0.5 s) came a step sooner in the loop while its
    # simulated arm lunged toward the command between mirrors and the cube slid
    n = len(tcp_sim)
    assert len(tcp_loop) == n
    apart = np.linalg.norm(tcp_sim[:n] - tcp_loop[:n], axis=1)
    # the goal, over the whole episode: the approach, the grasp and the lift
    assert np.median(apart) < 1e-3
    assert apart.max() < 5e-3


def test_the_default_drive_stays_the_servos() -> None:
    env = gym.make(TASK)
    assert env.unwrapped.drive is None
    assert expert_for(env)._gain == 5.0
    assert env.unwrapped.scene.timestep() == 0.002
    env.close()


def test_bad_drives_are_refused_by_name() -> None:
    with pytest.raises(mjk.SpecError, match="arm_drive must be one of 'servo', 'franka_imp"):
        gym.make(TASK, arm_drive="impedance")
    with pytest.raises(mjk.SpecError, match="the arm's actuation is 'joint_velocity'"):
        gym.make(TASK, arm_drive="franka_impedance", actuation="joint_velocity")
    with pytest.raises(mjk.SpecError, match="with robot_ip the arm in the loop runs it"):
        gym.make(TASK, arm_drive="franka_impedance", robot_ip="127.0.0.1")


def _succeeds(env: gym.Env, seed: int) -> bool:
    """Whether the expert's whole episode from `seed` ends in success."""
    return run_episode(env, make_policy("expert", env), seed).success


@pytest.mark.parametrize("env_id", list(TASKS))
def test_every_expert_succeeds_on_the_impedance_drive(env_id: str) -> None:
    """The experts approach and carry at the Franka arm's gains on this drive
    (benchmarks/sim_to_loop.py --experts: 30 seeds each, docs/hardware.md)."""
    env = gym.make(env_id, arm_drive="franka_impedance")
    try:
        assert _succeeds(env, 1)
    finally:
        env.close()


def test_the_stack_expert_succeeds_in_the_loop() -> None:
    """The hardest task's expert on its own observations against the lockstep server. Seed 13
    failed while the simulated arm was left to its servos between mirrors: it lunged toward the
    command within each step, and the carried cube slid out of the fingers over the base."""
    needs_extra("franka")
    with franka_sim("--lockstep", "--scene", "empty", "--command-timeout", "10") as server:
        loop = gym.make("mjkdl/PandaStack-v0", robot_ip=server.host, lockstep=True)
        try:
            assert [_succeeds(loop, seed) for seed in (1, 13)] == [True, True]
        finally:
            loop.close()
