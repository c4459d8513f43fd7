"""The PPO recipe (rsl-rl on `make_batch`) end to end at a small scale on the CPU engine."""

from __future__ import annotations

import dataclasses

import pytest
from conftest import import_extra

torch = import_extra("warp-rl", "torch")

from tensordict import TensorDict  # noqa: E402

from mjkdl.errors import SpecError  # noqa: E402
from mjkdl.task.batch.ppo import (  # noqa: E402
    DEFAULT_RECIPE,
    OBJECT_CPU,
    PUSH_CPU,
    RslRlEnv,
    auto_reset_workers,
    env_policy,
    recipe,
    train,
)


def test_recipe_trains_end_to_end_and_the_policy_acts() -> None:
    # 4 worlds, 4-step rollouts, episodes of 3 steps: every world resets mid-rollout.
    result = train(
        "mjkdl/PandaReach-v0",
        device="cpu",
        num_envs=4,
        num_steps_per_env=4,
        iterations=1,
        time_limit=0.3,
    )
    assert result.env_steps == 16
    policy = result.runner.get_inference_policy("cpu")
    # The observation normaliser saw every collected step (and the first observation).
    assert int(policy.obs_normalizer.count) >= 16
    obs = TensorDict({"policy": torch.zeros(5, 38)}, batch_size=[5])
    action = policy(obs)
    assert action.shape == (5, 7)
    assert bool(torch.isfinite(action).all())


def test_training_on_the_cpu_engine_repeats_with_its_seed() -> None:
    """`train(seed=)` seeds PyTorch, and the batch's physics and resets are deterministic: the
    same seed gives the same weights, another seed others."""

    def weights(seed: int) -> list[torch.Tensor]:
        result = train(
            "mjkdl/PandaReach-v0",
            device="cpu",
            num_envs=2,
            num_steps_per_env=4,
            iterations=2,
            seed=seed,
        )
        return [p.detach().clone() for p in result.runner.alg.get_policy().parameters()]

    first, again, other = weights(3), weights(3), weights(4)
    assert all(torch.equal(a, b) for a, b in zip(first, again, strict=True))
    assert not all(torch.equal(a, b) for a, b in zip(first, other, strict=True))


def test_the_env_policy_acts_on_the_cpu_and_goes_back() -> None:
    """`env_policy` evaluates on the CPU and puts the runner's policy back on the runner's
    device and object (on a GPU, `get_inference_policy("cpu")` alone left it on the CPU and
    the next `learn` failed on mixed devices, seen on an H200). Here the runner's device is
    the meta device, so that leaving it on the CPU shows."""
    import gymnasium as gym
    import numpy as np

    result = train(
        "mjkdl/PandaReach-v0", device="cpu", num_envs=2, num_steps_per_env=2, iterations=1
    )
    runner = result.runner
    own = runner.alg.get_policy()
    env = gym.make("mjkdl/PandaReach-v0")
    obs, _ = env.reset(seed=0)
    env.close()
    with env_policy(runner) as act:
        action = act(obs)
        flat = np.concatenate([np.ravel(v) for v in obs.values()]).astype(np.float32)
        with torch.no_grad():
            expected = own(TensorDict({"policy": torch.as_tensor(flat)[None]}, batch_size=[1]))
    np.testing.assert_array_equal(action, expected[0].numpy())
    assert action.shape == env.action_space.shape
    runner.device = "meta"
    with env_policy(runner) as act:
        assert {p.device.type for p in own.parameters()} == {"cpu"}
    assert runner.alg.get_policy() is own
    assert {p.device.type for p in own.parameters()} == {"meta"}


def test_the_object_recipes_act_by_translation_on_both_backends() -> None:
    """The object tasks' recipes act by translation and the gripper on a GPU as on the CPU; a
    batch made with the recipe's task parameters and the CPU env made with them take the same
    4-entry action."""
    import gymnasium as gym

    from mjkdl.task import make_batch

    for task in ("PickCube", "Push", "PickAndPlace"):
        gpu = recipe(f"mjkdl/Panda{task}-v0").on("cuda:0")
        cpu = recipe(f"mjkdl/Panda{task}-v0").on("cpu")
        assert gpu.task_kwargs == cpu.task_kwargs and gpu.config == OBJECT_CPU.config
        assert gpu.num_envs == 4096
    r = recipe("mjkdl/PandaPickAndPlace-v0")
    # A joint-space action drops the recipe's axes; tasks without a recipe get none.
    assert r.parameters({"actuation": "joint_position"}) == {
        "actuation": "joint_position",
        "reward_type": "shaped",
    }
    assert r.parameters({"time_limit": 5.0}) == {**r.task_kwargs, "time_limit": 5.0}
    assert DEFAULT_RECIPE.task_kwargs == {}
    batch = make_batch("mjkdl/PandaPickAndPlace-v0", 1, device="cpu", **r.task_kwargs)
    env = gym.make("mjkdl/PandaPickAndPlace-v0", **r.task_kwargs)
    try:
        assert RslRlEnv(batch).num_actions == 4 == env.action_space.shape[0]
    finally:
        batch.close()
        env.close()


def test_the_pick_cube_cpu_recipe_runs_a_few_updates() -> None:
    """The object tasks' CPU recipe (`OBJECT_CPU`): translation and the gripper, the shaped
    reward, on the batch and in the CPU env that evaluates it; its PPO settings reach rsl-rl."""
    for task in ("PickCube", "PickAndPlace"):
        assert recipe(f"mjkdl/Panda{task}-v0").on("cpu") == OBJECT_CPU
    # Push's ends its episodes on success; otherwise the same.
    assert recipe("mjkdl/PandaPush-v0").on("cpu") == PUSH_CPU
    assert PUSH_CPU.task_kwargs == {**OBJECT_CPU.task_kwargs, "terminate_on_success": True}
    assert dataclasses.replace(PUSH_CPU, task_kwargs=OBJECT_CPU.task_kwargs) == OBJECT_CPU
    cpu = recipe("mjkdl/PandaPickCube-v0").on("cpu")
    assert cpu.num_envs == 128 and cpu.num_steps_per_env == 24
    assert cpu.task_kwargs == {"cartesian_axes": "vx,vy,vz", "reward_type": "shaped"}
    result = train(
        "mjkdl/PandaPickCube-v0",
        device="cpu",
        num_envs=4,
        num_steps_per_env=4,
        iterations=2,
        time_limit=0.3,
    )
    assert result.env_steps == 32
    alg = result.runner.alg
    assert (alg.gamma, alg.lam) == (0.8, 0.9)
    policy = result.runner.get_inference_policy("cpu")
    action = policy(TensorDict({"policy": torch.zeros(3, 40)}, batch_size=[3]))
    assert action.shape == (3, 4)


def test_recipes_and_unbounded_episodes() -> None:
    pick = recipe("mjkdl/PandaPickCube-v0")
    assert pick.num_envs == 4096 == pick.worlds("cuda:0") and pick.on("cuda:0") is pick
    # No recipe runs a GPU's thousands of worlds on a CPU.
    assert pick.worlds("cpu") == 128
    reach = recipe("mjkdl/PandaReach-v0")
    assert reach.worlds("cpu") == 64 and reach.on("cpu").config == reach.config
    assert recipe("mjkdl/SomeNewTask-v0").iterations == DEFAULT_RECIPE.iterations
    from mjkdl.task import make_batch, registry

    spec = registry.panda_reach_spec()
    spec.time_limit = None
    batch = make_batch(spec, 1, device="cpu")
    try:
        with pytest.raises(SpecError, match="bounded episode"):
            RslRlEnv(batch)
    finally:
        batch.close()


def test_reset_workers_follow_the_cores_this_process_may_use(monkeypatch) -> None:
    """Pinned to 4 of a machine's 64 cores (taskset, a container's CPU set), a GPU batch
    gets 2 reset workers, not 15; the CPU engine none."""
    import os

    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0, 1, 2, 3})
    monkeypatch.setattr(os, "cpu_count", lambda: 64)
    assert auto_reset_workers("cuda:0") == 2
    assert auto_reset_workers("cpu") == 0
