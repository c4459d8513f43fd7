"""Domain randomisation: one description, a draw per episode from the env's generator, applied
from the nominal model at reset, stored with recorded demos (replay stays exact), bad ranges
refused by field."""

from __future__ import annotations

import json
from pathlib import Path

import gymnasium as gym
import h5py
import numpy as np
import pytest

import mjkdl
import mjkdl.task
from mjkdl.demos import DemoFile, collect, replay
from mjkdl.errors import SpecError, SpecTypeError, UnknownNameError
from mjkdl.task import TaskEnv
from mjkdl.task.randomization import Draw, Randomization, Uniform
from mjkdl.task.registry import panda_pick_cube_spec

PICK = "mjkdl/PandaPickCube-v0"
PHYSICS = {
    "body_mass": [0.5, 1.5, ["cube"]],
    "body_com": [-0.005, 0.005, ["cube"]],
    "geom_friction": [0.5, 1.5],
    "joint_damping": [0.5, 2.0],
    "joint_armature": [0.8, 1.2],
    "joint_frictionloss": [0.5, 1.5],
    "actuator_gain": [0.8, 1.2],
    "gravity": [-0.3, 0.3],
    "camera_pos": [-0.01, 0.01, ["front"]],
    "camera_euler": [-2.0, 2.0, ["front"]],
    "camera_fovy": [-3.0, 3.0],
    "light_diffuse": [0.6, 1.0],
    "geom_rgba": [0.2, 0.9, ["cube"]],
}


def test_each_episode_draws_from_the_nominal_model_and_a_seed_draws_the_same() -> None:
    env = gym.make(PICK, randomization=PHYSICS)
    u = env.unwrapped
    m = u.scene.model
    cube = m.body("cube").id
    mass, inertia, gravity = m.body_mass[cube], m.body_inertia[cube].copy(), m.opt.gravity.copy()
    front, box = m.camera("front").id, m.geom(m.body_geomadr[cube]).id
    cam_pos, cam_quat, fovy = m.cam_pos[front].copy(), m.cam_quat[front].copy(), m.cam_fovy.copy()
    diffuse = m.light_diffuse.copy()
    plain = gym.make(PICK)  # the robot's servos in their mode, as every episode has them
    plain.reset(seed=0)
    gain = plain.unwrapped.scene.model.actuator_gainprm.copy()
    bias = plain.unwrapped.scene.model.actuator_biasprm.copy()
    plain.close()
    try:
        obs3, _ = env.reset(seed=3)
        d3 = u.randomization_draw
        scale = d3.body_mass.values[0, 0]
        assert d3.body_mass.ids == (cube,) and 0.5 <= scale <= 1.5
        assert m.body_mass[cube] == mass * scale  # mass and inertia by the same factor
        np.testing.assert_array_equal(m.body_inertia[cube], inertia * scale)
        np.testing.assert_array_equal(m.opt.gravity, gravity + np.array(d3.gravity))
        assert len(d3.joint_damping.ids) == m.njnt and d3.action_latency == 0
        # every actuator's gain and feedback by its factor (the arm's position servos)
        k = d3.actuator_gain.values[0, 0]
        np.testing.assert_allclose(m.actuator_gainprm[0, 0], gain[0, 0] * k, rtol=1e-15)
        np.testing.assert_allclose(m.actuator_biasprm[0, 1:3], bias[0, 1:3] * k, rtol=1e-15)
        # what is seen: the front camera's pose and every camera's view, lights, the cube
        np.testing.assert_array_equal(m.cam_pos[front], cam_pos + d3.camera_pos.values[0])
        np.testing.assert_array_equal(m.cam_fovy, fovy + d3.camera_fovy.values[:, 0])
        turned = 2 * np.degrees(np.arccos(min(1.0, abs(float(m.cam_quat[front] @ cam_quat)))))
        assert 0.0 < turned <= 2.0 * np.sqrt(3) + 1e-9  # degrees: at most 2 about each axis
        # (MuJoCo keeps lights and colours in float32)
        np.testing.assert_allclose(m.light_diffuse, diffuse * d3.light_diffuse.values, rtol=1e-6)
        np.testing.assert_allclose(m.geom_rgba[box, :3], d3.geom_rgba.values[0], rtol=1e-6)
        assert np.all((d3.geom_rgba.values >= 0.2) & (d3.geom_rgba.values <= 0.9))
        env.reset(seed=4)
        assert u.randomization_draw.to_dict() != d3.to_dict()
        assert m.body_mass[cube] == mass * u.randomization_draw.body_mass.values[0, 0]
        again, _ = env.reset(seed=3)  # from the nominal values, not on top of seed 4's
        assert u.randomization_draw.to_dict() == d3.to_dict()
        assert m.body_mass[cube] == mass * scale
        for key in obs3:
            np.testing.assert_array_equal(again[key], obs3[key])
        # the draw is plain data: through JSON and back it is the same
        assert Draw.from_dict(json.loads(json.dumps(d3.to_dict()))).to_dict() == d3.to_dict()
    finally:
        env.close()


def test_a_rebuilt_scene_is_randomised_from_its_own_nominal_model() -> None:
    env = gym.make(PICK, randomization={"body_mass": [0.5, 1.5, ["cube"]], "gravity": [-1, 1]})
    u = env.unwrapped
    try:
        env.reset(seed=0)
        u.scene.add_object(
            mjkdl.SceneObject(name="block", shape=mjkdl.Shape.BOX, size=[0.03] * 3, mass=0.2,
                              pos=[0.0, 0.6, 0.1])
        )  # fmt: skip
        m = u.scene.model
        nominal_mass, nominal_g = m.body("cube").mass[0], m.opt.gravity.copy()
        env.reset(seed=1)
        draw = u.randomization_draw
        assert m is u.scene.model
        assert m.body("cube").mass[0] == nominal_mass * draw.body_mass.values[0, 0]
        np.testing.assert_array_equal(m.opt.gravity, nominal_g + np.array(draw.gravity))
    finally:
        env.close()


def test_the_placements_of_a_seed_stay_those_of_the_nominal_task() -> None:
    """The draw comes after the initializers: the cube lies where the seed puts it either way."""
    plain, rand = gym.make(PICK), gym.make(PICK, randomization={"body_mass": [0.5, 2.0]})
    try:
        a, _ = plain.reset(seed=11)
        b, _ = rand.reset(seed=11)
        np.testing.assert_array_equal(a["cube_pose"], b["cube_pose"])
    finally:
        plain.close()
        rand.close()


def test_action_latency_applies_each_action_whole_steps_late() -> None:
    spec = panda_pick_cube_spec()
    spec.randomization = Randomization(action_latency=(2, 2))  # TaskSpec takes it too
    late = TaskEnv(spec)
    plain = TaskEnv(panda_pick_cube_spec())
    try:
        late.reset(seed=0)
        plain.reset(seed=0)
        assert late.randomization_draw is not None and late.randomization_draw.action_latency == 2
        rng = np.random.default_rng(0)
        actions = [rng.uniform(-1, 1, late.action_space.shape) for _ in range(6)]
        delayed = [actions[0], actions[0], *actions[:4]]  # the first action until then
        for a, d in zip(actions, delayed, strict=True):
            ol, *_ = late.step(a)
            op, *_ = plain.step(d)
        for key in op:
            np.testing.assert_array_equal(ol[key], op[key])
    finally:
        late.close()
        plain.close()


def _record_targets(limiter: object, into: list[np.ndarray]) -> None:
    """Keep a copy of every tick's target the drive hands `limiter.positions`."""
    positions = limiter.positions  # type: ignore[attr-defined]

    def recorded(q: np.ndarray, q_out: np.ndarray, dq_out: np.ndarray) -> None:
        into.extend(q.copy())
        positions(q, q_out, dq_out)

    limiter.positions = recorded  # type: ignore[attr-defined]


def test_a_drawn_mass_leaves_the_arms_compensation_nominal() -> None:
    """On the impedance drive MuJoCo's gravcomp cancels the arm's weight as the robot does,
    from its nominal model: a drawn link mass pulls on the arm by what it adds."""
    kw = {"arm_drive": "franka_impedance"}
    nominal = gym.make(PICK, **kw)
    drawn = gym.make(PICK, randomization={"body_mass": [0.8, 1.2]}, **kw)
    try:
        nominal.reset(seed=0)
        m0, m = nominal.unwrapped.scene.model, drawn.unwrapped.scene.model
        arm = [m.body(f"link{i}").id for i in range(1, 8)]
        for seed in (0, 1):  # drawn, then undone and drawn again
            drawn.reset(seed=seed)
            assert np.abs(m.body_mass[arm] / m0.body_mass[arm] - 1.0).max() > 0.05
            cancelled = m.body_mass[arm] * m.body_gravcomp[arm]
            np.testing.assert_allclose(cancelled, m0.body_mass[arm], rtol=1e-12)
    finally:
        nominal.close()
        drawn.close()


def test_action_latency_ticks_applies_each_target_ticks_late_on_the_impedance_drive() -> None:
    """With `arm_drive="franka_impedance"`, each period's targets reach the rate limiter the
    drawn number of 1 ms ticks late: the same positions as without latency, that many ticks
    later (the arm at rest at its start until then); drawn per episode in the range."""
    kw = {"arm_drive": "franka_impedance", "actuation": "joint_position"}
    late = gym.make(PICK, randomization={"action_latency_ticks": [7, 7]}, **kw)
    plain = gym.make(PICK, **kw)
    try:
        seen: dict[str, list[np.ndarray]] = {"late": [], "plain": []}
        for name, env in (("late", late), ("plain", plain)):
            env.reset(seed=0)
            _record_targets(env.unwrapped.drive.limiter, seen[name])
        assert late.unwrapped.drive.latency == 7 and plain.unwrapped.drive.latency == 0
        start = late.unwrapped.drive.robot.jnt_pos_msr.copy()
        rng = np.random.default_rng(1)
        for _ in range(3):
            action = rng.uniform(-0.2, 0.2, late.action_space.shape)
            late.step(action)
            plain.step(action)
        delayed, on_time = np.array(seen["late"]), np.array(seen["plain"])
        assert len(delayed) == len(on_time) == 300
        np.testing.assert_array_equal(delayed[:7], np.tile(start, (7, 1)))
        np.testing.assert_array_equal(delayed[7:], on_time[:-7])
    finally:
        late.close()
        plain.close()
    drawn = gym.make(PICK, randomization={"action_latency_ticks": [0, 40]}, **kw)
    try:
        ticks = set()
        for seed in range(6):
            drawn.reset(seed=seed)
            latency = drawn.unwrapped.drive.latency
            assert drawn.unwrapped.randomization_draw.action_latency_ticks == latency
            ticks.add(latency)
        assert len(ticks) > 1 and ticks <= set(range(41))
    finally:
        drawn.close()
    with pytest.raises(SpecError, match=r"a control period is 100 ticks, so at most 99"):
        gym.make(PICK, randomization={"action_latency_ticks": [0, 100]}, **kw)


def test_observation_noise_is_what_the_agent_sees_and_not_what_rewards_see() -> None:
    kw = {"hide_observations": ()}
    plain = gym.make(PICK, **kw)
    noisy = gym.make(PICK, randomization={"observation_noise": {"cube_pose": 0.01}}, **kw)
    try:
        a, _ = plain.reset(seed=5)
        b, _ = noisy.reset(seed=5)
        diff = b["cube_pose"] - a["cube_pose"]
        assert 0.0 < np.abs(diff).max() < 0.06  # 1 cm standard deviation on 7 entries
        np.testing.assert_array_equal(a["panda_joint_pos"], b["panda_joint_pos"])
        action = np.zeros(plain.action_space.shape)
        _, ra, *_ = plain.step(action)
        _, rb, *_ = noisy.step(action)
        assert ra == rb  # the reward sees the true cube
    finally:
        plain.close()
        noisy.close()


@pytest.mark.parametrize(
    ("value", "error", "message"),
    [
        ({"body_mass": [0.0, 1.2]}, SpecError, "randomization.body_mass: a scale range must be"),
        ({"geom_friction": [1.5, 1.0]}, SpecError, "randomization.geom_friction: low must not"),
        (
            {"gravity": [0.0, float("nan")]},
            SpecError,
            "randomization.gravity.high must be a finite",
        ),
        ({"geom_rgba": [0.0, 1.5]}, SpecError, "randomization.geom_rgba: colour channels lie"),
        (
            {"joint_damping": [0.5, 2.0, ["joint9"]]},
            UnknownNameError,
            "no joint named 'joint9' in randomization.joint_damping",
        ),
        (
            {"observation_noise": {"cube_pos": 0.01}},
            UnknownNameError,
            "no observation named 'cube_pos' in randomization.observation_noise; close matches: "
            "cube_pose",
        ),
        (
            {"observation_noise": {"cube_pose": -0.1}},
            SpecError,
            "randomization.observation_noise['cube_pose'] must be a finite standard deviation",
        ),
        ({"action_latency": [3, 1]}, SpecError, "randomization.action_latency must be (low, high)"),
        (
            {"action_latency_ticks": [2.5, 4]},
            SpecError,
            "randomization.action_latency_ticks must be (low, high) whole 1 ms ticks",
        ),
        (
            {"action_latency_ticks": [0, 5]},
            SpecError,
            "randomization.action_latency_ticks delays the 1 ms ticks of arm_drive='franka_imp",
        ),
        ({"action_noise": "high"}, SpecTypeError, "randomization.action_noise must be a standard"),
        ({"body_masses": [0.5, 1.5]}, UnknownNameError, "close matches: body_mass"),
        ("heavy", SpecTypeError, "randomization must be a Randomization, a dict"),
        ({"body_mass": Uniform(0.5, 1.5, ["cube"])}, SpecTypeError, ".names must be a tuple"),
    ],
)
def test_bad_descriptions_are_refused_by_field(value: object, error: type, message: str) -> None:
    with pytest.raises(error) as caught:
        gym.make(PICK, randomization=value)
    assert message in str(caught.value), str(caught.value)


def test_recorded_demos_store_the_draw_and_replay_exactly(tmp_path: Path) -> None:
    out = tmp_path / "dr.hdf5"
    kwargs = {"randomization": {**PHYSICS, "action_latency": [0, 1], "action_noise": 0.05}}
    collect(PICK, "expert", out, episodes=2, seed=20, env_kwargs=kwargs, keep_failures=True,
            progress=False)  # fmt: skip
    env = gym.make(PICK, **kwargs)
    try:
        env.reset(seed=21)
        expected = env.unwrapped.randomization_draw.to_dict()
    finally:
        env.close()
    with DemoFile(out) as f:
        assert json.loads(f.demo(1).randomization) == expected
    result = replay(out, 1)
    assert result.max_state_error == 0.0 and result.first_mismatch == -1
    with h5py.File(out, "r+") as f:  # another draw than the env makes: refused by name
        f["data/demo_0"].attrs["randomization"] = json.dumps({**expected, "action_latency": 5})
    with pytest.raises(SpecError, match="demo_0: recorded with a domain-randomisation draw"):
        replay(out, 0)
