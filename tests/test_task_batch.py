"""The batch's MuJoCo Warp engine on Warp's CPU device, against the CPU env (`TaskEnv`)."""

from __future__ import annotations

import os
import sys

import gymnasium as gym
import numpy as np
import pytest
from conftest import import_extra

torch = import_extra("warp", "torch")

from mjkdl.errors import MjkdlError, SpecError, SpecTypeError  # noqa: E402
from mjkdl.task import make_batch, registry  # noqa: E402
from mjkdl.task.batch import DeviceUnavailableError  # noqa: E402
from mjkdl.task.batch.engine import UnsupportedFeatureError, mat_to_quat  # noqa: E402
from mjkdl.task.env import TaskEnv  # noqa: E402
from mjkdl.task.experts import expert_for  # noqa: E402
from mjkdl.task.initializers import PhysicsRandomizer  # noqa: E402
from mjkdl.task.randomization import Randomization  # noqa: E402
from mjkdl.task.rewards import batchable  # noqa: E402
from mjkdl.task.spec import Actuation, CameraSensor  # noqa: E402

WARP = {"device": "cpu", "engine": "warp"}  # MuJoCo Warp's CPU device (the GPU's kernels)
WORLDS = 2
STEPS = 4  # control steps per episode (time_limit 0.4 s at 0.1 s): a whole short episode
SEED = 7
# Tolerances over a whole episode of full-range random actions (the controller's velocity
# and acceleration bounds bind), float32 MuJoCo Warp against float64 MuJoCo: positions in
# metres and joint positions in radians (measured: at most 7e-7), rewards (2e-7).
POS_TOL = 1e-5
JOINT_TOL = 1e-5
REWARD_TOL = 1e-5
PANDA_HOME = np.array(registry.PANDA_HOME)


def _cpu_episode(env: TaskEnv, seed: int, actions: np.ndarray) -> list:
    obs, info = env.reset(seed=seed)
    out = [(obs, 0.0, info["is_success"])]
    for a in actions:
        obs, reward, _, _, info = env.step(a)
        out.append((obs, reward, info["is_success"]))
    return out


def _positions(obs: dict) -> list[str]:
    return [k for k in obs if k.endswith(("_tcp_pos", "_pose", "_rel", "goal"))]


def _compare(batch, cpu_env: TaskEnv, actions: np.ndarray) -> tuple[dict[str, float], dict]:
    """Worst gaps of one whole episode per world: positions, rewards, success mismatches;
    and the observation the last step returned (the next episode's, after auto-reset)."""
    episodes = [_cpu_episode(cpu_env, SEED + i, actions[:, i]) for i in range(WORLDS)]
    obs, info = batch.reset(seed=SEED)
    gaps = {"pos": 0.0, "joint": 0.0, "reward": 0.0, "success": 0.0, "done": 0.0}

    def check(k: int, obs: dict, reward: np.ndarray, success: np.ndarray) -> None:
        for i in range(WORLDS):
            ref, ref_reward, ref_success = episodes[i][k]
            for key in _positions(ref):
                gap = np.abs(obs[key][i].numpy() - ref[key]).max()
                gaps["pos"] = max(gaps["pos"], float(gap))
            for key in (k for k in ref if k.endswith("_joint_pos")):
                gap = np.abs(obs[key][i].numpy() - ref[key]).max()
                gaps["joint"] = max(gaps["joint"], float(gap))
            gaps["reward"] = max(gaps["reward"], abs(float(reward[i]) - ref_reward))
            gaps["success"] += float(bool(success[i]) != ref_success)

    check(0, obs, np.zeros(WORLDS), info["is_success"].numpy())
    returned: dict = {}
    for k in range(STEPS):
        returned, reward, terminated, truncated, info = batch.step(torch.as_tensor(actions[k]))
        obs = returned
        done = (terminated | truncated).numpy()
        if done.any():
            obs = info["final_obs"]
            success = info["final_info"]["is_success"]
        else:
            success = info["is_success"]
        gaps["done"] += float(done.any() != (k == STEPS - 1))
        check(k + 1, obs, reward.numpy(), success.numpy())
    return gaps, returned


@pytest.mark.parametrize("task_id", sorted(registry.TASKS))
def test_registered_tasks_match_the_cpu_env(task_id: str) -> None:
    batch = make_batch(task_id, WORLDS, **WARP, time_limit=0.4)
    cpu_env = gym.make(task_id, time_limit=0.4).unwrapped
    try:
        # The task's rules are evaluated for all worlds as torch operations on the device.
        spec = batch.host.task_spec
        rules = [r for r in (spec.reward, spec.success, spec.terminated) if r is not None]
        assert rules and all(batchable(r) for r in rules), rules
        rng = np.random.default_rng(0)
        n = len(batch.action_labels)
        actions = rng.uniform(-1.0, 1.0, (STEPS, WORLDS, n)).astype(np.float32)
        actions[..., -1] = 1.0  # the gripper closes (binary) in the last entry
        gaps, _ = _compare(batch, cpu_env, actions)
        assert gaps["pos"] < POS_TOL, gaps
        assert gaps["joint"] < JOINT_TOL, gaps
        assert gaps["reward"] < REWARD_TOL, gaps
        assert gaps["success"] == 0 and gaps["done"] == 0, gaps
    finally:
        batch.close()
        cpu_env.close()


def test_joint_position_mode_matches_and_auto_resets() -> None:
    spec = registry.panda_pick_cube_spec()
    spec.arms[0].actuation = Actuation.JOINT_POSITION
    spec.time_limit = 0.4
    batch = make_batch(spec, WORLDS, **WARP)
    cpu_env = TaskEnv(spec)
    try:
        rng = np.random.default_rng(1)
        # Normalised joint targets around home, the gripper closing.
        low, high = cpu_env.action_bounds
        mid, half = 0.5 * (low + high)[:7], 0.5 * (high - low)[:7]
        home = (PANDA_HOME - mid) / half
        actions = np.empty((STEPS, WORLDS, 8), dtype=np.float32)
        actions[..., :7] = home + rng.uniform(-0.05, 0.05, (STEPS, WORLDS, 7))
        actions[..., 7] = 1.0
        gaps, returned = _compare(batch, cpu_env, actions)
        assert gaps["pos"] < POS_TOL and gaps["joint"] < JOINT_TOL, gaps
        assert gaps["reward"] < REWARD_TOL, gaps
        # The episode ended in the last step and every world started its next one at once,
        # the one the CPU env starts with its next reset() after the seeded episode.
        assert batch.episode_steps.tolist() == [0] * WORLDS
        for i in range(WORLDS):
            cpu_env.reset(seed=SEED + i)
            for a in actions[:, i]:
                cpu_env.step(a)
            second, _ = cpu_env.reset()
            gap = np.abs(returned["cube_pose"][i].numpy() - second["cube_pose"]).max()
            assert gap < POS_TOL, (i, gap)
    finally:
        batch.close()
        cpu_env.close()


def test_each_world_draws_the_cpu_envs_randomization_for_its_seed() -> None:
    """World i's episode is the CPU env's for seed s + i with its draw of the physical fields
    and the latency, within float32's tolerances (the draw moves it well beyond them)."""
    spec = registry.panda_pick_cube_spec()
    spec.arms[0].actuation = Actuation.JOINT_POSITION
    spec.time_limit = 0.4
    plain = TaskEnv(spec)
    spec.randomization = Randomization.coerce(
        {
            "body_mass": [0.5, 2.0],
            "geom_friction": [0.7, 1.3],
            "joint_damping": [0.5, 2.0],
            "joint_armature": [0.5, 2.0],
            "actuator_gain": [0.8, 1.2],
            "gravity": [-0.5, 0.5],
            "action_latency": [0, 2],
        }
    )
    batch = make_batch(spec, WORLDS, **WARP)
    cpu_env = TaskEnv(spec)
    try:
        rng = np.random.default_rng(3)
        low, high = cpu_env.action_bounds
        mid, half = 0.5 * (low + high)[:7], 0.5 * (high - low)[:7]
        actions = np.empty((STEPS, WORLDS, 8), dtype=np.float32)
        actions[..., :7] = (PANDA_HOME - mid) / half + rng.uniform(-0.1, 0.1, (STEPS, WORLDS, 7))
        actions[..., 7] = 1.0
        gaps, _ = _compare(batch, cpu_env, actions)
        assert gaps["pos"] < POS_TOL and gaps["joint"] < JOINT_TOL, gaps
        assert gaps["reward"] < REWARD_TOL, gaps
        nominal, _ = _compare(batch, plain, actions)
        assert nominal["joint"] > 100 * JOINT_TOL, nominal
    finally:
        batch.close()
        cpu_env.close()
        plain.close()


@pytest.mark.parametrize("variant", ["joint_velocity", "joint_torque", "top_down"])
def test_joint_velocity_torque_and_top_down_actions_match(variant: str) -> None:
    """The joint velocity and torque modes, and the top-down Cartesian action
    (`cartesian_axes`: the batch fills the omitted twist entries with zeros, as the CPU env)."""
    spec = registry.panda_pick_cube_spec()
    rng = np.random.default_rng(2)
    if variant == "top_down":
        spec.arms[0].cartesian_axes = ("vx", "vy", "vz", "wz")
        actions = rng.uniform(-1, 1, (STEPS, WORLDS, 5))
    else:
        spec.arms[0].actuation = Actuation(variant)
        # Normalised: 0 is zero velocity, or gravity compensation alone.
        actions = rng.uniform(-0.05, 0.05, (STEPS, WORLDS, 8))
    spec.time_limit = 0.4
    batch = make_batch(spec, WORLDS, **WARP)
    cpu_env = TaskEnv(spec)
    try:
        assert batch.single_action_space.shape == actions.shape[2:]
        gaps, _ = _compare(batch, cpu_env, actions.astype(np.float32))
        assert gaps["pos"] < POS_TOL and gaps["joint"] < JOINT_TOL, gaps
        assert gaps["reward"] < REWARD_TOL and gaps["success"] == 0, gaps
    finally:
        batch.close()
        cpu_env.close()


def _tcp_height(obs: dict) -> float:
    return float(obs["panda_tcp_pos"][2])


def test_a_plain_callable_runs_on_the_host() -> None:
    """A reward without `evaluate` (no `ArrayRule`) is called world by world."""
    spec = registry.panda_reach_spec()
    spec.reward = _tcp_height
    spec.time_limit = 0.4
    batch = make_batch(spec, WORLDS, **WARP)
    cpu_env = TaskEnv(spec)
    try:
        actions = np.random.default_rng(4).uniform(-1, 1, (STEPS, WORLDS, 7)).astype(np.float32)
        gaps, _ = _compare(batch, cpu_env, actions)
        assert gaps["pos"] < POS_TOL and gaps["reward"] < REWARD_TOL, gaps
    finally:
        batch.close()
        cpu_env.close()


def _joint_trajectory(batch, actions: np.ndarray) -> torch.Tensor:
    batch.reset(seed=SEED)
    out = []
    for a in actions:
        obs, *_ = batch.step(torch.as_tensor(a))
        out.append(obs["panda_joint_pos"].clone())
    return torch.stack(out)


def test_the_physics_replays_as_a_graph_and_a_failed_capture_only_warns(monkeypatch) -> None:
    """From the second step on the physics replays as one captured graph: the same numbers
    as launching the kernels one by one, across an auto-reset; if Warp cannot capture, the
    batch says why and launches them one by one."""
    import warp as wp

    actions = np.random.default_rng(5).uniform(-1, 1, (6, WORLDS, 7)).astype(np.float32)
    captured = make_batch("mjkdl/PandaPickCube-v0", WORLDS, **WARP, time_limit=0.4)
    try:
        ref = _joint_trajectory(captured, actions)
        assert captured.state.captured
    finally:
        captured.close()

    def refuse(*args: object, **kwargs: object) -> None:
        raise RuntimeError("graphs refused here")

    monkeypatch.setattr(wp, "ScopedCapture", refuse)
    eager = make_batch("mjkdl/PandaPickCube-v0", WORLDS, **WARP, time_limit=0.4)
    try:
        with pytest.warns(UserWarning, match=r"could not be captured as a graph \(graphs refused"):
            got = _joint_trajectory(eager, actions)
        assert not eager.state.captured
    finally:
        eager.close()
    assert torch.equal(ref, got)


@pytest.mark.parametrize("workers", [0, 2], ids=["in-process", "2-workers"])
def test_every_restart_is_the_cpu_envs_next_reset(workers: int) -> None:
    """Each world's next start is computed ahead (while the device steps), in this process or
    by reset workers; over three episodes a world starts exactly where the CPU env's resets
    after `reset(seed)` do, and a second `reset(seed)` starts the first episodes again."""
    batch = make_batch(
        "mjkdl/PandaPickCube-v0", WORLDS, **WARP, time_limit=0.2, reset_workers=workers
    )
    procs = [w._proc for w in batch.starts._workers]
    assert len(procs) == workers
    cpu_env = gym.make("mjkdl/PandaPickCube-v0", time_limit=0.2).unwrapped
    try:
        first, _ = batch.reset(seed=SEED)
        starts = [first["cube_pose"].clone()]
        zero = torch.zeros(WORLDS, 7)
        for _ in range(4):  # two episodes of two steps
            obs, _, terminated, truncated, _ = batch.step(zero)
            if bool((terminated | truncated).all()):
                starts.append(obs["cube_pose"].clone())
        assert len(starts) == 3
        for i in range(WORLDS):
            for k in range(3):
                ref = cpu_env.reset(seed=SEED + i)[0] if k == 0 else cpu_env.reset()[0]
                gap = np.abs(starts[k][i].numpy() - ref["cube_pose"]).max()
                assert gap < POS_TOL, (i, k, gap)
        again, _ = batch.reset(seed=SEED)
        assert torch.equal(again["cube_pose"], first["cube_pose"])
    finally:
        batch.close()
        cpu_env.close()
    assert [p.poll() for p in procs] == [0] * workers  # the workers ended with the batch


def test_a_dead_reset_worker_is_named() -> None:
    batch = make_batch("mjkdl/PandaReach-v0", 2, **WARP, time_limit=0.1, reset_workers=1)
    try:
        batch.reset(seed=0)
        batch.starts._workers[0]._proc.kill()
        with pytest.raises(MjkdlError, match=r"reset worker 0 ended \(exit code -9\)"):
            batch.step(torch.zeros(2, 7))  # the episodes end: their starts are needed
    finally:
        batch.close()


class _FailsInOtherProcesses:
    """An initializer that works in the test's process and raises in any other."""

    def __init__(self) -> None:
        self.pid = os.getpid()

    def __call__(self, env: TaskEnv, rng: np.random.Generator) -> None:
        if os.getpid() != self.pid:
            raise ValueError("this initializer runs in the test's process only")


def test_a_reset_workers_error_is_raised_with_its_own_message() -> None:
    """The worker rebuilds the task from this test module (the import path travels with it),
    and its reset's own error reaches the batch."""
    spec = registry.panda_reach_spec()
    spec.initializers = [*spec.initializers, _FailsInOtherProcesses()]
    with pytest.raises(MjkdlError, match=r"reset worker 0 failed: ValueError: this initializer"):
        make_batch(spec, 1, **WARP, reset_workers=1)


class ScriptReward:
    def __call__(self, obs: dict) -> float:
        return 0.0


def test_reset_workers_refuse_what_the_running_script_defines(monkeypatch) -> None:
    """Pickled by reference to `__main__`, which a worker does not run."""
    monkeypatch.setattr(ScriptReward, "__module__", "__main__")
    monkeypatch.setattr(sys.modules["__main__"], "ScriptReward", ScriptReward, raising=False)
    spec = registry.panda_reach_spec()
    spec.reward = ScriptReward()
    with pytest.raises(SpecError, match=r"defined in the running script \(__main__\)"):
        make_batch(spec, 1, **WARP, reset_workers=1)


def test_reset_workers_need_a_picklable_task() -> None:
    spec = registry.panda_reach_spec()
    spec.reward = lambda obs: 0.0
    with pytest.raises(SpecError, match=r"cannot be pickled.*reset_workers=0"):
        make_batch(spec, 1, **WARP, reset_workers=1)
    from mjkdl.task.batch import BatchEnv

    host = TaskEnv(registry.panda_reach_spec())
    with pytest.raises(SpecError, match="reset workers need `maker`"):
        BatchEnv(host, 1, "cpu", engine="warp", reset_workers=1)
    host.close()


def _expert_episode(task_id: str, seed: int) -> tuple[np.ndarray, list[np.ndarray]]:
    """The expert's actions over a whole CPU-env episode, and the cube's position after each."""
    env = gym.make(task_id)
    expert = expert_for(env)
    obs, _ = env.reset(seed=seed)
    actions, cubes = [], []
    for _ in range(100):
        actions.append(expert(obs))
        obs, _, terminated, truncated, info = env.step(actions[-1])
        cubes.append(obs["cube_pose"][:3].copy())
        if terminated or truncated:
            break
    env.close()
    assert info["is_success"], "the expert failed on the CPU env"
    return np.array(actions), cubes


def test_a_whole_grasp_and_lift_matches_the_cpu_env() -> None:
    """The expert's PickCube episode (grasp, lift, hold) replayed in the batch: the cube
    follows the CPU env's within 1e-4 m at every step, and the batch ends the episode with
    success in the same step."""
    actions, cubes = _expert_episode("mjkdl/PandaPickCube-v0", 3)
    batch = make_batch("mjkdl/PandaPickCube-v0", 1, **WARP)
    try:
        batch.reset(seed=3)
        for k, a in enumerate(actions):
            obs, _, terminated, _, info = batch.step(torch.as_tensor(a)[None])
            if k < len(actions) - 1:
                gap = np.abs(obs["cube_pose"][0, :3].numpy() - cubes[k]).max()
                assert gap < 1e-4 and not bool(terminated[0]), (k, gap)
        assert bool(terminated[0]) and bool(info["final_info"]["is_success"][0])
        final = info["final_obs"]["cube_pose"][0, :3].numpy()
        assert np.abs(final - cubes[-1]).max() < 1e-4
        assert cubes[-1][2] > 0.05  # lifted
    finally:
        batch.close()


def test_a_world_out_of_constraint_rows_diverges_and_the_warning_names_the_fix() -> None:
    """MuJoCo Warp drops the constraint rows that do not fit: with the grasp's 129 rows in 64
    (MuJoCo Warp's own default for this scene) the world's episode ends as diverged, with a
    warning that names the fix, and its next episode starts clean."""
    actions, _ = _expert_episode("mjkdl/PandaPickCube-v0", 3)
    batch = make_batch("mjkdl/PandaPickCube-v0", 1, **WARP, njmax=64)
    try:
        batch.reset(seed=3)
        with pytest.warns(UserWarning, match=r"world 0: NEFC.*larger njmax.*now 64"):
            steps = 0
            for a in actions:
                _, reward, terminated, _, info = batch.step(torch.as_tensor(a)[None])
                steps += 1
                if bool(info["diverged"][0]):
                    break
        assert 1 < steps < len(actions), steps  # in the grasp, before the lift succeeded
        assert bool(terminated[0]) and float(reward[0]) == 0.0
        assert not bool(info["is_success"][0]) and int(batch.episode_steps[0]) == 0
        assert not bool(batch.state.failed()[0])  # the next episode starts clean
    finally:
        batch.close()


def test_steps_inside_inference_mode_then_a_reset_outside() -> None:
    """rsl-rl collects rollouts under `torch.inference_mode()`; the batch's own state must
    stay writable by a reset outside it."""
    batch = make_batch("mjkdl/PandaPickCube-v0", WORLDS, **WARP, time_limit=0.2)
    try:
        batch.reset(seed=0)
        with torch.inference_mode():
            for _ in range(3):  # across an auto-reset
                batch.step(torch.full((WORLDS, 7), 0.5))
        obs, _ = batch.reset(seed=0)
        assert obs["panda_joint_pos"].shape == (WORLDS, 7)
        batch.step(torch.zeros(WORLDS, 7))
    finally:
        batch.close()


def test_observations_are_device_tensors_and_the_vector_face() -> None:
    batch = make_batch("mjkdl/PandaReach-v0", 3, **WARP)
    try:
        obs, info = batch.reset(seed=0)
        assert isinstance(batch, gym.vector.VectorEnv)
        assert batch.num_envs == 3
        assert batch.action_space.shape == (3, 7)
        assert obs["panda_tcp_pos"].shape == (3, 3)
        assert obs["panda_tcp_pos"].device.type == "cpu"
        assert info["is_success"].dtype == torch.bool
        # Zero-copy: the torch view is Warp's array.
        batch.state.qpos[0, 0] = 0.25
        assert float(batch.state.data.qpos.numpy()[0, 0]) == pytest.approx(0.25)
    finally:
        batch.close()


def test_mat_to_quat_matches_mujoco() -> None:
    import mujoco

    rng = np.random.default_rng(3)
    quats = rng.normal(size=(64, 4))
    quats /= np.linalg.norm(quats, axis=1, keepdims=True)
    mats = np.empty((64, 9))
    for q, m in zip(quats, mats, strict=True):
        mujoco.mju_quat2Mat(m, q)
    ref = np.empty((64, 4))
    for m, out in zip(mats, ref, strict=True):
        mujoco.mju_mat2Quat(out, m)
    got = mat_to_quat(torch.as_tensor(mats, dtype=torch.float64).reshape(-1, 3, 3)).numpy()
    assert np.abs(got - ref).max() < 1e-12


# ---------------------------------------------------------------------- bad input


def test_cuda_without_a_gpu_names_the_fix() -> None:
    import warp as wp

    if wp.get_cuda_device_count() > 0 and torch.cuda.is_available():
        pytest.skip("this machine has a GPU")
    with pytest.raises(DeviceUnavailableError, match=r"device='cpu'.*allow_cpu=True"):
        make_batch("mjkdl/PandaReach-v0", 2, device="cuda")
    with pytest.warns(UserWarning, match="running on the CPU"):
        batch = make_batch("mjkdl/PandaReach-v0", 1, device="cuda:0", allow_cpu=True)
    assert batch.device.type == "cpu" and batch.state.name == "mujoco"  # the CPU engine
    batch.close()


@pytest.mark.parametrize(
    ("num_envs", "match"),
    [(0, "positive integer, got 0"), (-3, "positive integer"), (10**9, "GiB.*at most about")],
)
def test_bad_num_envs(num_envs: int, match: str) -> None:
    with pytest.raises(SpecError, match=match):
        make_batch("mjkdl/PandaReach-v0", num_envs, **WARP)


@pytest.mark.parametrize(
    ("value", "error"), [(-1, SpecError), (1.5, SpecTypeError), (True, SpecTypeError)]
)
def test_bad_reset_workers(value: object, error: type) -> None:
    with pytest.raises(error, match="reset_workers must be"):
        make_batch("mjkdl/PandaReach-v0", 1, **WARP, reset_workers=value)


@pytest.mark.parametrize("field", ["njmax", "nconmax"])
@pytest.mark.parametrize("value", [0, -8, 2.5, True])
def test_bad_buffer_sizes(field: str, value: object) -> None:
    with pytest.raises(SpecError, match=f"{field} must be a positive integer"):
        make_batch("mjkdl/PandaReach-v0", 1, **WARP, **{field: value})


def test_bad_device_and_task() -> None:
    with pytest.raises(SpecError, match="'cuda', 'cuda:N' or 'cpu'"):
        make_batch("mjkdl/PandaReach-v0", 1, device="tpu")
    with pytest.raises(SpecError, match="no registered task 'nope'"):
        make_batch("nope", 1, **WARP)


def test_unsupported_scene_feature_is_named() -> None:
    import mujoco

    from mjkdl.task.batch.warp_engine import warp_model

    model = mujoco.MjModel.from_xml_string(
        "<mujoco><option integrator='RK4' noslip_iterations='2'/><worldbody><body>"
        "<freejoint/><geom size='.1'/></body></worldbody></mujoco>"
    )
    model.opt.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    model.opt.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
    model.opt.solver = mujoco.mjtSolver.mjSOL_PGS
    with pytest.raises(UnsupportedFeatureError, match="mjSOL_PGS is unsupported"):
        warp_model(model)


def test_physics_randomizer_reflections_and_a_camera_twice_are_refused() -> None:
    spec = registry.panda_pick_cube_spec()
    spec.initializers = [*spec.initializers, PhysicsRandomizer(["cube"], mass_scale=(0.5, 2))]
    with pytest.raises(UnsupportedFeatureError, match=r"initializers\[1\] \(PhysicsRandomizer\)"):
        make_batch(spec, 1, **WARP)
    spec = registry.panda_reach_spec()
    spec.sensors = [*spec.sensors, CameraSensor("front", 32, 32, reflections=True)]
    with pytest.raises(
        UnsupportedFeatureError, match=r"sensors\[2\] \(CameraSensor\).*reflections"
    ):
        make_batch(spec, 1, **WARP)
    spec.sensors = [
        *spec.sensors[:2],
        CameraSensor("front", 32, 32),
        CameraSensor("front", 16, 16, name="small"),
    ]
    with pytest.raises(UnsupportedFeatureError, match=r"sensors\[3\].*'front' is observed twice"):
        make_batch(spec, 1, **WARP)


def test_bad_actions() -> None:
    batch = make_batch("mjkdl/PandaReach-v0", 2, **WARP)
    try:
        with pytest.raises(RuntimeError, match="before reset"):
            batch.step(torch.zeros(2, 7))
        batch.reset(seed=0)
        with pytest.raises(SpecError, match=r"shape \(2, 7\)"):
            batch.step(torch.zeros(3, 7))
        bad = torch.zeros(2, 7)
        bad[1, 2] = float("nan")
        with pytest.raises(SpecError, match=r"world 1, panda\.vz=nan"):
            batch.step(bad)
    finally:
        batch.close()


# ---------------------------------------------------------------------- cameras

# MuJoCo Warp ray-traces the same geometry for depth, but shades RGB with its own lighting
# model (not OpenGL's fixed pipeline). Measured on PickCube's front camera (64x48) over a
# short episode: depth median 3.6e-7 m, 99th percentile 1.6e-5 m (the rest: silhouette edge
# pixels, up to 2.3e-3 m); RGB mean absolute difference 17.3-17.7 levels, PSNR 19.6-19.9 dB
# (the wrist camera: 32-35 levels, 15.2-16.0 dB; docs/task.md, "Many worlds").
DEPTH_MEDIAN_TOL = 1e-5
DEPTH_P99_TOL = 1e-3
RGB_MAD_TOL = 20.0
RGB_PSNR_MIN = 19.0


def test_cameras_render_every_world_as_the_cpu_env_sees_it() -> None:
    spec = registry.panda_pick_cube_spec()
    spec.sensors = [*spec.sensors, CameraSensor("front", 64, 48, depth=True)]
    batch = make_batch(spec, WORLDS, **WARP)
    cpu_env = TaskEnv(spec)
    try:
        obs, _ = batch.reset(seed=SEED)
        assert obs["front_rgb"].shape == (WORLDS, 48, 64, 3)
        assert obs["front_rgb"].dtype == torch.uint8
        assert obs["front_depth"].shape == (WORLDS, 48, 64)
        for i in range(WORLDS):
            ref, _ = cpu_env.reset(seed=SEED + i)
            gap = np.abs(obs["front_depth"][i].numpy() - ref["front_depth"])
            assert np.median(gap) < DEPTH_MEDIAN_TOL and np.percentile(gap, 99) < DEPTH_P99_TOL
            diff = obs["front_rgb"][i].numpy().astype(float) - ref["front_rgb"]
            psnr = 10 * np.log10(255**2 / np.mean(diff**2))
            assert np.abs(diff).mean() < RGB_MAD_TOL and psnr > RGB_PSNR_MIN, psnr
            np.testing.assert_allclose(obs["front_intrinsics"][i].numpy(), ref["front_intrinsics"])
        # Each world is drawn from its own state: the cubes lie apart.
        assert float((obs["front_depth"][0] - obs["front_depth"][1]).abs().max()) > 0.005
    finally:
        batch.close()
        cpu_env.close()


def test_camera_buffers_count_in_the_memory_estimate() -> None:
    import re

    spec = registry.panda_reach_spec()
    spec.sensors = [*spec.sensors, CameraSensor("front", 128, 96, depth=True)]
    with pytest.raises(SpecError, match="GiB") as cams:
        make_batch(spec, 10**8, **WARP)
    with pytest.raises(SpecError, match="GiB") as plain:
        make_batch(registry.panda_reach_spec(), 10**8, **WARP)

    def kib(err: pytest.ExceptionInfo) -> int:
        return int(re.search(r"\((\d+) KiB per world\)", str(err.value)).group(1))

    # Colour (4 + 3 bytes a pixel) and depth (4 + 4), and the scene hierarchy's bounds.
    env = TaskEnv(spec)
    ngeom = env.scene.model.ngeom
    env.close()
    assert kib(cams) - kib(plain) == pytest.approx((128 * 96 * 15 + 28 * ngeom) / 1024, abs=1)
