"""A recorded state is the whole state (#37 items 1 and 6): set a recorded row and step the
recorded action, and the next recorded state comes back bit for bit with its observation
(camera frames included), reward and end, on every registered task; the controllers'
commands and the episode's counters are part of `mjSTATE_INTEGRATION`."""

from __future__ import annotations

import json
from pathlib import Path

import gymnasium as gym
import mujoco
import numpy as np
import pytest
from conftest import menagerie
from demo_envs import CAMERA

import mjkdl as mjk
from mjkdl.demos import DemoFile, make_env
from mjkdl.demos.collect import collect
from mjkdl.demos.convert import convert
from mjkdl.demos.episodes import restore, run_episode, scene_of
from mjkdl.demos.hdf5 import STATE, EpisodeData
from mjkdl.demos.policy import make_policy
from mjkdl.task import TaskEnv
from mjkdl.task.randomization import Draw
from mjkdl.task.registry import TASKS
from mjkdl.task.rewards import success_bonus


@pytest.fixture(autouse=True)
def _panda() -> None:
    menagerie("franka_emika_panda")


def _differ(a: dict[str, np.ndarray], b: dict[str, np.ndarray]) -> list[str]:
    """The keys whose arrays differ (in any bit)."""
    assert a.keys() == b.keys()
    return [k for k in a if not np.array_equal(a[k], b[k])]


@pytest.mark.parametrize("env_id", list(TASKS))
def test_a_restored_state_steps_on_exactly_as_recorded(env_id: str) -> None:
    """Every row of a whole expert demo: set (after another episode), observed, stepped. The
    goal-conditioned twins have the same physics: they go without the camera (software
    rendering is most of the time here)."""
    env = make_env(env_id, {} if env_id.endswith("Goal-v0") else CAMERA)
    try:
        rec = run_episode(env, make_policy("expert", env), seed=11, record=True).data
        assert rec is not None
        env.reset(seed=500)  # another episode's state first: nothing of it may leak
        assert _rows_step_on_as_recorded(env, rec) == rec.num_samples
    finally:
        env.close()


def _rows_step_on_as_recorded(env: gym.Env, rec: EpisodeData) -> int:
    """Set, observe and step every row of `rec` (with its draw): the observation, reward and
    end recorded with each, and the next row reached bit for bit; how many rows were."""
    scene = scene_of(env)
    state = np.empty(mujoco.mj_stateSize(scene.model, STATE))
    n, matched = rec.num_samples, 0
    draw = rec.randomization or None
    for t in range(n):
        obs, regenerated, *_ = restore(env, rec.states[t], draw=draw)
        assert _differ(obs, {k: v[t] for k, v in rec.obs.items()}) == [], t
        if t:  # the reward of the step that reached it, from the state alone
            assert regenerated == rec.rewards[t - 1], t
        after, reward, terminated, truncated, _ = env.step(rec.actions[t])
        assert reward == rec.rewards[t], t
        assert bool(terminated or truncated) == bool(rec.dones[t]), t
        if t + 1 < n:
            mujoco.mj_getState(scene.model, scene.data, state, STATE)
            matched += np.array_equal(state, rec.states[t + 1])
            assert _differ(after, {k: v[t + 1] for k, v in rec.obs.items()}) == [], t
        else:
            assert _differ(after, rec.final_obs) == []
            matched += 1
    return matched


def test_the_success_bonus_is_paid_once_and_regenerated() -> None:
    """PickCube ends on success with the bonus (the steps cut off); the restored last state
    pays the same."""
    env = make_env("mjkdl/PandaPickCube-v0")
    try:
        rec = run_episode(env, make_policy("expert", env), seed=3, record=True).data
        assert rec is not None and rec.success and rec.dones[-1]
        n, horizon = rec.num_samples, 100  # the registered TimeLimit
        task = env.unwrapped
        assert isinstance(task, TaskEnv)
        assert rec.rewards[-1] == success_bonus(1.0, n, horizon) == 101 - n
        env.reset(seed=0)
        restore(env, rec.states[-1])
        env.step(rec.actions[-1])
        _, reward, terminated, _, info = task.observe()
        assert (reward, terminated, info["is_success"]) == (101 - n, True, True)
        assert task.elapsed_steps == n
    finally:
        env.close()


def test_restore_needs_a_task_env_and_a_reset() -> None:
    env = make_env("mjkdl/PandaReach-v0")
    try:
        with pytest.raises(RuntimeError, match=r"TaskEnv.observe\(\) before reset\(\)"):
            env.unwrapped.observe()  # type: ignore[attr-defined]
    finally:
        env.close()


def test_scene_userdata_is_checked() -> None:
    spec = mjk.SceneSpec(timestep=0.002, add_floor=True, add_skybox=False, userdata=-1)
    with pytest.raises(ValueError, match=r"SceneSpec.userdata must be from 0 to 1000000, got -1"):
        mjk.Env.build(spec)
    spec.userdata = 2.0  # type: ignore[assignment]
    with pytest.raises(TypeError, match=r"SceneSpec.userdata must be a whole number .* got 2.0"):
        mjk.Env.build(spec)
    spec.userdata = 3
    with mjk.Env.build(spec) as scene:
        assert scene.model.nuserdata == 3


def test_a_resumed_controller_solves_as_if_fresh() -> None:
    """`resume(previous)`: the solution depends on the state and `previous` alone, not on
    what the controller solved before (DAQP's warm start would change its last bits)."""
    env = make_env("mjkdl/PandaPickCube-v0")
    try:
        env.reset(seed=0)
        eff = env.unwrapped.effectors[0]  # type: ignore[attr-defined]
        busy, robot = eff.controller, eff.robot
        fresh = mjk.CartesianVelocityController(robot, posture=busy.posture)
        twist, previous = np.array([0.05, -0.02, 0.03, 0.2, 0.0, -0.1]), np.full(7, 0.01)
        for k in range(5):  # a history: other twists, warm-started solves
            busy.solve(twist * (k - 2), 0.1)
        robot.update()
        busy.resume(previous)
        fresh.resume(previous)
        assert np.array_equal(busy.solve(twist, 0.1), fresh.solve(twist, 0.1))
        with pytest.raises(ValueError, match=r"resume\(previous\) needs 7 finite joint"):
            busy.resume(np.zeros(6))
        with pytest.raises(ValueError, match=r"resume\(previous\) needs 7 finite joint"):
            busy.resume([0.0] * 6 + [np.nan])
    finally:
        env.close()


def test_the_users_userdata_comes_first_and_is_left_alone() -> None:
    from mjkdl.task.registry import panda_pick_cube_spec

    spec = panda_pick_cube_spec()
    spec.scene.userdata = 3
    env = TaskEnv(spec)
    try:
        env.reset(seed=0)
        userdata = env.scene.data.userdata
        assert len(userdata) == 3 + 2 + 2 * 7  # the user's, the counters, command + solution
        userdata[:3] = [1.0, 2.0, 3.0]
        env.step(np.zeros(7, np.float32))
        env.step(np.zeros(7, np.float32))
        assert userdata[:3].tolist() == [1.0, 2.0, 3.0] and userdata[3] == env.elapsed_steps == 2
        assert env.task_spec.scene.userdata == 3  # the spec as given
    finally:
        env.close()


PICK = "mjkdl/PandaPickCube-v0"
RANDOM = {
    "body_mass": [0.5, 1.5],
    "geom_friction": [0.6, 1.4],
    "joint_damping": [0.8, 1.2],
    "gravity": [-0.2, 0.2],
    "action_latency": [1, 3],
    "action_noise": 0.05,
    "observation_noise": {"panda_tcp_pos": 0.002, "cube_pose": 0.003},
}


def test_a_randomised_state_with_its_draw_steps_on_exactly_as_recorded() -> None:
    """A whole PickCube demo under masses, friction, latency and noise: in another env, after
    another episode (another draw), each row with the demo's draw steps to the next row bit for
    bit, observations (noise included) too; the actions on their way are part of the state."""
    kwargs = {"randomization": RANDOM}
    rec_env, env = (
        make_env("mjkdl/PandaPickCube-v0", kwargs),
        make_env("mjkdl/PandaPickCube-v0", kwargs),
    )
    try:
        rec = run_episode(rec_env, make_policy("expert", rec_env), seed=4, record=True).data
        assert rec is not None and rec.randomization
        recorded = rec_env.unwrapped.randomization_draw  # type: ignore[attr-defined]
        assert recorded.action_latency >= 1 and recorded.body_mass is not None
        env.reset(seed=500)
        assert env.unwrapped.randomization_draw.to_dict() != recorded.to_dict()  # type: ignore[attr-defined]
        assert _rows_step_on_as_recorded(env, rec) == rec.num_samples > 20
        # the model is the recorded episode's, to the bit
        m, r = scene_of(env).model, scene_of(rec_env).model
        for name in ("body_mass", "body_inertia", "geom_friction", "dof_damping"):
            assert np.array_equal(getattr(m, name), getattr(r, name)), name
        assert np.array_equal(m.opt.gravity, r.opt.gravity)
    finally:
        env.close()
        rec_env.close()


def test_a_randomised_state_without_its_draw_is_refused() -> None:
    random, plain = (
        make_env("mjkdl/PandaPickCube-v0", {"randomization": RANDOM}),
        make_env("mjkdl/PandaPickCube-v0"),
    )
    try:
        rec = run_episode(random, make_policy("expert", random), seed=1, record=True).data
        assert rec is not None
        random.reset(seed=2)
        plain.reset(seed=2)
        with pytest.raises(ValueError, match=r"this env is randomised .* draw=demo.randomization"):
            restore(random, rec.states[3])
        with pytest.raises(ValueError, match=r"this env has no randomization: make it with"):
            restore(plain, rec.states[3], draw=rec.randomization)
        with pytest.raises(ValueError, match=r"no TaskSpec.randomization: it takes no draw"):
            plain.unwrapped.randomization_draw = Draw()  # type: ignore[attr-defined]
        with pytest.raises(ValueError, match=r"restore: draw is not a Draw or its dict"):
            restore(random, rec.states[3], draw={"body_mas": []})
        longer = json.loads(rec.randomization) | {"action_latency": 4}
        with pytest.raises(ValueError, match=r"action_latency \(4 steps\) is beyond .* \(1, 3\)"):
            restore(random, rec.states[3], draw=longer)
        noisy = json.loads(rec.randomization) | {"observation_noise": {"cube_rgb": 0.1}}
        with pytest.raises(KeyError, match=r"'cube_rgb' in the draw's observation_noise"):
            restore(random, rec.states[3], draw=noisy)
    finally:
        random.close()
        plain.close()


def test_convert_by_states_regenerates_a_randomised_demo(tmp_path: Path) -> None:
    """`convert --mode states` restores each row with the demo's draw: every observation,
    noise included, and the last `next_obs` come back as recorded."""
    src, out = tmp_path / "a.hdf5", tmp_path / "b.hdf5"
    kwargs = {"randomization": RANDOM}
    collect(
        PICK,
        "expert",
        src,
        episodes=1,
        seed=0,
        env_kwargs=kwargs,
        keep_failures=True,
        progress=False,
    )
    convert(src, out, mode="states")
    with DemoFile(src) as a, DemoFile(out) as b:
        recorded, regenerated = a.demo(a.names[0]), b.demo(b.names[0])
        assert recorded.randomization and recorded.num_samples > 20
        assert _differ(recorded.obs, regenerated.obs) == []
        assert _differ(recorded.final_obs, regenerated.final_obs) == []


def test_a_state_of_the_franka_impedance_drive_steps_on_exactly_as_recorded() -> None:
    """The drive's ramp and rate limiter live in userdata with the rest of the carried state:
    every row of a whole PickCube expert demo on `arm_drive="franka_impedance"`, with its
    commands drawn 1 ms ticks late, steps on bit for bit."""
    menagerie("franka_emika_panda")
    late = {"action_latency_ticks": [10, 40]}
    env = make_env(
        "mjkdl/PandaPickCube-v0", {"arm_drive": "franka_impedance", "randomization": late}
    )
    try:
        rec = run_episode(env, make_policy("expert", env), seed=4, record=True).data
        assert rec is not None and rec.success and rec.num_samples > 20
        assert 10 <= json.loads(rec.randomization)["action_latency_ticks"] <= 40
        env.reset(seed=500)  # another episode's state first: nothing of it may leak
        assert _rows_step_on_as_recorded(env, rec) == rec.num_samples
    finally:
        env.close()
