"""A reinforcement-learning environment built from parts, as in dm_robotics_panda's tutorial.

A Panda with a wrist camera (RGB and depth), a red ball to reach and ten grey props scattered
around it without touching anything. Every episode starts from a random TCP pose; the reward is
`1 - distance` between the TCP and the ball, clipped to [0, 1]. The agent here is a hand-written
proportional controller that hovers 10 cm above the ball — a stand-in for a learned policy.

    python examples/rl_environment.py                 # viewer, live plots; Backspace: new episode
    python examples/rl_environment.py --headless      # prints the spaces and the final reward
"""

from __future__ import annotations

import numpy as np
from common import parse_args
from tqdm import tqdm

import mjkdl as mjk
from mjkdl import task
from mjkdl.task.registry import panda_arm, panda_scene

BALL_RADIUS = 0.04
HOVER = 0.1  # metres above the ball's centre the agent aims for
SHAPES = [
    (mjk.Shape.BOX, [0.025, 0.025, 0.025]),
    (mjk.Shape.CYLINDER, [0.02, 0.03]),
    (mjk.Shape.CAPSULE, [0.015, 0.02]),
    (mjk.Shape.ELLIPSOID, [0.03, 0.02, 0.015]),
    (mjk.Shape.SPHERE, [0.025]),
]


def props(rng: np.random.Generator) -> list[mjk.SceneObject]:
    """The ball, then ten grey primitives of random kinds and sizes (the scene is fixed once
    built; where they stand is drawn at every reset)."""
    ball = mjk.SceneObject(
        name="ball", shape=mjk.Shape.SPHERE, size=[BALL_RADIUS], mass=1.0, rgba=[1.0, 0.0, 0.0, 1.0]
    )
    out = [ball]
    for i in range(10):
        shape, size = SHAPES[rng.integers(len(SHAPES))]
        scale = rng.uniform(0.7, 1.3)
        out.append(
            mjk.SceneObject(
                name=f"prop{i}",
                shape=shape,
                size=[s * scale for s in size],
                mass=0.1,
                rgba=[0.5, 0.5, 0.5, 1.0],
            )
        )
    return out


def spec() -> task.TaskSpec:
    scene = panda_scene(props(np.random.default_rng(7)))
    # A camera on the hand looking along the fingers (MuJoCo cameras look down their -z).
    scene.cameras.append(
        mjk.CameraSpec(
            name="wrist_camera",
            pos=[0.08, 0.0, 0.0],
            euler=[180.0, 0.0, -90.0],
            fovy=90.0,
            attach_to=mjk.AttachTarget(mjk.AttachKind.Body, "hand"),
        )
    )
    names = [o.name for o in scene.objects]
    return task.TaskSpec(
        scene=scene,
        arms=[panda_arm()],
        sensors=[
            task.CameraSensor("wrist_camera", width=64, height=64, depth=True, name="wrist_cam"),
            task.BodyPoseSensor("ball", name="goal"),
        ],
        initializers=[  # the arm first, then the props around where it stands
            task.PoseInitializer(
                "panda", low=[0.3, -0.3, 0.3, 165, -15, -120], high=[0.6, 0.3, 0.6, 195, 15, -60]
            ),
            task.PropPlacer(names, low=[0.3, -0.4, 0.06], high=[0.7, 0.4, 0.06]),
        ],
        reward=task.ReachReward("panda_tcp_pos", "goal_pose"),
    )


def hover_agent(obs: dict[str, np.ndarray]) -> np.ndarray:
    """TCP velocity toward a point `HOVER` above the ball (gain 2/s, at most 0.25 m/s)."""
    target = obs["goal_pose"][:3] + np.array([0.0, 0.0, HOVER])
    velocity = np.clip(2.0 * (target - obs["panda_tcp_pos"]), -0.25, 0.25)
    return np.concatenate([velocity, np.zeros(4)]).astype(np.float32)  # no turn, gripper open


def main() -> int:
    args = parse_args(__doc__.splitlines()[0], duration=4.0)
    env = task.TaskEnv(spec())
    print("action:", env.action_space, ", ".join(env.action_labels))
    for name, space in env.observation_space.spaces.items():
        print(f"  {name}: {space.shape} {space.dtype}")
    if not args.headless:
        task.view(env, hover_agent, plots=["panda_tcp_pos", "goal_pose"], seed=0)
        env.close()
        return 0
    obs, _ = env.reset(seed=0)
    reward = 0.0
    steps = round(args.duration / env.control_timestep)
    for _ in tqdm(range(steps), desc="control steps", disable=None, delay=1.0):
        obs, reward, *_ = env.step(hover_agent(obs))
    depth = obs["wrist_cam_depth"]
    print(f"simulated: {obs['time'][0]:.2f} s")
    print(f"distance: {np.linalg.norm(obs['goal_pose'][:3] - obs['panda_tcp_pos']):.4f} m")
    print(f"reward: {reward:.4f}")
    print(f"wrist depth: {depth.min():.3f} .. {depth.max():.3f} m")
    env.close()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
