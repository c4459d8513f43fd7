"""Initializers: props placed without contact, TCP poses by IK, joints, physical parameters."""

from __future__ import annotations

import mujoco
import numpy as np
import pinocchio as pin
import pytest
from conftest import menagerie
from gymnasium.utils import seeding

import mjkdl as mjk
from mjkdl.compile import euler_quat
from mjkdl.task import (
    JointInitializer,
    PhysicsRandomizer,
    PoseInitializer,
    PropPlacer,
    TaskEnv,
    TaskSpec,
)
from mjkdl.task.registry import PANDA_HOME, panda_arm, panda_scene

PROPS = [f"prop{i}" for i in range(10)]


@pytest.fixture(autouse=True)
def _panda() -> None:
    menagerie("franka_emika_panda")


def props() -> list[mjk.SceneObject]:
    shapes = [
        (mjk.Shape.BOX, [0.03, 0.02, 0.04]),
        (mjk.Shape.SPHERE, [0.035]),
        (mjk.Shape.CYLINDER, [0.03, 0.03]),
    ]
    return [
        mjk.SceneObject(
            name=name,
            shape=shapes[i % 3][0],
            size=shapes[i % 3][1],
            mass=0.1,
            pos=[-1.0, 0.0, 0.05],
        )  # all start in one spot, overlapping
        for i, name in enumerate(PROPS)
    ]


def env_with(*initializers, objects=None) -> TaskEnv:
    scene = panda_scene(props() if objects is None else objects)
    return TaskEnv(TaskSpec(scene=scene, arms=[panda_arm()], initializers=list(initializers)))


def prop_contacts(env: TaskEnv) -> int:
    """Contacts involving any prop, by MuJoCo's own collision detection after a forward."""
    model, data = env.scene.model, env.scene.data
    mujoco.mj_forward(model, data)
    ids = {env.scene.body_id(name) for name in PROPS}
    return sum(
        1
        for c in data.contact[: data.ncon]
        if model.geom_bodyid[c.geom1] in ids or model.geom_bodyid[c.geom2] in ids
    )


def test_prop_placer_leaves_no_contact() -> None:
    placer = PropPlacer(PROPS, low=[0.3, -0.3, 0.05], high=[0.6, 0.3, 0.05])
    env = env_with(placer)
    model, data = env.scene.model, env.scene.data
    for seed in range(3):
        env.reset(seed=seed)
        assert prop_contacts(env) == 0
        for name in PROPS:
            b = env.scene.body_id(name)
            x, y, z = data.xpos[b]
            assert 0.3 <= x <= 0.6 and -0.3 <= y <= 0.3 and z == pytest.approx(0.05)
            qw, qx, qy, qz = data.xquat[b]
            assert qx == qy == 0.0 and qw**2 + qz**2 == pytest.approx(1.0)  # a yaw only
    assert model.nbody > 0
    env.close()


def test_prop_placer_without_yaw_keeps_the_orientation() -> None:
    objects = props()[:2]
    objects[0].euler = [0.0, 0.0, 30.0]
    env = env_with(
        PropPlacer(PROPS[:2], [0.3, -0.3, 0.05], [0.6, 0.3, 0.05], random_yaw=False),
        objects=objects,
    )
    env.reset(seed=0)
    np.testing.assert_allclose(
        env.scene.data.xquat[env.scene.body_id("prop0")], euler_quat([0, 0, 30], "q"), atol=1e-12
    )
    env.close()


def test_impossible_box_names_the_prop() -> None:
    # Inside the floor: every draw touches it.
    env = env_with(PropPlacer(["prop3"], low=[0.3, 0, 0.0], high=[0.4, 0, 0.01], max_tries=7))
    with pytest.raises(ValueError, match=r"'prop3'.*7 tries"):
        env.reset(seed=0)
    env.close()


def test_prop_placer_keeps_clear_of_a_body_placed_before() -> None:
    """`min_distance` from `away_from`, horizontally; the draws it refuses cost no contact
    check, and a box that cannot hold the gap names the body and the gap."""
    clear = PropPlacer(["prop1"], [0.3, -0.3, 0.05], [0.6, 0.3, 0.05], False, 100, "prop0", 0.2)
    env = env_with(PropPlacer(["prop0"], [0.3, -0.3, 0.05], [0.6, 0.3, 0.05]), clear)
    gaps = []
    for seed in range(20):
        env.reset(seed=seed)
        xpos = env.scene.data.xpos
        p0, p1 = xpos[env.scene.body_id("prop0")], xpos[env.scene.body_id("prop1")]
        gaps.append(float(np.hypot(*(p1 - p0)[:2])))
    assert min(gaps) >= 0.2, gaps
    env.close()
    tight = PropPlacer(["prop1"], [0.3, 0, 0.05], [0.35, 0, 0.05], False, 7, "prop0", 0.5)
    env = env_with(PropPlacer(["prop0"], [0.3, 0, 0.05], [0.3, 0, 0.05]), tight)
    with pytest.raises(ValueError, match=r"'prop1' without contact and 0\.5 m from 'prop0' in 7"):
        env.reset(seed=0)
    env.close()


@pytest.mark.parametrize(
    ("placer", "error", "message"),
    [
        (
            PropPlacer(["prop0", "porp1"], [0, 0, 0.1], [0, 0, 0.1]),
            KeyError,
            r"'porp1' in PropPlacer\.bodies\[1\]",
        ),
        (
            PropPlacer(["link3"], [0, 0, 0.1], [0, 0, 0.1]),
            ValueError,
            "'link3' is neither a free body",
        ),
        (
            PropPlacer(["prop0"], [0, 0, 0.1], [0, 0, 0.1], away_from="porp1", min_distance=0.1),
            KeyError,
            r"'porp1' in PropPlacer\.away_from",
        ),
        (PropPlacer(["prop0"], [0, 0, 0.1], [0, 0]), ValueError, r"PropPlacer\.high"),
        (PropPlacer(["prop0"], [0, 0, 0.2], [0, 0, 0.1]), ValueError, "low must not exceed"),
        (PropPlacer("prop0", [0, 0, 0.1], [0, 0, 0.1]), ValueError, "list of body names"),
    ],
)
def test_prop_placer_bad_input(placer, error, message) -> None:
    env = env_with(placer)
    with pytest.raises(error, match=message):
        env.reset(seed=0)
    env.close()


def test_pose_initializer_reaches_its_sampled_pose() -> None:
    low = [0.35, -0.2, 0.3, 170.0, -10.0, -60.0]
    high = [0.55, 0.2, 0.5, 190.0, 10.0, -30.0]
    env = env_with(PoseInitializer("panda", low, high), objects=[])
    robot = env.robots["panda"]
    for seed in range(5):
        obs, _ = env.reset(seed=seed)
        rng, _ = seeding.np_random(seed)
        x = rng.uniform(low, high)  # the initializer's first draw
        target = pin.SE3(pin.Quaternion(*euler_quat(x[3:], "x")).matrix(), x[:3])
        reached = robot.fk_frame()
        assert np.linalg.norm(reached.translation - target.translation) < 1e-5
        assert np.linalg.norm(pin.log3(reached.rotation.T @ target.rotation)) < 1e-4
        np.testing.assert_allclose(obs["panda_tcp_pos"], target.translation, atol=1e-5)
        # Synced: the arm holds the pose (no stale home command pulls it back).
        obs, *_ = env.step(np.zeros(7))
        np.testing.assert_allclose(obs["panda_tcp_pos"], target.translation, atol=2e-3)
    env.close()


def test_pose_initializer_unreachable_box_and_unknown_arm() -> None:
    far = PoseInitializer("panda", [3, 0, 0.5, 180, 0, 0], [3, 0, 0.5, 180, 0, 0], max_tries=2)
    env = env_with(far, objects=[])
    with pytest.raises(ValueError, match=r"PoseInitializer\('panda'\).*2 draws"):
        env.reset(seed=0)
    env.task_spec.initializers = [PoseInitializer("pnda", [0] * 6, [0] * 6)]
    with pytest.raises(KeyError, match=r"'pnda'.*close matches: panda"):
        env.reset(seed=0)
    env.close()


def test_joint_initializer_draws_in_its_box() -> None:
    low = np.array(PANDA_HOME) - 0.2
    high = np.array(PANDA_HOME) + 0.2
    env = env_with(JointInitializer("panda", low, high), objects=[])
    obs, _ = env.reset(seed=4)
    rng, _ = seeding.np_random(4)
    np.testing.assert_array_equal(obs["panda_joint_pos"], rng.uniform(low, high))
    env.task_spec.initializers = [JointInitializer("panda", low[:3], high[:3])]
    with pytest.raises(ValueError, match=r"JointInitializer\('panda'\)\.low must have 7"):
        env.reset(seed=0)
    high[3] = 0.5  # joint4's upper limit is -0.0698
    env.task_spec.initializers = [JointInitializer("panda", low, high)]
    with pytest.raises(ValueError, match="joint limits of joint4"):
        env.reset(seed=0)
    env.close()


def test_physics_randomizer_edits_the_model_without_compounding() -> None:
    rand = PhysicsRandomizer(
        ["prop0", "prop1"], mass_scale=(0.5, 2.0), friction_scale=(0.8, 1.2), colors=True
    )
    env = env_with(rand)
    model = env.scene.model
    b0 = env.scene.body_id("prop0")
    nominal = model.body_mass[b0]
    geom = int(np.flatnonzero(model.geom_bodyid == b0)[0])
    masses, colors = [], []
    for seed in range(6):
        env.reset(seed=seed)
        assert env.scene.model is model  # edited in place, not rebuilt
        masses.append(model.body_mass[b0])
        colors.append(model.geom_rgba[geom].copy())
        assert 0.5 * nominal <= masses[-1] <= 2.0 * nominal
        assert 0.8 <= model.geom_friction[geom, 0] <= 1.2
        # MuJoCo's derived constant follows: the subtree mass is the body's.
        assert model.body_subtreemass[b0] == pytest.approx(masses[-1])
    assert len(set(masses)) == 6
    env.reset(seed=2)
    assert model.body_mass[b0] == masses[2]
    np.testing.assert_array_equal(model.geom_rgba[geom], colors[2])
    env.close()


def test_physics_randomizer_unknown_body() -> None:
    env = env_with(PhysicsRandomizer(["prop0", "prp1"]))
    with pytest.raises(KeyError, match=r"'prp1' in PhysicsRandomizer\.bodies\[1\]"):
        env.reset(seed=0)
    env.close()


def test_randomized_arm_masses_reach_the_pinocchio_model() -> None:
    env = env_with(PhysicsRandomizer(["link6", "link7", "hand"], mass_scale=(1.5, 2.0)), objects=[])
    robot = env.robots["panda"]
    data = env.scene.data
    nominal = robot.gravity_torques().copy()  # before any reset: the authored masses
    for seed in range(3):
        env.reset(seed=seed)
        mujoco.mj_forward(env.scene.model, data)
        robot.update()
        # At rest MuJoCo's bias force is gravity alone: Pinocchio must agree with the new masses.
        np.testing.assert_allclose(
            robot.gravity_torques(), data.qfrc_bias[:7], rtol=1e-8, atol=1e-9
        )
        assert np.abs(robot.gravity_torques() - nominal).max() > 0.05
    env.close()


def test_a_failed_reset_leaves_no_episode_to_step() -> None:
    env = env_with(objects=[])
    env.reset(seed=0)
    env.step(np.zeros(7))
    env.task_spec.initializers = [
        PoseInitializer("panda", [3, 0, 0, 0, 0, 0], [3, 0, 0, 0, 0, 0], max_tries=1)
    ]
    with pytest.raises(ValueError, match="PoseInitializer"):
        env.reset(seed=1)
    with pytest.raises(RuntimeError, match="before reset"):
        env.step(np.zeros(7))
    env.close()


@pytest.fixture(scope="module")
def props_env():
    """An env with the props, its initializers set per test."""
    menagerie("franka_emika_panda")
    env = env_with()
    yield env
    env.close()


BOX = ([0.4, 0.0, 0.1], [0.5, 0.1, 0.1])
POSE = ([0.4, 0, 0.4, 180, 0, 0], [0.45, 0, 0.45, 180, 0, 0])


@pytest.mark.parametrize(
    ("initializer", "error", "message"),
    [
        (
            PoseInitializer("panda", *POSE, max_tries=2.5),  # type: ignore[arg-type]
            mjk.SpecTypeError,
            "PoseInitializer('panda').max_tries must be a positive integer, got 2.5",
        ),
        (
            PoseInitializer("panda", *POSE, max_tries=None),  # type: ignore[arg-type]
            mjk.SpecTypeError,
            "PoseInitializer('panda').max_tries must be a positive integer, got None",
        ),
        (
            PoseInitializer("panda", *POSE, max_tries=0),
            mjk.SpecError,
            "PoseInitializer('panda').max_tries must be a positive integer, got 0",
        ),
        (
            PoseInitializer("panda", *POSE, max_tries=-3),
            mjk.SpecError,
            "PoseInitializer('panda').max_tries must be a positive integer, got -3",
        ),
        (
            PoseInitializer("panda", *POSE, max_tries=True),
            mjk.SpecTypeError,
            "PoseInitializer('panda').max_tries must be a positive integer, got True",
        ),
        (
            PropPlacer(["prop0"], *BOX, max_tries=np.True_),  # type: ignore[arg-type]
            mjk.SpecTypeError,
            "PropPlacer.max_tries must be a positive integer, got np.True_",
        ),
        (
            PropPlacer(None, *BOX),  # type: ignore[arg-type]
            mjk.SpecTypeError,
            "PropPlacer.bodies must be a list of body names, got None",
        ),
        (
            PropPlacer(["prop0", 5], *BOX),  # type: ignore[list-item]
            mjk.SpecTypeError,
            "PropPlacer.bodies[1] must be a string, got 5",
        ),
        (
            PropPlacer(["prop0"], *BOX, min_distance=-0.1, away_from="prop1"),
            mjk.SpecError,
            "PropPlacer.min_distance must be >= 0 (0: off), got -0.1",
        ),
        (
            PropPlacer(["prop0"], *BOX, min_distance=0.1),
            mjk.SpecError,
            "PropPlacer.min_distance needs PropPlacer.away_from: the body to keep clear of",
        ),
        (
            PropPlacer(["prop0"], *BOX, random_yaw="no"),  # type: ignore[arg-type]
            mjk.SpecTypeError,
            "PropPlacer.random_yaw must be True or False, got 'no'",
        ),
        (
            PhysicsRandomizer(None),  # type: ignore[arg-type]
            mjk.SpecTypeError,
            "PhysicsRandomizer.bodies must be a list of body names, got None",
        ),
        (
            PhysicsRandomizer("prop0"),
            mjk.SpecTypeError,
            "PhysicsRandomizer.bodies must be a list of body names, got 'prop0'",
        ),
        (
            PhysicsRandomizer([None]),  # type: ignore[list-item]
            mjk.SpecTypeError,
            "PhysicsRandomizer.bodies[0] must be a string, got None",
        ),
        (
            PhysicsRandomizer(["prop0"], colors="no"),  # type: ignore[arg-type]
            mjk.SpecTypeError,
            "PhysicsRandomizer.colors must be True or False, got 'no'",
        ),
        (
            JointInitializer({}, [0] * 7, [0] * 7),  # type: ignore[arg-type]
            mjk.SpecTypeError,
            "JointInitializer.arm must be a string, got {}",
        ),
        (
            PoseInitializer(["panda"], *POSE),  # type: ignore[arg-type]
            mjk.SpecTypeError,
            "PoseInitializer.arm must be a string, got ['panda']",
        ),
    ],
)
def test_initializer_fields_are_checked_by_name(props_env, initializer, error, message) -> None:
    props_env.task_spec.initializers = [initializer]
    with pytest.raises(error) as err:
        props_env.reset(seed=0)
    assert str(err.value) == message


def test_counts_may_be_numpy_integers(props_env) -> None:
    props_env.task_spec.initializers = [
        PropPlacer(["prop0"], *BOX, max_tries=np.int64(5)),
        PoseInitializer("panda", *POSE, max_tries=np.int32(20)),
    ]
    obs, _ = props_env.reset(seed=0)
    assert 0.4 <= obs["panda_tcp_pos"][0] <= 0.45
    assert 0.4 <= props_env.scene.data.xpos[props_env.scene.body_id("prop0")][0] <= 0.5
