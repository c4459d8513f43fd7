"""The batch's CPU engine (MuJoCo's own `mujoco.batch`) against the CPU env (`TaskEnv`)."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from conftest import import_extra

torch = import_extra("batch", "torch")

import mujoco  # noqa: E402

from mjkdl.errors import SpecError, SpecTypeError  # noqa: E402
from mjkdl.task import make_batch, registry  # noqa: E402
from mjkdl.task.batch import UnsupportedFeatureError  # noqa: E402
from mjkdl.task.batch.cpu_engine import available_threads  # noqa: E402
from mjkdl.task.env import TaskEnv  # noqa: E402
from mjkdl.task.spec import Actuation, CameraSensor  # noqa: E402

PICK = "mjkdl/PandaPickCube-v0"
WORLDS = 3
SEED = 7
STEPS = 12  # control steps: with time_limit 0.5 s, two episodes and a restart per world
# Cartesian actions: the batch's QP (torch, active set) against DAQP, within rounding once
# the active set settles (measured here over these episodes: qpos 1e-14, rewards 3e-17).
CARTESIAN_TOL = 1e-9
REWARD_TOL = 1e-12  # the task's rules in torch against NumPy (measured 3e-17)


def _cpu_states(env: TaskEnv, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(qpos, reward) of each world after its reset and after each step, a finished episode
    restarting at once (the batch's autoreset) from the CPU env's next reset."""
    qpos, rewards = [], []
    for i in range(actions.shape[1]):
        env.reset(seed=SEED + i)
        q, r = [env.scene.data.qpos.copy()], [0.0]
        for a in actions[:, i]:
            _, reward, terminated, truncated, _ = env.step(a)
            if terminated or truncated:
                env.reset()
            q.append(env.scene.data.qpos.copy())
            r.append(reward)
        qpos.append(q)
        rewards.append(r)
    return np.array(qpos).transpose(1, 0, 2), np.array(rewards).T


def _batch_states(batch, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """The same from the batch; and how many episodes ended."""
    batch.reset(seed=SEED)
    q, r, ends = [batch.state.qpos.numpy().copy()], [np.zeros(actions.shape[1])], 0
    for a in actions:
        _, reward, terminated, truncated, _ = batch.step(torch.as_tensor(a))
        q.append(batch.state.qpos.numpy().copy())
        r.append(reward.numpy())
        ends += int((terminated | truncated).sum())
    return np.array(q), np.array(r), ends


def _actions(n: int, seed: int) -> np.ndarray:
    return np.random.default_rng(seed).uniform(-1, 1, (STEPS, WORLDS, n)).astype(np.float32)


@pytest.mark.parametrize("actuation", ["joint_position", "joint_velocity", "joint_torque"])
def test_joint_space_episodes_are_the_cpu_envs_bit_for_bit(actuation: str) -> None:
    """Same physics, same commands (Pinocchio's gravity feed-forward, float64): every state of
    whole episodes and their restarts equals the CPU env's exactly."""
    batch = make_batch(PICK, WORLDS, device="cpu", actuation=actuation, time_limit=0.5)
    env = gym.make(PICK, actuation=actuation, time_limit=0.5).unwrapped
    try:
        assert batch.state.name == "mujoco" and batch.dtype == torch.float64
        actions = _actions(8, 0)
        if actuation != "joint_position":
            actions[..., :7] *= 0.1  # normalised velocities or torques about gravity alone
        ref_q, ref_r = _cpu_states(env, actions)
        q, r, ends = _batch_states(batch, actions)
        assert ends == 2 * WORLDS  # two whole episodes per world, restarts included
        assert np.array_equal(q, ref_q), np.abs(q - ref_q).max()
        assert np.abs(r - ref_r).max() < REWARD_TOL
    finally:
        batch.close()
        env.close()


PHYSICS = {
    "body_mass": [0.5, 2.0],
    "body_com": [-0.005, 0.005, ["cube"]],
    "geom_friction": [0.7, 1.3],
    "joint_damping": [0.5, 2.0],
    "joint_armature": [0.5, 2.0],
    "joint_frictionloss": [0.5, 2.0],
    "actuator_gain": [0.8, 1.2],
    "gravity": [-0.5, 0.5],
    "action_latency": [0, 3],
}


def test_each_world_draws_the_cpu_envs_randomization_for_its_seed_bit_for_bit() -> None:
    """World i of reset(seed=s) is the CPU env's episode for seed s + i, with its draw of
    every physical field and of the action latency (restarts draw again): the same states
    exactly, with the reset workers too."""
    kw = {"actuation": "joint_position", "time_limit": 0.5, "randomization": PHYSICS}
    batch = make_batch(PICK, WORLDS, device="cpu", **kw)
    env = gym.make(PICK, **kw).unwrapped
    plain = make_batch(PICK, WORLDS, device="cpu", actuation="joint_position", time_limit=0.5)
    try:
        actions = _actions(8, 2)
        ref_q, _ = _cpu_states(env, actions)
        q, _, ends = _batch_states(batch, actions)
        assert ends == 2 * WORLDS
        assert np.array_equal(q, ref_q), np.abs(q - ref_q).max()
        workers = make_batch(PICK, WORLDS, device="cpu", reset_workers=1, **kw)
        try:  # the reset workers draw the same
            assert np.array_equal(_batch_states(workers, actions)[0], ref_q)
        finally:
            workers.close()
        nominal, _, _ = _batch_states(plain, actions)
        assert np.abs(q - nominal).max() > 1e-3  # the draws changed the motion
        # the last world's model is the CPU env's of the same (last) episode, constants too
        mine, ref = batch.state.batch.get_model(WORLDS - 1), env.scene.model
        for name in (
            "body_mass",
            "body_inertia",
            "body_ipos",
            "geom_friction",
            "dof_damping",
            "dof_armature",
            "actuator_gainprm",
            "body_subtreemass",
            "dof_invweight0",
        ):
            assert np.array_equal(getattr(mine, name), getattr(ref, name)), name
            assert not np.array_equal(getattr(mine, name), getattr(plain.host.scene.model, name))
        assert np.array_equal(mine.opt.gravity, ref.opt.gravity)
    finally:
        batch.close()
        plain.close()
        env.close()


def _assert_cartesian_episodes_match(task_id: str, seed: int, **kwargs: Any) -> int:
    """The batch's states and rewards against the CPU env's over `_actions(..., seed)`, both
    made with `kwargs` and a 0.5 s time limit; returns the action's length."""
    batch = make_batch(task_id, WORLDS, device="cpu", time_limit=0.5, **kwargs)
    env = gym.make(task_id, time_limit=0.5, **kwargs).unwrapped
    try:
        actions = _actions(len(batch.action_labels), seed)
        ref_q, ref_r = _cpu_states(env, actions)
        q, r, _ = _batch_states(batch, actions)
        assert np.abs(q - ref_q).max() < CARTESIAN_TOL
        assert np.abs(r - ref_r).max() < REWARD_TOL
        return len(batch.action_labels)
    finally:
        batch.close()
        env.close()


@pytest.mark.parametrize("task_id", sorted(registry.TASKS))
def test_cartesian_episodes_match_within_rounding(task_id: str) -> None:
    _assert_cartesian_episodes_match(task_id, 1)


@pytest.mark.parametrize("task", ["PickCube", "Push", "PickAndPlace", "Stack"])
def test_shaped_rewards_and_translation_actions_match_the_cpu_env(task: str) -> None:
    """The CPU recipe's task parameters (`OBJECT_CPU`): the shaped reward evaluated in torch
    on the batch pays what the CPU env pays, the 4-entry action moving both alike."""
    kwargs = {"cartesian_axes": "vx,vy,vz", "reward_type": "shaped"}
    assert _assert_cartesian_episodes_match(f"mjkdl/Panda{task}-v0", 2, **kwargs) == 4


def test_pushing_with_the_gripper_blocked_matches_the_cpu_env() -> None:
    """Push with `block_gripper` and the CPU recipe's action: the fingers held closed, out of
    the 3-entry action, in every world as in the CPU env."""
    kwargs = {"cartesian_axes": "vx,vy,vz", "reward_type": "shaped", "block_gripper": True}
    assert _assert_cartesian_episodes_match("mjkdl/PandaPush-v0", 3, **kwargs) == 3


def test_any_thread_count_gives_the_same_states() -> None:
    actions = _actions(8, 2)
    runs = []
    for threads in (1, 2):
        batch = make_batch(PICK, WORLDS, device="cpu", threads=threads, actuation="joint_position")
        try:
            assert batch.state.threads == threads
            runs.append(_batch_states(batch, actions)[0])
        finally:
            batch.close()
    assert np.array_equal(runs[0], runs[1])


def test_tensors_share_memory_with_the_batch() -> None:
    """No copy per step: the tensors are the batch's own arrays."""
    batch = make_batch("mjkdl/PandaReach-v0", 2, device="cpu")
    try:
        batch.reset(seed=0)
        s = batch.state
        for name in ("qpos", "ctrl", "xpos", "cvel", "qfrc_actuator"):
            assert getattr(s, name).data_ptr() == s.batch.bind(name).ctypes.data, name
        s.qpos[1, 0] = 0.25
        assert s.batch.bind("qpos")[1, 0] == 0.25
        obs, *_ = batch.step(torch.zeros(2, 7))
        assert obs["panda_tcp_pos"].dtype == torch.float64
    finally:
        batch.close()


def test_the_device_chooses_the_engine_and_threads_default_to_the_cores() -> None:
    if torch.cuda.is_available():
        pytest.skip("this machine has a GPU: make_batch() without a device takes it")
    batch = make_batch("mjkdl/PandaReach-v0", 1)
    try:
        assert batch.device.type == "cpu" and batch.state.name == "mujoco"
        assert batch.state.threads == available_threads() >= 1
    finally:
        batch.close()


def test_a_gpu_without_mujoco_warp_is_named_and_no_device_falls_back(monkeypatch) -> None:
    """torch sees a GPU, but only the `batch` extra is installed: `device="cuda"` names the
    missing extra; no device runs the CPU engine with a warning that says why."""
    from mjkdl.task.batch import DeviceUnavailableError, warp_engine

    def missing() -> None:
        raise ImportError("No module named 'mujoco_warp'")

    monkeypatch.setattr(torch.cuda, "is_available", lambda: True)
    monkeypatch.setattr(warp_engine, "warp_modules", missing)
    with pytest.raises(DeviceUnavailableError, match=r"MuJoCo Warp is not installed.*\[warp\]"):
        make_batch("mjkdl/PandaReach-v0", 1, device="cuda")
    with pytest.warns(UserWarning, match=r"MuJoCo Warp is not installed.*running on the CPU"):
        batch = make_batch("mjkdl/PandaReach-v0", 1)
    assert batch.state.name == "mujoco"
    batch.close()


def test_a_world_whose_physics_fails_ends_as_diverged() -> None:
    """A non-finite state in one world ends its episode (reward 0, `diverged`), the others
    step on, and the world starts its next episode."""
    batch = make_batch(PICK, 2, device="cpu", actuation="joint_torque")
    try:
        batch.reset(seed=0)
        batch.state.qvel[1, 0] = float("inf")
        _, reward, terminated, _, info = batch.step(torch.zeros(2, 8))
        assert info["diverged"].tolist() == [False, True]
        assert terminated.tolist() == [False, True] and float(reward[1]) == 0.0
        assert bool(torch.isfinite(batch.state.qvel).all())  # restarted
    finally:
        batch.close()


def test_a_world_where_mujoco_raises_ends_as_diverged_with_its_message() -> None:
    """MuJoCo's batch reports the simulations that raised (they keep their state, the others
    step on): those worlds' episodes end, a warning quotes MuJoCo's message, and they start
    clean."""
    batch = make_batch(PICK, 2, device="cpu")
    real = batch.state.batch

    class Failing:  # world 1 raises in the next step, as an arena overflow would
        def __getattr__(self, name: str) -> object:
            return getattr(real, name)

        def step(self, ids: object = None, **kwargs: int) -> None:
            real.step(ids, **kwargs)
            raise mujoco.batch.SimulationError(np.array([1]), "1 simulation failed")

        def error(self, sim: int) -> str:
            return "mj_stackAlloc: out of memory" if sim == 1 else ""

    try:
        batch.reset(seed=0)
        batch.state.batch = Failing()
        with pytest.warns(UserWarning, match=r"error in 1 of 2 worlds \(world 1: mj_stackAlloc"):
            _, reward, terminated, _, info = batch.step(torch.zeros(2, 7))
        assert info["diverged"].tolist() == [False, True]
        assert terminated.tolist() == [False, True] and float(reward[1]) == 0.0
        batch.state.batch = real
        assert batch.state.failed().tolist() == [False, False]  # the new episode starts clean
        _, _, _, _, info = batch.step(torch.zeros(2, 7))
        assert info["diverged"].tolist() == [False, False]
    finally:
        batch.state.batch = real
        batch.close()


# ---------------------------------------------------------------------- bad input


def test_bad_engine_threads_and_warp_only_fields() -> None:
    with pytest.raises(SpecError, match=r"engine must be one of \['mujoco', 'warp'\]"):
        make_batch("mjkdl/PandaReach-v0", 1, device="cpu", engine="physx")
    with pytest.raises(SpecError, match=r"engine='mujoco'.*runs on the CPU, not 'cuda:0'"):
        make_batch("mjkdl/PandaReach-v0", 1, device="cuda:0", engine="mujoco", allow_cpu=True)
    with pytest.raises(SpecError, match="threads must be a positive integer, got 0"):
        make_batch("mjkdl/PandaReach-v0", 1, device="cpu", threads=0)
    with pytest.raises(SpecTypeError, match=r"threads must be a positive integer, got 1\.5"):
        make_batch("mjkdl/PandaReach-v0", 1, device="cpu", threads=1.5)
    with pytest.raises(SpecError, match="njmax=64 sizes MuJoCo Warp's buffers"):
        make_batch("mjkdl/PandaReach-v0", 1, device="cpu", njmax=64)


def test_the_impedance_drive_is_refused_by_name() -> None:
    """Its ramp and rate limiter run on one env: the batch would drive the actuators without
    them, silently another arm."""
    with pytest.raises(SpecError, match="make_batch: arm_drive='franka_impedance' runs on one"):
        make_batch("mjkdl/PandaPickCube-v0", 2, device="cpu", arm_drive="franka_impedance")


def test_mass_draws_on_bodies_that_gravcomp_holds_are_refused() -> None:
    """The CPU env keeps their compensation nominal per draw (`body_gravcomp`), which the
    engines do not carry per world."""
    drive = gym.make(PICK, arm_drive="franka_impedance", randomization={"body_mass": [0.8, 1.2]})
    spec = drive.unwrapped.task_spec  # the Panda with its impedance (gravcomp) built in
    drive.close()
    with pytest.raises(UnsupportedFeatureError, match=r"randomization\.body_mass: .*gravcomp"):
        make_batch(spec, 1, device="cpu")


def test_cameras_are_refused_with_the_engine_that_renders_them() -> None:
    spec = registry.panda_reach_spec()
    spec.sensors = [*spec.sensors, CameraSensor("front", 32, 32)]
    with pytest.raises(UnsupportedFeatureError, match=r"sensors\[2\].*engine='warp'"):
        make_batch(spec, 1, device="cpu")


@pytest.mark.parametrize(
    ("engine", "field", "value", "where"),
    [
        ("mujoco", "camera_fovy", [-5, 5], r"only the CPU env \(TaskEnv\) draws it"),
        ("mujoco", "action_noise", 0.1, r"only the CPU env \(TaskEnv\) draws it"),
        ("warp", "camera_fovy", [-5, 5], r"only the CPU env \(TaskEnv\) draws it"),
        ("warp", "body_com", [-0.01, 0.01], "engine='mujoco' draws it per world"),
    ],
)
def test_a_randomization_the_engine_cannot_draw_is_refused_by_field(
    engine: str, field: str, value: object, where: str
) -> None:
    with pytest.raises(
        UnsupportedFeatureError,
        match=rf"TaskSpec\.randomization\.{field}: engine='{engine}' does not draw it per "
        rf"world; {where}",
    ):
        make_batch(PICK, 1, device="cpu", engine=engine, randomization={field: value})


def test_the_memory_estimate_counts_available_memory(monkeypatch) -> None:
    """Huge batches are refused before allocating, against `MemAvailable` (free memory and
    the page cache the kernel can reclaim), not only the free pages."""
    from mjkdl.task.batch import env as batch_env

    available = batch_env._free_bytes("cpu")
    with open("/proc/meminfo") as f:
        fields = {line.split(":")[0]: int(line.split()[1]) * 1024 for line in f}
    assert abs(available - fields["MemAvailable"]) < 2**28  # it moves a little meanwhile
    monkeypatch.setattr(batch_env, "_free_bytes", lambda device: 2**30)
    with pytest.raises(
        SpecError,
        match=r"num_envs=10000000 needs about .* of the 1\.00 GiB available; use at most about "
        r"\d+ worlds",
    ):
        make_batch("mjkdl/PandaReach-v0", 10**7, device="cpu")


def test_joint_actuation_spec_runs_in_the_batch() -> None:
    """A `TaskSpec` (not an id) with a joint actuation, the model's timestep kept."""
    spec = registry.panda_pick_cube_spec()
    spec.arms[0].actuation = Actuation.JOINT_POSITION
    batch = make_batch(spec, 1, device="cpu")
    try:
        model = batch.host.scene.model
        assert batch.state.batch.get_model(0).opt.timestep == model.opt.timestep
        assert mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_INTEGRATION) == (
            batch.state.batch.nstate
        )
    finally:
        batch.close()


_CHAIN = """
<mujoco>
  <worldbody>
    <body name="base" pos="0.1 -0.2 0.3" quat="0.9 0.1 0.3 -0.2">
      <body name="l1" pos="0 0 0.2" quat="0.7 0.7 0 0">
        <joint name="j1" type="hinge" axis="0 0 1"/>
        <geom size="0.05" mass="1"/>
        <body name="l2" pos="0.3 0 0">
          <joint name="j2" type="slide" axis="1 0.5 0"/>
          <geom size="0.05" mass="1"/>
          <body name="fixed" pos="0 0.1 0" quat="0.8 0 0.6 0">
            <geom size="0.05" mass="1"/>
            <body name="l3" pos="0.2 0 0" quat="0.6 0 0 0.8">
              <joint name="j3" type="hinge" axis="0 1 1" pos="0 0 0.1"/>
              <geom size="0.05" mass="1"/>
              <site name="tcp" pos="0.05 0.02 0.1" quat="0.5 0.5 0.5 0.5"/>
            </body>
          </body>
        </body>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


def test_the_chain_kinematics_is_mujocos_with_slides_and_hinges_off_their_origin() -> None:
    """The QP's Jacobian comes from the chain walked in torch: anchors, axes and the TCP at
    given joint positions equal MuJoCo's `mj_kinematics` there, for a hinge about an axis off
    its body's origin, a slide, and a body without a joint between them."""
    from types import SimpleNamespace

    from mjkdl.task.batch.control import ChainKinematics
    from mjkdl.task.batch.engine import Tcp

    model = mujoco.MjModel.from_xml_string(_CHAIN)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    jids = [model.joint(n).id for n in ("j1", "j2", "j3")]
    site = model.site("tcp").id
    offset = np.array([0.01, -0.02, 0.03])
    tcp = Tcp(site, int(model.site_bodyid[site]), torch.as_tensor(offset), torch.eye(3))
    rng = np.random.default_rng(0)
    q = rng.uniform(-1.5, 1.5, (5, 3))
    base = model.body("base").id
    state = SimpleNamespace(
        device="cpu",
        dtype=torch.float64,
        xpos=torch.as_tensor(np.repeat(data.xpos[None], 5, 0)),
        xmat=torch.as_tensor(np.repeat(data.xmat.reshape(1, -1, 3, 3), 5, 0)),
    )
    arm = SimpleNamespace(name="toy", prefix="", base_body="l1", tip_body="l3")
    chain = ChainKinematics(model, arm, jids, tcp, state)  # type: ignore[arg-type]
    anchors, axes, at = (x.numpy() for x in chain(torch.as_tensor(q)))
    assert int(model.body_parentid[model.body("l1").id]) == base
    for w in range(5):
        data.qpos[:] = q[w]
        mujoco.mj_kinematics(model, data)
        np.testing.assert_allclose(anchors[w], data.xanchor[jids], atol=1e-14)
        np.testing.assert_allclose(axes[w], data.xaxis[jids], atol=1e-14)
        want = data.site_xpos[site] + data.site_xmat[site].reshape(3, 3) @ offset
        np.testing.assert_allclose(at[w], want, atol=1e-14)
