"""Demonstrations in robomimic's HDF5 layout: one writer that never loses a finished demo,
one reader that checks the file is one.

Layout (what robomimic, robosuite, MimicGen and LIBERO read)::

    data.attrs: env_args (JSON: env_name, type, env_kwargs, mjkdl_version, mujoco_version), total
    data/demo_<i>/actions (T×A), rewards (T), dones (T), states (T×S), obs/<key> (T×...)
    data/demo_<i>/next_obs/<key>: obs/<key> one step on (camera frames: a virtual dataset
        over rows 1.. of obs/<key> and final_obs/<key>, the frame after the last action)
    data/demo_<i>.attrs: num_samples, seed, model_file (MJCF), model_hash, success
    mask/train, mask/valid: demo names, 90/10
    models/<model_hash>: the compiled model as MJB bytes (zlib), one per distinct model

`states[t]` is MuJoCo's `mjSTATE_INTEGRATION` state *before* `actions[t]`, `obs/<key>[t]` the
observation the policy saw then.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import shutil
import warnings
import weakref
import zlib
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import h5py
import mujoco
import numpy as np

try:
    import resource  # Unix: the process's file-size limit
except ImportError:  # pragma: no cover (Windows)
    resource = None  # type: ignore[assignment]

from .. import __version__ as mjkdl_version
from ..closable import Closable
from ..compile import build_mjspec
from ..errors import MjkdlError, SpecError, unknown_name
from ..scene import Scene, mujoco_version
from ..validate import real

STATE = mujoco.mjtState.mjSTATE_INTEGRATION
ENV_TYPE = 100
"""robomimic's `EnvType` of mjkdl files (robomimic's own are 1-3); `mjkdl.demos.robomimic`
makes robomimic's `env_utils` build an mjkdl env for it."""
VALID_FRACTION = 0.1
"""Share of the demos `merge`, `filter` and `convert` put in `mask/valid` by default."""
_IMAGE_COMPRESSION = {"compression": "gzip", "compression_opts": 4}


class DemoFileError(MjkdlError, ValueError):
    """A file that is not a readable demonstration file (foreign, truncated, incomplete)."""


class StoredModelWarning(MjkdlError, UserWarning):
    """An env was built on the compiled model a file stores: its asset files are missing."""


class DemoWriteError(MjkdlError, OSError):
    """A demo could not be written (disk full, file not writable); finished demos stay."""


@dataclass
class EpisodeData:
    """One recorded episode: `states[t]` and `obs[key][t]` are before `actions[t]`."""

    seed: int
    actions: np.ndarray
    rewards: np.ndarray
    dones: np.ndarray
    states: np.ndarray
    obs: dict[str, np.ndarray]
    success: bool
    model_file: str = ""
    model_hash: str = ""
    final_obs: dict[str, np.ndarray] = field(default_factory=dict)
    model_mjb: bytes = field(default=b"", repr=False)
    randomization: str = ""
    """The episode's domain-randomisation draw (`Draw.to_dict()` as JSON); "": none."""

    @property
    def num_samples(self) -> int:
        """Steps in the episode (rows of `actions`)."""
        return len(self.actions)


@dataclass
class EpisodeBuffer:
    """Collects one episode of `scene` step by step, in memory, until written or dropped."""

    scene: Scene
    states: list[np.ndarray] = field(default_factory=list)
    actions: list[np.ndarray] = field(default_factory=list)
    rewards: list[float] = field(default_factory=list)
    dones: list[bool] = field(default_factory=list)
    obs: dict[str, list[np.ndarray]] = field(default_factory=dict)
    final_obs: dict[str, np.ndarray] = field(default_factory=dict)

    def before_step(self, obs: Mapping[str, np.ndarray]) -> None:
        """Keep the state and observation the next action starts from."""
        model, data = self.scene.model, self.scene.data
        state = np.empty(mujoco.mj_stateSize(model, STATE))
        mujoco.mj_getState(model, data, state, STATE)
        self.states.append(state)
        for key, value in obs.items():
            self.obs.setdefault(key, []).append(value)

    def after_step(
        self, action: np.ndarray, reward: float, done: bool, obs: Mapping[str, np.ndarray]
    ) -> None:
        """Keep what the step did (`action` is copied) and the observation it led to."""
        self.actions.append(np.array(action, copy=True))
        self.rewards.append(float(reward))
        self.dones.append(bool(done))
        self.final_obs = dict(obs)

    def finish(self, seed: int, success: bool, randomization: str = "") -> EpisodeData:
        """The episode as arrays, with the scene's model for `model_file`/`model_hash` (the
        nominal one: `randomization` is the episode's draw on it, as JSON)."""
        n = len(self.actions)
        xml, fingerprint, mjb = scene_model(self.scene)
        return EpisodeData(
            seed=seed,
            actions=np.stack(self.actions),
            rewards=np.asarray(self.rewards, dtype=np.float64),
            dones=np.asarray(self.dones, dtype=np.int64),
            states=np.stack(self.states[:n]),
            obs={k: np.stack(v[:n]) for k, v in self.obs.items()},
            success=success,
            model_file=xml,
            model_hash=fingerprint,
            final_obs=dict(self.final_obs),
            model_mjb=mjb,
            randomization=randomization,
        )


def scene_model(scene: Scene) -> tuple[str, str, bytes]:
    """The scene's compiled MJCF (robomimic's `model_file`), `model_hash` and MJB bytes, from
    its spec compiled afresh: a Robot rewrites actuator parameters of the live model for its
    control mode, which must not change the fingerprint. Cached per scene."""
    known = _SCENE_MODELS.get(scene)
    if known is None:
        with warnings.catch_warnings():  # MuJoCo's attach notes, already shown at build time
            warnings.simplefilter("ignore")
            spec = build_mjspec(scene.spec)
            model = spec.compile()
            known = (str(spec.to_xml()), model_hash(model), model_binary(model))
        _SCENE_MODELS[scene] = known
    return known


_SCENE_MODELS: weakref.WeakKeyDictionary[Scene, tuple[str, str, bytes]] = (
    weakref.WeakKeyDictionary()
)


def adopt_scene_model(scene: Scene, model: tuple[str, str, bytes]) -> None:
    """Let `scene_model(scene)` answer `model` (MJCF, `model_hash`, MJB): a scene built on a
    file's stored model, whose spec cannot be compiled here."""
    _SCENE_MODELS[scene] = model


def model_binary(model: mujoco.MjModel) -> bytes:
    """`model` as MuJoCo's MJB bytes: meshes and textures included, so it loads on a machine
    without the asset files (by the same MuJoCo version)."""
    buffer = np.empty(mujoco.mj_sizeModel(model), dtype=np.uint8)
    mujoco.mj_saveModel(model, None, buffer)
    return buffer.tobytes()


def model_hash(model: mujoco.MjModel) -> str:
    """SHA-256 of a compiled model's numbers (names and file paths left out, so the same
    model found under another directory hashes the same)."""
    h = hashlib.sha256()
    for name in sorted(dir(model)):
        if name.startswith("_") or "name" in name or "path" in name:
            continue
        value = getattr(model, name)
        if isinstance(value, np.ndarray) and value.dtype.kind in "biuf":
            h.update(name.encode())
            h.update(np.ascontiguousarray(value).tobytes())
    for name in sorted(n for n in dir(model.opt) if not n.startswith("_")):
        value = getattr(model.opt, name)
        if isinstance(value, (int, float, np.ndarray)):
            h.update(name.encode())
            h.update(np.asarray(value, dtype=np.float64).tobytes())
    return h.hexdigest()


def env_args(env_name: str, env_kwargs: Mapping[str, Any]) -> dict[str, Any]:
    """robomimic's `env_args` record, with the versions that made the file."""
    return {
        "env_name": env_name,
        "type": ENV_TYPE,
        "env_kwargs": dict(env_kwargs),
        "env_version": mjkdl_version,  # robomimic compares it with EnvMjkdl.version
        "mjkdl_version": mjkdl_version,
        "mujoco_version": mujoco_version(),
    }


class EpisodeWriter(Closable):
    """Appends finished episodes to an HDF5 file as `data/demo_<i>`, flushing after each.

    A crash or SIGKILL loses at most the episode being written: every `write` ends with the
    file complete on disk. An existing file is refused unless `append=True` (continue it: the
    same env and kwargs) or `overwrite=True` (replace it).
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        env_name: str,
        env_kwargs: Mapping[str, Any] | None = None,
        *,
        append: bool = False,
        overwrite: bool = False,
    ) -> None:
        self._path = Path(path)
        args = env_args(env_name, env_kwargs or {})
        try:
            json.dumps(args)
        except TypeError as err:
            raise DemoFileError(f"env_kwargs must be JSON-serialisable: {err}") from None
        self._file: h5py.File | None = None
        if self._path.exists() and not (append or overwrite):
            raise DemoFileError(
                f"{self._path} exists: pass --append to add demos to it or --overwrite to "
                "replace it"
            )
        if append and self._path.exists():
            DemoFile(self._path).close()  # a foreign or broken file is refused here
            f = self._open(self._path, "a")
            old = json.loads(f["data"].attrs["env_args"])
            if (old["env_name"], old["env_kwargs"]) != (args["env_name"], args["env_kwargs"]):
                f.close()
                raise DemoFileError(
                    f"{self._path} holds demos of {old['env_name']} with {old['env_kwargs']}; "
                    f"cannot append {env_name} with {args['env_kwargs']}"
                )
            self._file = f
        else:
            f = self._open(self._path, "w")
            data = f.create_group("data")
            data.attrs["env_args"] = json.dumps(args)
            data.attrs["total"] = 0
            f.create_group("mask")
            f.flush()
            self._file = f
        data = self._file["data"]
        self._demos = sorted(_finished(data), key=_demo_index)
        self._next = 1 + max((_demo_index(n) for n in data), default=-1)
        self._seeds = {int(data[n].attrs["seed"]): n for n in self._demos}
        self._packed: dict[str, bytes] = {}

    @staticmethod
    def _open(path: Path, mode: str) -> h5py.File:
        try:
            return h5py.File(path, mode)
        except OSError as err:
            raise DemoWriteError(f"cannot open {path} for writing: {err}") from None

    @property
    def path(self) -> Path:
        """The HDF5 file."""
        return self._path

    @property
    def num_demos(self) -> int:
        """Finished demos in the file."""
        return len(self._demos)

    @property
    def seeds(self) -> list[int]:
        """The seeds of the finished demos, in the file's order."""
        return list(self._seeds)

    @property
    def next_seed(self) -> int:
        """The seed after the file's last one (0 for an empty file)."""
        return 1 + max(self._seeds, default=-1)

    @property
    def closed(self) -> bool:
        return self._file is None

    def write(self, episode: EpisodeData) -> str:
        """Add `episode` as the next `demo_<i>`, flush the file; the demo's name. A seed the
        file already holds is refused: the same seed twice is the same demo twice."""
        self._check_open()
        f = self._file
        assert f is not None
        if episode.num_samples == 0:
            raise DemoFileError("an episode of 0 steps has nothing to record")
        if episode.seed in self._seeds:
            raise DemoFileError(
                f"{self._path} already holds seed {episode.seed} ({self._seeds[episode.seed]}); "
                "continue after its last seed (collect --append without --seed) or pick unused "
                "seeds"
            )
        name = f"demo_{self._next}"
        self._check_room(name, episode)
        try:
            self.add_model(episode)
            self._write_group(f["data"], name, episode)
            self._demos.append(name)
            f["data"].attrs["total"] = int(f["data"].attrs["total"]) + episode.num_samples
            _add_to_mask(f, name)
            f.flush()
            self._seeds[episode.seed] = name
        except (OSError, RuntimeError) as err:
            self._demos = [d for d in self._demos if d != name]
            kept = len(self._demos)
            try:
                if name in f["data"]:
                    del f["data"][name]
                f.flush()
            except (OSError, RuntimeError, KeyError):
                pass
            why = " ".join(str(err).split())  # HDF5's message spans lines
            raise DemoWriteError(
                f"could not write {name} to {self._path} ({why}); the file keeps its {kept} "
                "finished demos"
            ) from None
        self._next += 1
        return name

    def split(self, valid_fraction: float = VALID_FRACTION) -> None:
        """Rebuild `mask/train` and `mask/valid` over the finished demos: `valid_fraction` of
        them, evenly spread (`valid_positions`), validate and the rest train. Both masks
        always exist (robomimic's training reads both)."""
        self._check_open()
        f = self._file
        assert f is not None
        valid = valid_positions(len(self._demos), valid_fraction)
        for key, names in (
            ("train", [d for i, d in enumerate(self._demos) if i not in valid]),
            ("valid", [d for i, d in enumerate(self._demos) if i in valid]),
        ):
            if key in f["mask"]:
                del f["mask"][key]
            f["mask"].create_dataset(
                key,
                data=np.array([n.encode() for n in names], dtype=_MASK_NAME),
                maxshape=(None,),
                chunks=(256,),
            )
        f.flush()

    def _check_room(self, name: str, ep: EpisodeData) -> None:
        """Refuse a demo the disk (or the process's file-size limit) cannot hold, before HDF5
        writes any of it: HDF5 fails mid-write inconsistently, up to a crash at the next
        flush. The need is counted uncompressed (the model: as stored), erring towards
        refusing."""
        arrays = [ep.actions, ep.rewards, ep.dones, ep.states, *ep.obs.values()]
        need = sum(a.nbytes for a in arrays) + sum(
            v.nbytes for v in ep.obs.values() if not _is_frames(v)
        )  # next_obs copies the low-dim rows
        packed = self._packed_model(ep)
        need += len(packed or b"") + 64 * 1024  # the groups, attributes and masks
        room, why = self._room()
        if need > room:
            raise DemoWriteError(
                f"could not write {name} to {self._path} ({why}: it needs about {need} bytes, "
                f"{max(room, 0)} are left); the file keeps its {len(self._demos)} finished demos"
            )

    def _room(self) -> tuple[int, str]:
        """Bytes the file may still grow by, and what limits it."""
        size = self._path.stat().st_size
        room, why = shutil.disk_usage(self._path.parent).free, "No space left on device"
        limit = resource.getrlimit(resource.RLIMIT_FSIZE)[0] if resource else -1
        if limit != getattr(resource, "RLIM_INFINITY", -1) and limit - size < room:
            room, why = limit - size, "File too large"
        return room, why

    def _packed_model(self, ep: EpisodeData) -> bytes | None:
        """The episode's model as stored (zlib level 1: the Panda's 35.6 MB of MJB -> 15 MB
        in 1.3 s; its size must be known before writing), or None when nothing is to store."""
        f = self._file
        assert f is not None
        if not ep.model_mjb or not ep.model_hash or ep.model_hash in f.get("models", {}):
            return None
        packed = self._packed.get(ep.model_hash)
        if packed is None:
            packed = self._packed[ep.model_hash] = zlib.compress(ep.model_mjb, 1)
        return packed

    def add_model(self, episode: EpisodeData) -> None:
        """Store the episode's compiled model (`models/<model_hash>`) unless the file has it:
        `write` does this; call it for an episode that is not written so that the model of
        the ones that follow (which may come without `model_mjb`) is kept."""
        self._check_open()
        f = self._file
        assert f is not None
        packed = self._packed_model(episode)
        if packed is None:
            return
        room, why = self._room()
        if len(packed) + 4096 > room:
            raise DemoWriteError(
                f"could not store the model of {self._path}'s demos ({why}: it needs "
                f"{len(packed)} bytes, {max(room, 0)} are left)"
            )
        stored = f.require_group("models").create_dataset(
            episode.model_hash, data=np.frombuffer(packed, dtype=np.uint8)
        )
        stored.attrs["compression"] = "zlib"
        stored.attrs["mujoco_version"] = mujoco_version()
        self._packed.pop(episode.model_hash, None)

    @staticmethod
    def _write_group(data: h5py.Group, name: str, ep: EpisodeData) -> None:
        g = data.create_group(name)
        g.create_dataset("actions", data=ep.actions)
        g.create_dataset("rewards", data=ep.rewards)
        g.create_dataset("dones", data=ep.dones)
        g.create_dataset("states", data=ep.states)
        obs = g.create_group("obs")
        for key, value in ep.obs.items():
            _obs_dataset(obs, key, value)
        if ep.obs and ep.final_obs.keys() >= ep.obs.keys():
            nxt = g.create_group("next_obs")
            for key, rows in ep.obs.items():
                last = np.asarray(ep.final_obs[key])[None]
                if _is_frames(rows):  # a virtual dataset: no second copy of the frames
                    final = _obs_dataset(g.require_group("final_obs"), key, last)
                    _next_obs(nxt, key, obs[key], final)
                else:  # a copy: cheaper to write than a virtual dataset (0.1 ms against 1 ms)
                    nxt.create_dataset(key, data=np.concatenate([rows[1:], last]))
        g.attrs["seed"] = ep.seed
        g.attrs["model_file"] = ep.model_file
        g.attrs["model_hash"] = ep.model_hash
        g.attrs["success"] = bool(ep.success)
        if ep.randomization:
            g.attrs["randomization"] = ep.randomization
        g.attrs["num_samples"] = ep.num_samples  # last: a demo without it is unfinished

    def close(self) -> None:
        """Flush and close the file (again: nothing)."""
        if self._file is not None:
            try:
                self._file.close()
            finally:
                self._file = None


def valid_positions(n: int, fraction: float) -> set[int]:
    """Which of `n` demos validate: the last of every `1 / fraction` (at 0.1 the tenth, the
    twentieth, ..., as `collect`'s masks have it), and of two or more demos at least the last
    one when the fraction is positive."""
    fraction = real(fraction, "valid_fraction")
    if not 0.0 <= fraction < 1.0:
        raise SpecError(f"valid_fraction must be in [0, 1), got {fraction!r}")
    shares = [math.floor(i * fraction + 1e-9) for i in range(n + 1)]
    out = {i for i in range(n) if shares[i + 1] > shares[i]}
    if not out and fraction > 0 and n >= 2:
        out = {n - 1}
    return out


def _is_frames(value: np.ndarray) -> bool:
    return bool(value.dtype == np.uint8 and value.ndim >= 3)


def _obs_dataset(group: h5py.Group, key: str, value: np.ndarray) -> h5py.Dataset:
    if _is_frames(value):  # camera frames, one chunk each
        return group.create_dataset(
            key, data=value, chunks=(1, *value.shape[1:]), **_IMAGE_COMPRESSION
        )
    return group.create_dataset(key, data=value)


def _next_obs(nxt: h5py.Group, key: str, obs: h5py.Dataset, last: h5py.Dataset) -> None:
    """`next_obs/<key>` as a virtual dataset over `obs/<key>` rows 1.. and the final row."""
    n = obs.shape[0]
    layout = h5py.VirtualLayout(shape=obs.shape, dtype=obs.dtype)
    if n > 1:
        layout[: n - 1] = h5py.VirtualSource(obs)[1:]
    layout[n - 1 :] = h5py.VirtualSource(last)
    nxt.create_virtual_dataset(key, layout)


def _demo_index(name: str) -> int:
    try:
        return int(name.rsplit("_", 1)[1])
    except (IndexError, ValueError):
        return -1


def _finished(data: h5py.Group) -> list[str]:
    return [n for n in data if n.startswith("demo_") and "num_samples" in data[n].attrs]


def _add_to_mask(f: h5py.File, name: str) -> None:
    """Append `name` to `mask/valid` if its index ends in 9 (demo_9, demo_19, ...), else to
    `mask/train`: 90/10, stable on append, and O(1) per demo however long the file grows."""
    key = "valid" if _demo_index(name) % 10 == 9 else "train"
    mask = f["mask"]
    names = mask.get(key)
    if names is None or names.maxshape != (None,):  # new, or fixed-size (robomimic's tools)
        old = [] if names is None else [bytes(n) for n in names[()]]
        if names is not None:
            del mask[key]
        names = mask.create_dataset(
            key, data=np.array(old, dtype=_MASK_NAME), maxshape=(None,), chunks=(256,)
        )
    n = len(names)
    names.resize((n + 1,))
    names[n] = name.encode()


_MASK_NAME = h5py.string_dtype("ascii")  # variable length: robomimic decodes the bytes


@dataclass
class Demo(EpisodeData):
    """One demo read back (arrays in memory), with its name in the file."""

    name: str = ""


class DemoFile(Closable):
    """A demonstration file opened for reading; a foreign or broken file is refused by name."""

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self._path = Path(path)
        if not self._path.is_file():
            raise DemoFileError(f"{self._path}: no such demonstration file")
        try:
            self._file: h5py.File | None = h5py.File(self._path, "r")
        except OSError as err:
            if "unable to lock file" in str(err):
                raise DemoFileError(
                    f"{self._path} is open for writing in another process (a collection or "
                    "teleop session); read it when that ends"
                ) from None
            raise DemoFileError(
                f"{self._path} is not a readable HDF5 file (truncated or foreign?): {err}"
            ) from None
        try:
            self._args = self._read_args()
        except BaseException:
            self.close()
            raise
        data = self._file["data"]
        self._names = sorted(_finished(data), key=_demo_index)
        self._models: dict[str, bytes] = {}

    def _read_args(self) -> dict[str, Any]:
        f = self._file
        assert f is not None
        if "data" not in f or "env_args" not in f["data"].attrs:
            raise DemoFileError(
                f"{self._path} is not a demonstration file: it has no data.attrs['env_args']"
            )
        try:
            args = json.loads(f["data"].attrs["env_args"])
        except (TypeError, ValueError) as err:
            raise DemoFileError(
                f"{self._path}: data.attrs['env_args'] is not JSON: {err}"
            ) from None
        if not isinstance(args, dict) or not isinstance(args.get("env_name"), str):
            raise DemoFileError(f"{self._path}: data.attrs['env_args'] has no 'env_name'")
        args.setdefault("env_kwargs", {})
        return args

    @property
    def path(self) -> Path:
        """The HDF5 file."""
        return self._path

    @property
    def env_name(self) -> str:
        """The Gymnasium id the demos were recorded in."""
        return str(self._args["env_name"])

    @property
    def env_kwargs(self) -> dict[str, Any]:
        """The keyword arguments of `gymnasium.make` they were recorded with."""
        return dict(self._args["env_kwargs"])

    @property
    def env_args(self) -> dict[str, Any]:
        """The whole `env_args` record (versions included)."""
        return dict(self._args)

    @property
    def names(self) -> list[str]:
        """Finished demos, in order (`demo_0`, `demo_1`, ...)."""
        return list(self._names)

    def __len__(self) -> int:
        return len(self._names)

    def __iter__(self) -> Iterator[Demo]:
        for name in self._names:
            yield self.demo(name)

    @property
    def closed(self) -> bool:
        return self._file is None

    def demo(self, key: int | str) -> Demo:
        """Demo `demo_<key>` (an int) or by name."""
        self._check_open()
        assert self._file is not None
        name = f"demo_{key}" if isinstance(key, (int, np.integer)) else str(key)
        if name not in self._names:
            raise unknown_name("demo", name, self._names, str(self._path))
        g = self._file["data"][name]
        try:
            return Demo(
                name=name,
                seed=int(g.attrs["seed"]),
                actions=g["actions"][()],
                rewards=g["rewards"][()],
                dones=g["dones"][()],
                states=g["states"][()],
                obs={k: v[()] for k, v in g["obs"].items()} if "obs" in g else {},
                success=bool(g.attrs.get("success", False)),
                model_file=str(g.attrs.get("model_file", "")),
                model_hash=str(g.attrs.get("model_hash", "")),
                randomization=str(g.attrs.get("randomization", "")),
                final_obs={k: v[-1] for k, v in g["next_obs"].items()} if "next_obs" in g else {},
            )
        except (KeyError, OSError) as err:
            raise DemoFileError(f"{self._path}: {name} is incomplete or damaged: {err}") from None

    @property
    def seeds(self) -> list[int]:
        """Each finished demo's seed, in order."""
        self._check_open()
        assert self._file is not None
        data = self._file["data"]
        return [int(data[n].attrs["seed"]) for n in self._names]

    def model_bytes(self, key: int | str = 0) -> bytes:
        """The MJB bytes of demo `key`'s model (b"" when the file has none)."""
        return self._model_bytes(str(self._group(key).attrs.get("model_hash", "")))

    def _group(self, key: int | str) -> h5py.Group:
        self._check_open()
        assert self._file is not None
        name = f"demo_{key}" if isinstance(key, (int, np.integer)) else str(key)
        if name not in self._names:
            raise unknown_name("demo", name, self._names, str(self._path))
        return self._file["data"][name]

    def _model_bytes(self, fingerprint: str) -> bytes:
        assert self._file is not None
        models = self._file.get("models")
        if not fingerprint or models is None or fingerprint not in models:
            return b""
        known = self._models.get(fingerprint)
        if known is None:
            stored = models[fingerprint]
            known = stored[()].tobytes()
            if stored.attrs.get("compression") == "zlib":
                known = zlib.decompress(known)
            self._models[fingerprint] = known
        return known

    def stored_model(self, key: int | str = 0) -> tuple[str, str, bytes]:
        """Demo `key`'s `model_file` (MJCF), `model_hash` and MJB bytes (b"" without)."""
        attrs = self._group(key).attrs
        fingerprint = str(attrs.get("model_hash", ""))
        return str(attrs.get("model_file", "")), fingerprint, self._model_bytes(fingerprint)

    def model(self, key: int | str = 0) -> mujoco.MjModel:
        """The compiled model demo `key` was recorded with, from the MJB bytes the file
        stores: no asset files needed (the same MuJoCo version is)."""
        g = self._group(key)
        name = g.name.rsplit("/", 1)[1]
        fingerprint = str(g.attrs.get("model_hash", ""))
        raw = self._model_bytes(fingerprint)
        if not raw:
            raise DemoFileError(
                f"{self._path}: {name} has no stored model (models/{fingerprint or '?'}); files "
                "written before mjkdl stored models hold only model_file, which names asset files"
            )
        assert self._file is not None
        version = self._file["models"][fingerprint].attrs.get("mujoco_version", "")
        try:
            return mujoco.MjModel.from_binary_path("model.mjb", {"model.mjb": raw})
        except ValueError as err:
            raise DemoFileError(
                f"{self._path}: models/{fingerprint} (MJB of MuJoCo {version}) does not load in "
                f"MuJoCo {mujoco_version()}: {err}; rebuild the env by name instead"
            ) from None

    def close(self) -> None:
        """Close the file (again: nothing)."""
        if self._file is not None:
            self._file.close()
            self._file = None
