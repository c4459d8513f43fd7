"""convert, merge, filter: observations regenerated for other cameras by exact replay or from
the states, files merged and filtered with their seeds, models and masks rebuilt."""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np
import pytest
from conftest import menagerie
from test_demos_hdf5 import PICK, REACH, cli

from mjkdl.demos import DemoFile, DemoFileError, collect
from mjkdl.demos.convert import convert, filter_demos, merge, parse_seeds

WRIST = {"camera_names": ["wrist"], "camera_size": [32, 40]}


@pytest.fixture(autouse=True)
def _panda() -> None:
    menagerie("franka_emika_panda")


@pytest.fixture(scope="module")
def picks(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Two short PickCube demos without cameras."""
    menagerie("franka_emika_panda")
    out = tmp_path_factory.mktemp("convert") / "picks.hdf5"
    collect(PICK, "demo_envs:approach", out, episodes=2, seed=3, keep_failures=True,
            env_kwargs={"max_episode_steps": 8}, progress=False)  # fmt: skip
    return out


def test_convert_adds_a_camera_by_exact_replay(picks: Path, tmp_path: Path) -> None:
    out = tmp_path / "wrist.hdf5"
    r = cli("convert", str(picks), str(out), "--env-kwargs", '{"camera_names": ["wrist"], '
            '"camera_size": [32, 40], "camera_depth": true}')  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == f"{out}: 2 demos, observations by actions"
    with DemoFile(picks) as a, DemoFile(out) as b:
        assert b.env_kwargs == {"max_episode_steps": 8, **WRIST, "camera_depth": True}
        assert b.seeds == a.seeds == [3, 4]
        for da, db in zip(a, b, strict=True):
            assert db.obs["wrist_rgb"].shape == (8, 32, 40, 3) and db.obs["wrist_rgb"].std() > 0
            depth = db.obs["wrist_depth"]  # metres: the fingers a few cm away, the floor < 1 m
            assert depth.shape == (8, 32, 40) and depth.dtype == np.float32
            assert 0.01 < depth.min() < 0.1 and 0.3 < depth.max() < 1.0
            assert np.array_equal(da.states, db.states) and np.array_equal(da.actions, db.actions)
            for key, rows in da.obs.items():  # the old keys, as recorded
                assert np.array_equal(rows, db.obs[key]), key
            assert db.success == da.success and np.array_equal(db.rewards, da.rewards)
            assert b.model(db.name).ncam == a.model(da.name).ncam  # a model of its own, stored
    with h5py.File(out, "r") as f:  # the frames' next_obs: a view, not a second copy
        g = f["data/demo_1"]
        assert g["next_obs/wrist_rgb"].is_virtual and g["next_obs/wrist_rgb"].shape == (
            8,
            32,
            40,
            3,
        )
        assert np.array_equal(g["next_obs/wrist_rgb"][:7], g["obs/wrist_rgb"][1:])
        assert np.array_equal(g["next_obs/wrist_rgb"][7], g["final_obs/wrist_rgb"][0])


def test_convert_from_states(picks: Path, tmp_path: Path) -> None:
    """Every row as recorded, the last `next_obs` (the last action stepped from the set last
    state) too: a recorded state is the whole state (#37 item 1)."""
    out = convert(picks, tmp_path / "s.hdf5", WRIST, mode="states").path
    with DemoFile(picks) as a, DemoFile(out) as b:
        for da, db in zip(a, b, strict=True):
            for key, rows in da.obs.items():
                assert np.array_equal(db.obs[key], rows), key
                assert np.array_equal(db.final_obs[key], da.final_obs[key]), key
            assert db.obs["wrist_rgb"].shape == (8, 32, 40, 3)
    with h5py.File(picks, "r") as fa, h5py.File(out, "r") as fb:
        for name in fa["data"]:
            for key in fa[f"data/{name}/next_obs"]:
                recorded = fa[f"data/{name}/next_obs/{key}"][()]
                assert np.array_equal(fb[f"data/{name}/next_obs/{key}"][()], recorded), key


def test_frames_from_states_are_the_frames_of_replay(picks: Path, tmp_path: Path) -> None:
    """A camera observes the state it is recorded with (#30 item 1: needs TaskEnv to update
    the cameras' poses after each step)."""
    kwargs = {**WRIST, "camera_depth": True}  # depth too: the same render of the same state
    by_actions = convert(picks, tmp_path / "a.hdf5", kwargs).path
    by_states = convert(picks, tmp_path / "s.hdf5", kwargs, mode="states").path
    with DemoFile(by_actions) as a, DemoFile(by_states) as s:
        for da, ds in zip(a, s, strict=True):
            assert np.array_equal(da.obs["wrist_rgb"], ds.obs["wrist_rgb"])
            assert np.array_equal(da.obs["wrist_depth"], ds.obs["wrist_depth"])


def test_convert_refuses_what_it_cannot_do(picks: Path, tmp_path: Path) -> None:
    edited = tmp_path / "edited.hdf5"
    edited.write_bytes(picks.read_bytes())
    with h5py.File(edited, "r+") as f:
        f["data/demo_1/actions"][3, 0] += 0.05
    with pytest.raises(
        DemoFileError,
        match=r"edited\.hdf5:demo_1 does not replay in "
        r"mjkdl/PandaPickCube-v0 .* at step 4\): convert it with --mode states",
    ):
        convert(edited, tmp_path / "x.hdf5", WRIST)  # fmt: skip
    with pytest.raises(DemoFileError, match=r"picks\.hdf5 is an input too"):
        convert(picks, picks, WRIST, overwrite=True)
    with pytest.raises(ValueError, match="--mode must be one of actions, states, got 'obs'"):
        convert(picks, tmp_path / "y.hdf5", mode="obs")
    r = cli("convert", str(picks), str(tmp_path / "z.hdf5"), "--env-kwargs", '{"camera_names": 3}')
    assert r.returncode == 2 and "error: camera_names" in r.stderr


def test_merge_and_filter(tmp_path: Path) -> None:
    kw = {"max_episode_steps": 3}
    a = collect(REACH, "random", tmp_path / "a.hdf5", episodes=3, seed=0, env_kwargs=kw,
                keep_failures=True, progress=False).path  # fmt: skip
    b = collect(REACH, "random", tmp_path / "b.hdf5", episodes=8, seed=3, env_kwargs=kw,
                keep_failures=True, progress=False).path  # fmt: skip
    assert merge([a, b], tmp_path / "ab.hdf5").demos == 11
    with DemoFile(tmp_path / "ab.hdf5") as f, DemoFile(b) as fb:
        assert f.seeds == list(range(11)) and f.names == [f"demo_{i}" for i in range(11)]
        assert np.array_equal(f.demo(5).actions, fb.demo(2).actions)
        assert f.model(10).nq == fb.model(0).nq
    with h5py.File(tmp_path / "ab.hdf5", "r") as f:  # masks of the new numbering
        assert [n.decode() for n in f["mask/valid"][()]] == ["demo_9"]
        assert len(f["mask/train"]) == 10 and len(f["models"]) == 1
    r = cli("merge", str(a), str(a), "--out", str(tmp_path / "aa.hdf5"))
    assert r.returncode == 2 and r"already holds seed 0 (demo_0)" in r.stderr
    other = collect(REACH, "random", tmp_path / "o.hdf5", episodes=1, seed=50,
                    env_kwargs={"max_episode_steps": 2}, keep_failures=True,
                    progress=False).path  # fmt: skip
    with pytest.raises(
        DemoFileError,
        match=r"o\.hdf5 holds demos of mjkdl/PandaReach-v0 with "
        r"\{'max_episode_steps': 2\}.*merge files of one env",
    ):
        merge([a, other], tmp_path / "ao.hdf5")  # fmt: skip

    r = cli("filter", str(tmp_path / "ab.hdf5"), str(tmp_path / "f.hdf5"), "--seeds", "1,4-6,9")
    assert r.returncode == 0 and r.stdout.strip() == f"{tmp_path / 'f.hdf5'}: 5 demos kept"
    with DemoFile(tmp_path / "f.hdf5") as f:
        assert f.seeds == [1, 4, 5, 6, 9] and f.names == [f"demo_{i}" for i in range(5)]
    assert filter_demos(a, tmp_path / "s.hdf5", success=True).demos == 0  # random: none succeed
    assert filter_demos(a, tmp_path / "l.hdf5", min_length=4).demos == 0
    assert filter_demos(a, tmp_path / "m.hdf5", success=False, max_length=3).demos == 3
    assert parse_seeds("2, 7-9") == [2, 7, 8, 9]
    with pytest.raises(ValueError, match="--seeds takes integers and ranges like 1,4,10-19"):
        parse_seeds("1,x")
    with pytest.raises(ValueError, match="--seeds range 9-7 runs backwards"):
        parse_seeds("9-7")


def masks(path: Path) -> dict[str, list[str]]:
    with h5py.File(path, "r") as f:
        return {k: [n.decode() for n in f["mask"][k][()]] for k in ("train", "valid")}


def test_merge_and_filter_are_atomic_and_keep_the_masks(tmp_path: Path) -> None:
    """#37 item 4: a refused merge leaves nothing behind (an existing output stays as it was);
    a filtered file of under ten demos still has `mask/valid`; `--valid-fraction`."""
    kw = {"max_episode_steps": 2}
    a = collect(REACH, "random", tmp_path / "a.hdf5", episodes=5, seed=0, env_kwargs=kw,
                keep_failures=True, progress=False).path  # fmt: skip
    out = tmp_path / "aa.hdf5"
    r = cli("merge", str(a), str(a), "--out", str(out))
    assert r.returncode == 2 and "already holds seed 0 (demo_0)" in r.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.hdf5"]  # no partial file
    out.write_bytes(b"kept")
    with pytest.raises(DemoFileError, match=r"already holds seed 0"):
        merge([a, a], out, overwrite=True)
    assert out.read_bytes() == b"kept"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.hdf5", "aa.hdf5"]
    with pytest.raises(DemoFileError, match=r"aa\.hdf5 exists: pass --overwrite to replace it"):
        filter_demos(a, out)

    r = cli("filter", str(a), str(tmp_path / "f.hdf5"), "--seeds", "0-2")
    assert r.returncode == 0, r.stderr
    assert masks(tmp_path / "f.hdf5") == {"train": ["demo_0", "demo_1"], "valid": ["demo_2"]}
    r = cli("merge", str(a), "--out", str(tmp_path / "m.hdf5"), "--valid-fraction", "0.4")
    assert r.returncode == 0, r.stderr
    assert masks(tmp_path / "m.hdf5") == {
        "train": ["demo_0", "demo_1", "demo_3"],
        "valid": ["demo_2", "demo_4"],
    }
    filter_demos(a, tmp_path / "z.hdf5", valid_fraction=0.0)
    assert masks(tmp_path / "z.hdf5")["valid"] == []
    with pytest.raises(ValueError, match=r"valid_fraction must be in \[0, 1\), got 1\.0"):
        filter_demos(a, tmp_path / "one.hdf5", valid_fraction=1.0)
    assert not (tmp_path / "one.hdf5").exists()
