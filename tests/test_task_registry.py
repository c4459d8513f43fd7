"""Registered Panda tasks: checkers, success, rewards, actions, parameters, goal variants,
rendering and async vector envs with cameras."""

from __future__ import annotations

import math
import warnings

import gymnasium as gym
import numpy as np
import pytest
from conftest import menagerie
from gymnasium.utils.env_checker import check_env

import mjkdl.task
from mjkdl.errors import SpecError, SpecTypeError, UnknownNameError
from mjkdl.task import TaskEnv
from mjkdl.task.experts import expert_for
from mjkdl.task.registry import CUBE_HALF, LIFT, TASKS

IDS = list(TASKS)
REACH, PICK = "mjkdl/PandaReach-v0", "mjkdl/PandaPickCube-v0"
REACH_GOAL, PICK_GOAL = "mjkdl/PandaReachGoal-v0", "mjkdl/PandaPickCubeGoal-v0"


@pytest.fixture(autouse=True)
def _panda() -> None:
    menagerie("franka_emika_panda")


def run(env: gym.Env, policy, seed: int) -> tuple[float, bool, int, list[dict]]:
    """One episode: (return, final is_success, steps, infos)."""
    obs, info = env.reset(seed=seed)
    if hasattr(policy, "reset"):
        policy.reset()
    total, infos, steps = 0.0, [info], 0
    done = False
    while not done:
        obs, reward, terminated, truncated, info = env.step(policy(obs))
        total += reward
        infos.append(info)
        steps += 1
        done = terminated or truncated
    return total, bool(info["is_success"]), steps, infos


# ------------------------------------------------------------------------- checkers, spaces


@pytest.mark.parametrize("env_id", IDS)
def test_registered_tasks_pass_gymnasiums_checker(env_id: str) -> None:
    env = gym.make(env_id)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env.unwrapped, skip_render_check=True)
    # Only the unbounded-state notices Gymnasium's own MuJoCo envs get too.
    others = [str(w.message) for w in caught if "infinity" not in str(w.message)]
    assert others == []
    assert env.action_space == gym.spaces.Box(-1.0, 1.0, (7,), np.float32)
    assert env.unwrapped.control_timestep == pytest.approx(0.1)
    assert env.unwrapped.scene.timestep() == 0.002
    assert env.spec is not None and env.spec.max_episode_steps == 100
    env.close()


@pytest.mark.parametrize("env_id", IDS)
def test_every_step_reports_success_and_divergence(env_id: str) -> None:
    env = gym.make(env_id)
    _, info = env.reset(seed=0)
    assert info == {"is_success": False, "diverged": False}
    *_, info = env.step(env.action_space.sample())
    assert set(info) == {"is_success", "diverged"}
    assert type(info["is_success"]) is bool and info["diverged"] is False
    env.close()


def test_the_entry_points_are_classes_gymnasiums_wrappers_apply_to() -> None:
    for env_id, cls in TASKS.items():
        env = gym.make(env_id)
        assert type(env.unwrapped) is cls and issubclass(cls, TaskEnv)
        assert gym.spec(env_id).entry_point == f"mjkdl.task.registry:{cls.__name__}"
        env.close()


# ------------------------------------------------------------------------------ success


def test_reach_succeeds_within_the_success_distance() -> None:
    env = gym.make(REACH, success_distance=0.08).unwrapped
    obs, _ = env.reset(seed=3)
    goal = obs["goal_pose"][:3]
    np.testing.assert_allclose(obs["goal_rel"], goal - obs["panda_tcp_pos"], atol=1e-12)
    for offset, expected in ((0.079, True), (0.081, False)):
        env.scene.set_body_pose("goal", (obs["panda_tcp_pos"] + [offset, 0.0, 0.0]).tolist())
        obs, reward, terminated, _, info = env.step(np.zeros(7, np.float32))
        d = np.linalg.norm(obs["goal_pose"][:3] - obs["panda_tcp_pos"])
        assert info["is_success"] is bool(d <= 0.08) is expected
        assert not terminated  # Reach goes on unless terminate_on_success
        assert reward == pytest.approx(0.5 * (1 - math.tanh(d / 0.25)) + 0.5 * expected)
    env.close()


def test_the_reach_goal_is_a_marker_the_hand_passes_through() -> None:
    env = gym.make(REACH).unwrapped
    obs, _ = env.reset(seed=1)
    env.scene.set_body_pose("goal", obs["panda_tcp_pos"].tolist())
    start = env.scene.data.mocap_pos.copy()
    for _ in range(5):
        obs, *_ = env.step(np.array([1, 0, -1, 0, 0, 0, -1], np.float32))
    np.testing.assert_array_equal(env.scene.data.mocap_pos, start)
    model = env.scene.model
    goal = model.body("goal").id
    geoms = [g for g in range(model.ngeom) if model.geom_bodyid[g] == goal]
    assert geoms and all(model.geom_contype[g] == model.geom_conaffinity[g] == 0 for g in geoms)
    env.close()


def test_pick_cube_succeeds_only_when_lifted_between_the_fingers() -> None:
    env = gym.make(PICK).unwrapped
    obs, info = env.reset(seed=0)
    assert obs["cube_pose"][2] == pytest.approx(CUBE_HALF + 0.002, abs=1e-9)
    assert not info["is_success"] and obs["cube_contacts"].tolist() == [0.0, 0.0]
    # Lifted but not held (put in the air beside the hand): no success, no end.
    env.scene.set_body_pose("cube", [0.3, 0.3, 0.3])
    obs, reward, terminated, _, info = env.step(np.zeros(7, np.float32))
    assert obs["cube_pose"][2] > CUBE_HALF + LIFT and not info["is_success"] and not terminated
    assert reward < 0.25
    env.close()


def test_pick_cube_ends_after_half_a_second_of_success_and_pays_the_rest() -> None:
    env = gym.make(PICK)
    expert = expert_for(env)
    obs, _ = env.reset(seed=4)
    expert.reset()
    successes, rewards, step = [], [], 0
    terminated = truncated = False
    while not (terminated or truncated):
        obs, reward, terminated, truncated, info = env.step(expert(obs))
        successes.append(info["is_success"])
        rewards.append(reward)
        step += 1
    assert terminated and not truncated
    # Six success steps in a row: the first, then 0.5 s more of holding.
    assert successes[-6:] == [True] * 6 and not successes[-7]
    assert rewards[-6:-1] == [1.0] * 5
    assert rewards[-1] == pytest.approx(1.0 * (1 + 100 - step))
    env.close()


# ------------------------------------------------------------------------------ rewards


def zero(obs) -> np.ndarray:
    return np.zeros(7, np.float32)


class Random:
    def __init__(self, seed: int) -> None:
        self.rng = np.random.default_rng(seed)

    def __call__(self, obs) -> np.ndarray:
        return self.rng.uniform(-1, 1, 7).astype(np.float32)


class Hover:
    """Goes over the cube (or goal) and stays 4 cm above it, gripper open: never succeeds."""

    def __init__(self, key: str) -> None:
        self.key = key

    def __call__(self, obs) -> np.ndarray:
        a = np.zeros(7, np.float32)
        above = obs[self.key][:3] + np.array([0.0, 0.0, 0.09])
        a[:3] = np.clip(4.0 * (above - obs["panda_tcp_pos"]) / 0.5, -1, 1)
        a[6] = -1.0
        return a


@pytest.mark.parametrize(("env_id", "key"), [(REACH, "goal_pose"), (PICK, "cube_pose")])
def test_the_expert_earns_more_than_failing_policies(env_id: str, key: str) -> None:
    env = gym.make(env_id)
    expert = expert_for(env)
    for seed in range(6):
        best, expert_success, *_ = run(env, expert, seed)
        assert expert_success
        for policy in (zero, Random(seed), Hover(key)):
            ret, success, *_ = run(env, policy, seed)
            assert not success
            assert ret < best, (seed, policy)
    env.close()


def test_pick_cube_rewards_grow_through_the_stages() -> None:
    """Reward before the grasp < 0.25; grasped, 0.25 more plus up to 0.25 for the height, at
    most 0.75; success 1."""
    env = gym.make(PICK)
    expert = expert_for(env)
    obs, _ = env.reset(seed=2)
    expert.reset()
    by_stage: dict[str, list[float]] = {"reach": [], "grasp": [], "success": []}
    done = False
    while not done:
        obs, reward, terminated, truncated, info = env.step(expert(obs))
        done = terminated or truncated
        if info["is_success"]:
            by_stage["success"].append(reward)
        elif obs["cube_contacts"].all():
            by_stage["grasp"].append(reward)
        else:
            by_stage["reach"].append(reward)
    env.close()
    assert max(by_stage["reach"]) < 0.25 + 1e-12
    grasp = by_stage["grasp"]
    assert grasp and max(by_stage["reach"]) + 0.2 < min(grasp) <= max(grasp) < 0.75
    assert grasp[-1] > grasp[0] + 0.1  # the lift pays as the cube rises
    assert by_stage["success"][0] == 1.0


def test_sparse_rewards_pay_one_on_success_steps_only() -> None:
    env = gym.make(REACH, reward_type="sparse")
    expert = expert_for(env)
    obs, _ = env.reset(seed=5)
    paid = []
    for _ in range(30):
        obs, reward, _, _, info = env.step(expert(obs))
        paid.append((reward, info["is_success"]))
    env.close()
    assert {r for r, _ in paid} == {0.0, 1.0}
    assert all(r == float(s) for r, s in paid)


# ------------------------------------------------------------------------------ actions


def test_actions_are_normalised_to_the_twist_limits_and_the_gripper_closes_on_plus_one() -> None:
    env = gym.make(PICK).unwrapped
    obs, _ = env.reset(seed=0)
    assert obs["panda_gripper"][0] > 0.99  # open at the first observation
    start = obs["panda_tcp_pos"].copy()
    for _ in range(3):
        obs, *_ = env.step(np.array([0.5, 0, 0, 0, 0, 0, 1.0], np.float32))
    # 0.5 of the 0.5 m/s bound for 0.3 s; the position servos lag a little at the start.
    moved = obs["panda_tcp_pos"] - start
    assert 0.05 < moved[0] < 0.08 and abs(moved[1]) < 0.01 and abs(moved[2]) < 0.01
    # The fingers move at the Franka Hand's 0.05 m/s each (GripperDrive): 15 of 40 mm in 0.3 s.
    assert obs["panda_gripper"][0] == pytest.approx(1.0 - 0.3 * 0.05 / 0.04, abs=0.03)
    for _ in range(7):
        obs, *_ = env.step(np.array([0, 0, 0, 0, 0, 0, 1.0], np.float32))
    assert obs["panda_gripper"][0] < 0.02  # closed
    for _ in range(10):
        obs, *_ = env.step(np.array([0, 0, 0, 0, 0, 0, -1.0], np.float32))
    assert obs["panda_gripper"][0] > 0.98
    env.close()


# --------------------------------------------------------------------------- parameters


def test_episode_length_follows_max_episode_steps_and_time_limit() -> None:
    for kwargs, steps in (
        ({}, 100),
        ({"max_episode_steps": 130}, 130),
        ({"time_limit": 5.0}, 50),
        ({"control_timestep": 0.05}, 100),
        ({"control_timestep": 0.05, "time_limit": 1.0}, 20),
    ):
        env = gym.make(REACH, **kwargs)
        _, _, n, _ = run(env, zero, seed=0)
        assert n == steps, kwargs
        env.close()


def test_goal_and_cube_boxes_are_parameters() -> None:
    env = gym.make(REACH, goal_low=[0.5, 0.1, 0.3], goal_high=[0.5, 0.1, 0.3])
    obs, _ = env.reset(seed=0)
    np.testing.assert_allclose(obs["goal_pose"][:3], [0.5, 0.1, 0.3])
    env.close()
    env = gym.make(PICK, cube_low=[0.45, -0.05], cube_high=[0.5, 0.0])
    for seed in range(5):
        obs, _ = env.reset(seed=seed)
        x, y, _ = obs["cube_pose"][:3]
        assert 0.45 <= x <= 0.5 and -0.05 <= y <= 0.0
    env.close()


def test_cameras_are_observations_of_the_asked_size() -> None:
    env = gym.make(PICK, camera_names=["wrist", "front"], camera_size=(48, 64))
    obs, _ = env.reset(seed=0)
    for name in ("wrist", "front"):
        assert obs[f"{name}_rgb"].shape == (48, 64, 3) and obs[f"{name}_rgb"].dtype == np.uint8
        assert obs[f"{name}_rgb"].std() > 5
        assert env.observation_space[f"{name}_rgb"].shape == (48, 64, 3)
    env.close()


@pytest.mark.parametrize(
    ("kwargs", "error", "message"),
    [
        ({"goal_hight": [1, 1, 1]}, SpecError, "unknown parameter(s) ['goal_hight']; valid: "),
        ({"reward_type": "shaped"}, SpecError, "reward_type must be one of ['dense', 'sparse']"),
        ({"camera_names": ["top"]}, UnknownNameError, "'top'"),
        ({"camera_names": "wrist"}, SpecTypeError, "camera_names must be a list of camera"),
        ({"camera_size": (64,)}, SpecError, "camera_size must be (height, width), got (64,)"),
        ({"success_distance": 0}, SpecError, "success_distance must be a positive number"),
        ({"goal_low": [1, 0, 0]}, SpecError, "goal_low must not exceed goal_high"),
        ({"time_limit": -1}, SpecError, "TaskSpec.time_limit must be a positive number"),
        ({"terminate_on_success": "yes"}, SpecTypeError, "terminate_on_success"),
    ],
)
def test_bad_parameters_are_refused_by_name(kwargs: dict, error: type, message: str) -> None:
    with pytest.raises(error) as caught:
        gym.make(REACH, **kwargs)
    assert message in str(caught.value)


def test_an_unknown_parameter_lists_the_valid_ones() -> None:
    with pytest.raises(SpecError) as caught:
        gym.make(PICK, goal_low=[0, 0, 0])
    assert str(caught.value).startswith(
        "PandaPickCubeEnv: unknown parameter(s) ['goal_low']; valid: render_mode, time_limit, "
        "control_timestep, actuation, cartesian_axes, cube_low, cube_high, reward_type, "
        "terminate_on_success, "
    )


# ------------------------------------------------------------------------------ goals


@pytest.mark.parametrize("env_id", [REACH_GOAL, PICK_GOAL])
def test_goal_variants_compute_the_reward_step_pays(env_id: str) -> None:
    env = gym.make(env_id)
    obs, _ = env.reset(seed=1)
    assert list(obs)[:3] == ["observation", "achieved_goal", "desired_goal"]
    inner = env.unwrapped
    expert = expert_for(env)
    rewards, achieved, desired = [], [], []
    for _ in range(40):
        obs, reward, _, _, info = env.step(expert(obs))
        rewards.append(reward)
        achieved.append(obs["achieved_goal"])
        desired.append(obs["desired_goal"])
        assert info["is_success"] == (
            np.linalg.norm(obs["achieved_goal"] - obs["desired_goal"])
            <= inner.goal_reward.threshold
        )
    batch = inner.compute_reward(np.array(achieved), np.array(desired), [{}] * 40)
    np.testing.assert_array_equal(batch, rewards)
    assert set(rewards) == {0.0, 1.0}  # sparse by default, and the expert gets there
    env.close()


def test_goal_observations_leave_out_what_depends_on_the_goal() -> None:
    env = gym.make(REACH_GOAL).unwrapped
    keys = [k for k, _ in env.observation_layout]
    assert "goal_pose" not in keys and "goal_rel" not in keys and "time" not in keys
    assert keys[:2] == ["panda_joint_pos", "panda_joint_vel"]
    obs, _ = env.reset(seed=0)
    assert obs["observation"].shape == (sum(n for _, n in env.observation_layout),)
    env.close()


# ------------------------------------------------------------------------------ experts


@pytest.mark.parametrize("env_id", [REACH, PICK])
def test_the_experts_succeed_on_at_least_95_of_100_seeds(env_id: str) -> None:
    env = gym.make(env_id)
    expert = expert_for(env)
    wins = sum(run(env, expert, seed)[1] for seed in range(100))
    env.close()
    assert wins >= 95


def test_an_env_without_an_expert_is_named() -> None:
    env = gym.make("CartPole-v1")
    with pytest.raises(UnknownNameError, match="no expert for CartPoleEnv; experts exist for"):
        expert_for(env)


# ---------------------------------------------------------------------------- rendering


def test_rgb_and_depth_frames_of_a_registered_task() -> None:
    env = gym.make(REACH, render_mode="rgb_array", render_width=96, render_height=64)
    env.reset(seed=0)
    frame = env.render()
    assert frame.shape == (64, 96, 3) and frame.dtype == np.uint8 and frame.std() > 5
    env.close()
    env = gym.make(REACH, render_mode="depth_array", render_width=96, render_height=64)
    env.reset(seed=0)
    depth = env.render()
    assert depth.shape == (64, 96) and depth.dtype == np.float32
    assert 0.5 < float(depth.min()) < float(depth.max()) < 50.0  # metres from the front camera
    env.close()


def test_rgb_array_list_collects_a_frame_per_reset_and_step() -> None:
    env = gym.make(REACH, render_mode="rgb_array_list", render_width=32, render_height=24)
    env.reset(seed=0)
    for _ in range(3):
        env.step(np.zeros(7, np.float32))
    frames = env.render()
    assert len(frames) == 4 and frames[0].shape == (24, 32, 3)
    env.close()


def test_a_taskenv_refuses_rgb_array_list_and_says_where_it_comes_from() -> None:
    with pytest.raises(SpecError, match=r"gymnasium.make adds it around 'rgb_array'"):
        mjkdl.task.registry.PandaReachEnv(render_mode="rgb_array_list")


# ------------------------------------------------------------------------ vector envs


def rollout(env, seeds: list[int], actions: np.ndarray) -> np.ndarray:
    """TCP positions and rewards of sequential episodes, one per seed."""
    out = []
    for k, seed in enumerate(seeds):
        obs, _ = env.reset(seed=seed)
        trace = [obs["panda_tcp_pos"]]
        for a in actions[:, k]:
            obs, reward, *_ = env.step(a)
            trace += [obs["panda_tcp_pos"], [reward]]
        out.append(np.concatenate(trace))
    return np.array(out)


def test_async_vector_env_repeats_sequential_episodes() -> None:
    rng = np.random.default_rng(0)
    n, steps = 2, 4
    actions = rng.uniform(-1, 1, (steps, n, 7)).astype(np.float32)
    vec = gym.make_vec(REACH, num_envs=n, vectorization_mode="async")
    try:
        obs, _ = vec.reset(seed=100)
        traces = [[obs["panda_tcp_pos"][k]] for k in range(n)]
        for a in actions:
            obs, reward, *_ = vec.step(a)
            for k in range(n):
                traces[k] += [obs["panda_tcp_pos"][k], [reward[k]]]
    finally:
        vec.close()
    env = gym.make(REACH)
    sequential = rollout(env, [100, 101], actions)
    env.close()
    np.testing.assert_array_equal(np.array([np.concatenate(t) for t in traces]), sequential)


CAMERA_WORKERS = """
import gymnasium as gym, numpy as np
import mjkdl.task
kwargs = dict(camera_names=["wrist"], camera_size=(32, 32))
vec = gym.make_vec("mjkdl/PandaReach-v0", num_envs=2, vectorization_mode="async", **kwargs)
assert vec.unwrapped.context is None  # the platform default: fork on Linux
obs, _ = vec.reset(seed=7)
frames = [obs["wrist_rgb"].copy()]
obs, *_ = vec.step(np.zeros((2, 7), np.float32))
frames.append(obs["wrist_rgb"].copy())
vec.close()
env = gym.make("mjkdl/PandaReach-v0", **kwargs)
for k in range(2):
    obs, _ = env.reset(seed=7 + k)
    assert np.array_equal(obs["wrist_rgb"], frames[0][k])
    obs, *_ = env.step(np.zeros(7, np.float32))
    assert np.array_equal(obs["wrist_rgb"], frames[1][k])
print("same frames", frames[0].std() > 5)
"""


def test_camera_envs_render_in_forked_workers() -> None:
    """A script's async vector env of camera envs with Linux's default start method (fork;
    Gymnasium builds one env in the parent first): each worker makes its own OpenGL context
    and renders what one env renders alone."""
    import subprocess
    import sys

    out = subprocess.run(
        [sys.executable, "-c", CAMERA_WORKERS], capture_output=True, text=True, timeout=240
    )
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.strip() == "same frames True"


def test_a_worker_forked_after_its_parent_rendered_says_why_it_cannot() -> None:
    env = gym.make(REACH, render_mode="rgb_array", render_width=32, render_height=32)
    env.reset(seed=0)
    env.render()  # this process now holds an EGL display that a fork cannot take along
    env.close()
    vec = gym.make_vec(
        REACH, num_envs=1, vectorization_mode="async", camera_names=["wrist"], camera_size=(8, 8)
    )
    try:
        with pytest.raises(Exception, match="forked from one that had already rendered"):
            vec.reset(seed=0)
    finally:
        vec.close(terminate=True)


# ------------------------------------------------------------- Push, PickAndPlace, Stack

PUSH, PLACE, STACK = "mjkdl/PandaPush-v0", "mjkdl/PandaPickAndPlace-v0", "mjkdl/PandaStack-v0"
NEW = [PUSH, PLACE, STACK]
NEW_GOALS = [i.replace("-v0", "Goal-v0") for i in NEW]


def steps_to_success(env: gym.Env, expert, seed: int) -> int | None:
    """Control steps the expert needs to succeed from `seed`, None within 100."""
    obs, _ = env.reset(seed=seed)
    expert.reset()
    for k in range(100):
        obs, _, terminated, truncated, info = env.step(expert(obs))
        if info["is_success"]:
            return k + 1
        if terminated or truncated:
            return None
    return None


@pytest.mark.parametrize(
    ("env_id", "seeds"), [(i, (0, 1)) for i in NEW] + [(i, (2,)) for i in NEW_GOALS]
)
def test_the_new_experts_succeed_on_a_few_seeds(env_id: str, seeds: tuple[int, ...]) -> None:
    env = gym.make(env_id)
    expert = expert_for(env)
    steps = [steps_to_success(env, expert, s) for s in seeds]
    env.close()
    assert all(n is not None and n < 80 for n in steps), steps


def test_push_goals_lie_on_the_floor_and_pick_and_place_targets_in_the_air() -> None:
    push, place = gym.make(PUSH), gym.make(PLACE)
    for seed in range(3):
        goal = push.reset(seed=seed)[0]["goal_pose"]
        assert goal[2] == pytest.approx(CUBE_HALF)
        assert 0.35 <= goal[0] <= 0.65 and -0.2 <= goal[1] <= 0.2
        target = place.reset(seed=seed)[0]["target_pose"]
        assert CUBE_HALF + 0.08 <= target[2] <= CUBE_HALF + 0.2
    push.close()
    place.close()


def test_push_goals_start_clear_of_the_cube() -> None:
    """No Push episode begins solved: the goal lands `goal_clearance` (10 cm) or more from
    the cube; 0 draws it anywhere, as panda-gym does, and a negative one is refused."""
    env = gym.make(PUSH)
    gaps = []
    for seed in range(40):
        obs = env.reset(seed=seed)[0]
        gaps.append(float(np.hypot(*(obs["goal_pose"] - obs["cube_pose"])[:2])))
        assert not env.unwrapped.task_spec.success(obs)
    assert min(gaps) >= 0.1
    env.close()
    anywhere = gym.make(PUSH, goal_clearance=0.0)
    near = [anywhere.reset(seed=s)[0] for s in range(40)]
    assert min(float(np.hypot(*(o["goal_pose"] - o["cube_pose"])[:2])) for o in near) < 0.1
    anywhere.close()
    with pytest.raises(SpecError) as err:
        gym.make(PUSH, goal_clearance=-1)
    assert str(err.value) == "goal_clearance must be >= 0 metres (0: anywhere), got -1"


def test_stack_succeeds_only_once_the_cube_is_let_go_on_the_base() -> None:
    env = gym.make(STACK)
    obs, info = env.reset(seed=3)
    above = obs["base_pose"][:3] + np.array([0.0, 0.0, 2 * CUBE_HALF])
    np.testing.assert_allclose(obs["target_pose"][:3], above)
    expert = expert_for(env)
    held_there = []
    for _ in range(100):
        obs, reward, _, _, info = env.step(expert(obs))
        there = np.linalg.norm(obs["cube_pose"][:3] - obs["target_pose"][:3]) <= 0.02
        if there and obs["cube_contacts"].max() > 0.5:
            held_there.append((info["is_success"], reward))
        if info["is_success"]:
            break
    env.close()
    assert info["is_success"] and reward == 1.0
    assert held_there and all(not s and r < 1.0 for s, r in held_there)


@pytest.mark.parametrize("env_id", NEW_GOALS)
def test_new_goal_variants_recompute_reward_and_ends_from_goals(env_id: str) -> None:
    env = gym.make(env_id)
    inner = env.unwrapped
    obs, _ = env.reset(seed=4)
    expert = expert_for(env)
    rows = []
    for _ in range(80):
        obs, reward, terminated, truncated, info = env.step(expert(obs))
        ag, dg = obs["achieved_goal"], obs["desired_goal"]
        assert reward == inner.compute_reward(ag, dg, info)
        assert terminated == inner.compute_terminated(ag, dg, info)
        assert truncated == inner.compute_truncated(ag, dg, info)
        rows.append((ag, dg, reward))
    ag, dg, rewards = (np.array(c) for c in zip(*rows, strict=True))
    np.testing.assert_array_equal(inner.compute_reward(ag, dg, [{}] * 80), rewards)
    # Relabelled with the achieved goal, every step pays the success reward.
    np.testing.assert_array_equal(inner.compute_reward(ag, ag, [{}] * 80), np.ones(80))
    assert inner.compute_terminated(ag, dg, [{}] * 80).shape == (80,)
    assert 1.0 in rewards  # the expert gets there within 80 steps
    env.close()


@pytest.mark.long
@pytest.mark.parametrize("env_id", NEW + NEW_GOALS)
def test_the_new_experts_succeed_on_at_least_95_of_100_seeds(env_id: str) -> None:
    """Whole episodes: success at the last of the 100 steps (the cube stays put)."""
    env = gym.make(env_id)
    expert = expert_for(env)
    wins = sum(run(env, expert, seed)[1] for seed in range(100))
    env.close()
    assert wins >= 95


# ------------------------------------------------------------------ joint-space actions


def test_joint_position_actions_span_the_joint_ranges() -> None:
    env = gym.make(PICK, actuation="joint_position")
    assert env.action_space == gym.spaces.Box(-1.0, 1.0, (8,), np.float32)
    inner = env.unwrapped
    assert inner.action_labels == [f"panda.joint{i}" for i in range(1, 8)] + ["panda.gripper"]
    limits = inner.robots["panda"].joint_limits
    env.reset(seed=0)
    target = np.array([0.3, -0.2, 0.1, -1.9, 0.2, 1.9, 0.5])
    action = np.append(2 * (target - limits[:, 0]) / (limits[:, 1] - limits[:, 0]) - 1, -1.0)
    for _ in range(15):
        obs, *_ = env.step(action.astype(np.float32))
    np.testing.assert_allclose(obs["panda_joint_pos"], target, atol=0.02)
    env.close()


def test_joint_velocity_actions_move_each_joint_its_way() -> None:
    env = gym.make(REACH, actuation="joint_velocity")
    obs, _ = env.reset(seed=0)
    start = obs["panda_joint_pos"].copy()
    action = np.zeros(8, np.float32)
    action[0], action[3] = 0.5, -0.5
    for _ in range(3):
        obs, *_ = env.step(action)
    moved = obs["panda_joint_pos"] - start
    assert moved[0] > 0.1 and moved[3] < -0.1
    assert np.abs(np.delete(moved, [0, 3])).max() < 0.02
    check_env(env.unwrapped, skip_render_check=True)
    env.close()


# ------------------------------------------------------------------ top-down actions


def test_top_down_axes_act_as_the_full_twist_with_zeros() -> None:
    """`cartesian_axes="vx,vy,vz,wz"`: an action of 5 entries that moves the arm exactly as
    the full twist with wx = wy = 0 does."""
    top = gym.make(PICK, cartesian_axes="vx,vy,vz,wz")
    full = gym.make(PICK)
    assert top.action_space == gym.spaces.Box(-1.0, 1.0, (5,), np.float32)
    labels = ["panda.vx", "panda.vy", "panda.vz", "panda.wz", "panda.gripper"]
    assert top.unwrapped.action_labels == labels
    low, high = top.unwrapped.action_bounds
    assert high.tolist() == [0.5, 0.5, 0.5, 1.0, 1.0] and low.tolist()[:4] == [-0.5] * 3 + [-1.0]
    top.reset(seed=2)
    full.reset(seed=2)
    rng = np.random.default_rng(0)
    for _ in range(5):
        a = rng.uniform(-1, 1, 5).astype(np.float32)
        obs, *_ = top.step(a)
        ref, *_ = full.step(np.array([*a[:3], 0, 0, *a[3:]], np.float32))
        np.testing.assert_array_equal(obs["panda_joint_pos"], ref["panda_joint_pos"])
    top.close()
    full.close()


@pytest.mark.parametrize("env_id", [PICK, PLACE, STACK, PUSH])
def test_experts_succeed_with_top_down_axes(env_id: str) -> None:
    """The experts' twists keep the hand pointing down, so they act through the top-down
    axes alone (measured: 20 of 20 seeds on each task)."""
    env = gym.make(env_id, cartesian_axes=("vx", "vy", "vz", "wz"))
    assert run(env, expert_for(env), 3)[1]
    env.close()


@pytest.mark.parametrize(
    ("axes", "error", "match"),
    [
        ("vx,vy,vz,yaw", SpecError, r"unknown entries \['yaw'\]; valid: vx, vy, vz, wx"),
        ("vz,vx", SpecError, r"distinct entries in the order"),
        ("vx,vx", SpecError, r"distinct entries in the order"),
        (3, SpecTypeError, r"cartesian_axes must be a comma-separated string"),
        ((), SpecTypeError, r"must be a non-empty tuple"),
    ],
)
def test_bad_cartesian_axes_are_named(axes: object, error: type, match: str) -> None:
    with pytest.raises(error, match=match):
        gym.make(REACH, cartesian_axes=axes)


def test_cartesian_axes_with_joint_actuation_are_refused() -> None:
    with pytest.raises(SpecError, match=r"cartesian_axes chooses.*'joint_position'"):
        gym.make(REACH, actuation="joint_position", cartesian_axes="vx,vy,vz")


def test_bad_actuation_and_experts_outside_cartesian_mode_are_named() -> None:
    with pytest.raises(SpecError, match=r"actuation must be one of \['joint_position', "):
        gym.make(REACH, actuation="joints")
    env = gym.make(PUSH, actuation="joint_torque")
    with pytest.raises(SpecError, match="the experts act in Cartesian velocity; this "):
        expert_for(env)
    env.close()


# ------------------------------------------------------------ headless checker, options


def test_headless_human_mode_opens_nothing_until_it_renders(monkeypatch) -> None:
    """The window opens at the first render() (reset renders in "human" mode), so an env
    can be built and checked headless; the render modes that need no window work."""
    from gymnasium.utils.passive_env_checker import env_render_passive_checker

    from mjkdl.viewer import NoDisplayError

    monkeypatch.delenv("DISPLAY", raising=False)
    env = gym.make(STACK, render_mode="human")
    assert env.unwrapped._viewer is None
    with pytest.raises(NoDisplayError, match="needs a display and DISPLAY is not set"):
        env.reset(seed=0)
    env.close()
    for mode in ("rgb_array", "depth_array"):
        env = gym.make(STACK, render_mode=mode, render_width=64, render_height=48)
        env.reset(seed=0)
        env_render_passive_checker(env.unwrapped)
        env.close()


def test_reset_takes_the_options_gymnasiums_vector_envs_pass() -> None:
    envs = gym.make_vec(PUSH, num_envs=2, vectorization_mode="sync")
    first, _ = envs.reset(seed=[5, 6], options={})
    again, _ = envs.reset(options={"reset_mask": np.array([False, True])})
    np.testing.assert_array_equal(again["cube_pose"][0], first["cube_pose"][0])  # kept
    envs.close()


def test_the_shared_parameters_are_declared_once_and_documented() -> None:
    """Each class takes its own keywords only; the shared ones come from one table, which the
    docs' table and the unknown-parameter message follow."""
    import inspect
    from pathlib import Path

    from mjkdl.task.registry import SHARED_PARAMETERS, TASKS

    shared = [p.name for p in SHARED_PARAMETERS]
    assert len(shared) == 19 and len(set(shared)) == 19
    docs = (Path(__file__).resolve().parents[1] / "docs" / "task.md").read_text()
    rows = [line for line in docs.splitlines() if line.startswith("| `")]
    for name in shared:
        assert any(f"`{name}`" in row.split("|")[1] for row in rows), name
    for env_id, cls in TASKS.items():
        own = list(inspect.signature(cls.__init__).parameters)[1:-1]
        assert own[0] == "render_mode" and not set(own) & set(shared), env_id
        taken = cls.shared_parameters()
        goal = env_id.endswith("Goal-v0")
        assert ("terminate_on_success" in taken) is not goal, env_id
        assert taken["reward_type"] == ("sparse" if goal else "dense"), env_id
    assert TASKS["mjkdl/PandaPickCube-v0"].shared_parameters()["terminate_on_success"] is True
    assert TASKS["mjkdl/PandaPickCubeGoal-v0"].parameter_names()[:8] == [
        "render_mode",
        "time_limit",
        "control_timestep",
        "actuation",
        "cartesian_axes",
        "cube_low",
        "cube_high",
        "target_low",
    ]
    with pytest.raises(SpecError, match=r"unknown parameter\(s\) \['terminate_on_success'\]"):
        gym.make(PICK_GOAL, terminate_on_success=True)


def test_push_with_a_blocked_gripper_holds_the_fingers_closed_out_of_the_action() -> None:
    """`block_gripper` (panda-gym's Push): the action loses its gripper entry, the fingers
    start closed and stay closed, and the expert still pushes the cube there; the goal variant
    takes it too, and a non-boolean is refused by name."""
    env = gym.make(PUSH, block_gripper=True, cartesian_axes="vx,vy,vz")
    assert env.unwrapped.action_labels == ["panda.vx", "panda.vy", "panda.vz"]
    assert env.action_space.shape == (3,)
    obs, _ = env.reset(seed=0)
    assert obs["panda_gripper"][0] < 1e-3  # closed at the first observation
    for _ in range(5):
        obs = env.step(np.ones(3, np.float32))[0]
    assert obs["panda_gripper"][0] < 1e-3
    steps = steps_to_success(env, expert_for(env), 1)
    env.close()
    assert steps is not None and steps < 80, steps
    goal = gym.make("mjkdl/PandaPushGoal-v0", block_gripper=True)
    assert goal.action_space.shape == (6,)
    goal.close()
    with pytest.raises(SpecTypeError, match="block_gripper must be True or False, got 'yes'"):
        gym.make(PUSH, block_gripper="yes")
