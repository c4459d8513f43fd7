"""robomimic 0.3.0 on mjkdl's files: `create_env_from_metadata` builds the task, robomimic's own
`train.py` (BC, its default config: rollouts and `next_obs` on) trains on a low-dim and on an
image dataset and rolls out in mjkdl, and its `playback_dataset.py` and
`dataset_states_to_obs.py` run on the files. robomimic needs torch and torchvision, so CI runs
these in an environment of robomimic's own (`.ci/run`); elsewhere they skip."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest
from conftest import EXTRAS, ROOT, menagerie
from test_demos_hdf5 import PICK

from mjkdl.demos import DemoFile, collect

REQUIRE_ROBOMIMIC = os.environ.get("MJKDL_REQUIRE_ROBOMIMIC") == "1"


def robomimic_imports() -> bool:
    try:
        import robomimic.utils.env_utils  # noqa: F401
    except Exception:  # absent, or without torch/torchvision
        return False
    return True


if REQUIRE_ROBOMIMIC or robomimic_imports():
    import mjkdl.demos.robomimic  # noqa: F401  (torch's Triton before any EGL context)

pytestmark = pytest.mark.skipif(
    not REQUIRE_ROBOMIMIC and not robomimic_imports(),
    reason=EXTRAS["robomimic"].reason,
)
LOW_DIM = ["panda_tcp_pos", "panda_tcp_quat", "panda_gripper", "cube_rel"]
IMAGES = {"camera_names": ["wrist"], "camera_size": [48, 48]}


@pytest.fixture(autouse=True)
def _panda() -> None:
    menagerie("franka_emika_panda")


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Expert demos of PickCube: low-dim only, and with an 48×48 wrist camera."""
    menagerie("franka_emika_panda")
    folder = tmp_path_factory.mktemp("robomimic")
    out = {"low_dim": folder / "low_dim.hdf5", "image": folder / "image.hdf5"}
    collect(PICK, "expert", out["low_dim"], episodes=3, seed=0, progress=False)
    collect(PICK, "expert", out["image"], episodes=2, seed=0, env_kwargs=IMAGES, progress=False)
    return out


def robomimic(
    *args: str, cwd: Path, direct: bool = False, rc: int = 0, menagerie_root: Path | None = None
) -> subprocess.CompletedProcess:
    """robomimic's own script in a fresh process: `python -m mjkdl.demos.robomimic SCRIPT
    ...`, or with `direct` `python robomimic/scripts/SCRIPT.py ...` as robomimic documents it
    (after `python -m mjkdl.demos.robomimic install`, the one step its docs add)."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    if menagerie_root is not None:
        env["MENAGERIE_ROOT"] = str(menagerie_root)
    if direct:
        import robomimic as rm

        done = subprocess.run([sys.executable, "-m", "mjkdl.demos.robomimic", "install"],
                              capture_output=True, text=True, env=env)  # fmt: skip
        assert done.returncode == 0 and "macros_private.py: robomimic's scripts build" in (
            done.stdout
        ), done.stderr[-2000:]
        command = [sys.executable, str(Path(rm.__file__).parent / "scripts" / f"{args[0]}.py")]
        command += args[1:]
    else:
        command = [sys.executable, "-m", "mjkdl.demos.robomimic", *args]
    r = subprocess.run(command, capture_output=True, text=True, env=env, cwd=cwd, timeout=900)
    assert r.returncode == rc, (r.stdout + r.stderr)[-3000:]
    return r


def test_create_env_from_metadata_builds_the_task(files: dict[str, Path]) -> None:
    import robomimic.utils.env_utils as env_utils
    import robomimic.utils.file_utils as file_utils

    from mjkdl.demos.robomimic import EnvMjkdl, register

    register()
    meta = file_utils.get_env_metadata_from_dataset(str(files["low_dim"]))
    assert meta["type"] == 100 and meta["env_name"] == PICK
    env = env_utils.create_env_from_metadata(env_meta=meta, render_offscreen=True)
    assert isinstance(env, EnvMjkdl) and env.action_dimension == 7
    assert env.serialize() == {"env_name": PICK, "type": 100, "env_kwargs": {}}
    with DemoFile(files["low_dim"]) as f:
        demo = f.demo(1)
    env.reset()
    obs = env.reset_to({"states": demo.states[4]})
    for key in ("panda_joint_pos", "panda_tcp_pos", "cube_pose"):
        np.testing.assert_allclose(obs[key], demo.obs[key][4], rtol=0, atol=1e-12)
    assert env.get_reward() == demo.rewards[3]
    assert np.array_equal(env.get_state()["states"], demo.states[4])
    frame = env.render(mode="rgb_array", height=40, width=30, camera_name="front")
    assert frame.shape == (40, 30, 3) and frame.std() > 0
    last = env.reset_to({"states": demo.states[-1]})
    assert all(np.array_equal(last[k], demo.obs[k][-1]) for k in demo.obs)
    env.step(demo.actions[-1])  # the bonus of the step that ends it, as recorded (#37 item 6)
    assert env.get_reward() == demo.rewards[-1] > 1 and env.is_done()
    with pytest.raises(ValueError, match=r"states must have shape \(\d+,\)"):
        env.reset_to({"states": demo.states[4][:-1]})


def config(data: Path, out: Path, low_dim: list[str], rgb: list[str]) -> Path:
    """robomimic's default BC config, shortened: 2 epochs of 5 steps, 2 rollouts of 30 steps
    each epoch (its defaults otherwise: rollouts and videos on), `next_obs` loaded (robomimic's
    base default, which BC's config turns off)."""
    from robomimic.config import config_factory

    c = config_factory("bc")
    assert c.experiment.rollout.enabled and c.experiment.render_video
    with c.unlocked():
        c.train.hdf5_load_next_obs = True
        c.train.data = str(data)
        c.train.output_dir = str(out)
        c.train.num_epochs = 2
        c.train.batch_size = 8
        c.experiment.epoch_every_n_steps = 5
        c.experiment.rollout.n = 2
        c.experiment.rollout.horizon = 30
        c.experiment.rollout.rate = 1
        c.experiment.name = "bc"
        c.observation.modalities.obs.low_dim = low_dim
        c.observation.modalities.obs.rgb = rgb
    path = out.parent / f"{out.name}.json"
    path.write_text(json.dumps(c, indent=2))
    return path


@pytest.mark.parametrize(
    ("kind", "low_dim", "rgb", "direct"),
    [
        ("low_dim", LOW_DIM, [], True),  # robomimic's own command line
        ("image", ["panda_tcp_pos", "panda_gripper"], ["wrist_rgb"], False),
    ],
)
def test_robomimics_train_py_trains_bc_and_rolls_out_in_mjkdl(
    files: dict[str, Path],
    tmp_path: Path,
    kind: str,
    low_dim: list[str],
    rgb: list[str],
    direct: bool,
) -> None:
    cfg = config(files[kind], tmp_path / f"bc_{kind}", low_dim, rgb)
    r = robomimic("train", "--config", str(cfg), cwd=tmp_path, direct=direct)
    log = r.stdout + r.stderr
    assert "Created environment with name mjkdl/PandaPickCube-v0" in log
    assert "finished run successfully!" in log, log[-3000:]  # train.py exits 0 either way
    for epoch in (1, 2):  # 2 rollouts in mjkdl after each epoch, filmed
        assert f"Epoch {epoch} Rollouts took" in log
    assert log.count("Env: mjkdl_PandaPickCube-v0") == 2 and log.count('"Success_Rate": ') == 2
    (run,) = (tmp_path / f"bc_{kind}" / "bc").iterdir()
    videos = sorted(v.name for v in (run / "videos").glob("*.mp4") if v.stat().st_size > 0)
    assert videos[0] == "mjkdl_PandaPickCube-v0_epoch_1.mp4"  # robomimic keeps the best ones
    assert list((run / "models").glob("model_epoch_*.pth"))


def test_a_failed_training_run_exits_non_zero(files: dict[str, Path], tmp_path: Path) -> None:
    """robomimic's train.py catches the error, prints it and exits 0; ours exits 1."""
    cfg = config(files["low_dim"], tmp_path / "bad", ["no_such_key"], [])
    r = robomimic("train", "--config", str(cfg), cwd=tmp_path, rc=1)
    assert "run failed with error" in r.stdout
    assert "error: robomimic's train.py reported a failed run (above)" in r.stderr


def test_playback_dataset_replays_our_files_on_their_stored_model(
    files: dict[str, Path], tmp_path: Path
) -> None:
    """robomimic's own script, run directly, with no Menagerie: the file's model (#37 items 2
    and 3)."""
    video = tmp_path / "playback.mp4"
    (tmp_path / "empty").mkdir()
    r = robomimic("playback_dataset", "--dataset", str(files["low_dim"]), "--use-actions",
                  "--video_path", str(video), "--render_image_names", "front",
                  cwd=tmp_path, direct=True, menagerie_root=tmp_path / "empty")  # fmt: skip
    assert "StoredModelWarning: MuJoCo Menagerie model 'franka_emika_panda' is not" in r.stderr
    assert f"runs on the model {files['low_dim']} stores instead" in r.stderr
    assert r.stdout.count("Playing back episode: demo_") == 3
    assert "playback diverged" not in r.stdout  # robomimic's own state check, every step
    assert video.stat().st_size > 0


def test_dataset_states_to_obs_regenerates_observations(
    files: dict[str, Path], tmp_path: Path
) -> None:
    copy = tmp_path / "in.hdf5"
    copy.write_bytes(files["low_dim"].read_bytes())
    robomimic("dataset_states_to_obs", "--dataset", str(copy), "--output_name", "obs.hdf5",
              "--camera_names", "front", "--camera_height", "32", "--camera_width", "40",
              "--done_mode", "2", cwd=tmp_path, direct=True)  # fmt: skip
    with h5py.File(tmp_path / "obs.hdf5", "r") as out, DemoFile(copy) as f:
        assert sorted(out["data"]) == f.names
        for demo in f:
            g = out["data"][demo.name]
            assert g["obs/front_rgb"].shape == (demo.num_samples, 32, 40, 3)
            assert np.array_equal(g["actions"][()], demo.actions)
            # every row, the last next_obs (the last action stepped from a set state) too: a
            # recorded state is the whole state (#37 item 1)
            for key, rows in demo.obs.items():
                assert np.array_equal(g[f"obs/{key}"][()], rows), key
                recorded = np.concatenate([rows[1:], demo.final_obs[key][None]])
                assert np.array_equal(g[f"next_obs/{key}"][()], recorded), key
            assert np.array_equal(g["rewards"][()], demo.rewards)
            assert "seed" not in g.attrs  # robomimic's copy drops it: mjkdl's convert keeps it


@pytest.fixture(scope="module")
def checkpoint(files: dict[str, Path], tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A BC checkpoint of 2 short epochs on the low-dim demos, without rollouts."""
    folder = tmp_path_factory.mktemp("ckpt")
    cfg = config(files["low_dim"], folder / "bc_low_dim", LOW_DIM, [])
    c = json.loads(cfg.read_text())
    c["experiment"]["rollout"]["enabled"] = False
    c["experiment"]["save"]["every_n_epochs"] = 2
    cfg.write_text(json.dumps(c))
    robomimic("train", "--config", str(cfg), cwd=folder)
    (ckpt,) = (folder / "bc_low_dim" / "bc").glob("*/models/model_epoch_2.pth")
    return ckpt


def test_a_robomimic_checkpoint_acts_as_robomimics_rollout_policy(checkpoint: Path) -> None:
    """`robomimic:CKPT` is robomimic's own RolloutPolicy on the keys it was trained on."""
    import gymnasium as gym
    import robomimic.utils.file_utils as file_utils
    import torch

    from mjkdl.demos import RobomimicPolicy, make_policy

    env = gym.make(PICK)
    policy = make_policy(f"robomimic:{checkpoint}", env)
    assert isinstance(policy, RobomimicPolicy)
    theirs, _ = file_utils.policy_from_checkpoint(
        ckpt_path=str(checkpoint), device=torch.device("cpu")
    )
    obs, _ = env.reset(seed=3)
    policy.reset()
    theirs.start_episode()
    for _ in range(5):
        action = policy(obs)
        expected = theirs(ob={k: obs[k] for k in LOW_DIM})
        assert action.dtype == np.float32 and action.shape == (7,)
        np.testing.assert_allclose(action, expected, rtol=0, atol=1e-6)
        obs = env.step(action)[0]
    env.close()


def test_evaluate_runs_a_robomimic_checkpoint(checkpoint: Path, tmp_path: Path) -> None:
    """The command line, as with any policy source: per-episode lines and the summary."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    command = [sys.executable, "-m", "mjkdl.demos", "evaluate", PICK, "--policy",
               f"robomimic:{checkpoint}", "--episodes", "2", "--seed", "7"]  # fmt: skip
    r = subprocess.run(command, capture_output=True, text=True, env=env, cwd=tmp_path, timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    assert "seed 7" in r.stdout and "seed 8" in r.stdout, r.stdout
    assert "(95 % CI" in r.stdout and "/2)" in r.stdout, r.stdout


def test_bad_robomimic_sources_are_named(checkpoint: Path, files: dict[str, Path]) -> None:
    import gymnasium as gym

    from mjkdl.demos import PolicyError, make_policy

    env = gym.make(PICK)
    with pytest.raises(PolicyError, match=r"robomimic:/no/such\.pth: no such checkpoint; give a"):
        make_policy("robomimic:/no/such.pth", env)
    with pytest.raises(PolicyError, match=r"robomimic:.*low_dim\.hdf5: not a robomimic checkpoint"):
        make_policy(f"robomimic:{files['low_dim']}", env)
    env.close()
    reach = gym.make("mjkdl/PandaReach-v0")
    with pytest.raises(PolicyError, match=r"looks at cube_rel, which this env does not observe"):
        make_policy(f"robomimic:{checkpoint}", reach)
    reach.close()
