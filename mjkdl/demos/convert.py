"""New files from recorded ones: observations regenerated for other env keywords (cameras,
sizes, observation keys), files merged, demos filtered. Each writes through `EpisodeWriter`,
so the output is a complete file of its own: masks rebuilt (`valid_fraction` of the demos in
`mask/valid`), the model stored, seeds unique. The output appears whole or not at all: it is
written beside `out` under a hidden name and renamed when complete."""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import gymnasium as gym
import mujoco
import numpy as np

from ..errors import SpecError
from .episodes import file_env, restore, scene_of
from .hdf5 import (
    STATE,
    VALID_FRACTION,
    Demo,
    DemoFile,
    DemoFileError,
    EpisodeWriter,
    scene_model,
    valid_positions,
)

CONVERT_MODES = ("actions", "states")


@dataclass(frozen=True)
class Written:
    """What a convert, merge or filter wrote: the file and its demo count."""

    path: Path
    demos: int


def convert(
    src: str | os.PathLike[str],
    out: str | os.PathLike[str],
    env_kwargs: Mapping[str, Any] | None = None,
    *,
    mode: str = "actions",
    overwrite: bool = False,
    valid_fraction: float = VALID_FRACTION,
) -> Written:
    """Write `src`'s demos to `out` with observations of an env built with the recorded
    keywords updated by `env_kwargs` (e.g. `{"camera_names": ["wrist"], "camera_size": [84,
    84]}`), one env for all demos.

    `mode="actions"` replays each demo's actions from its seed (the new observations then are
    exactly what a policy sees in the new env) and refuses a demo whose states do not come back
    bit for bit; `"states"` sets each recorded state and observes it (for a file whose actions
    do not replay here, e.g. recorded by another MuJoCo version), the final observation after
    the last action from one step of it."""
    if mode not in CONVERT_MODES:
        raise SpecError(f"--mode must be one of {', '.join(CONVERT_MODES)}, got {mode!r}")
    with DemoFile(src) as f:
        _not_an_input(out, [f.path])
        kwargs = {**f.env_kwargs, **dict(env_kwargs or {})}
        env = file_env(f, kwargs)
        try:
            run = _by_actions if mode == "actions" else _by_states
            demos = (run(env, d, f.path) for d in f)
            return _write(out, f.env_name, kwargs, demos, overwrite, valid_fraction)
        finally:
            env.close()


def _by_actions(env: gym.Env, demo: Demo, path: Path) -> Demo:
    obs, _ = env.reset(seed=demo.seed)
    scene = scene_of(env)
    state = np.empty(demo.states.shape[1])
    rows: dict[str, list[np.ndarray]] = {k: [] for k in obs}
    for t, action in enumerate(demo.actions):
        mujoco.mj_getState(scene.model, scene.data, state, STATE)
        if state.shape != demo.states[t].shape or not np.array_equal(state, demo.states[t]):
            raise DemoFileError(
                f"{path}:{demo.name} does not replay in {demo_env(env)} with these keywords (its "
                f"state differs at step {t}): convert it with --mode states"
            )
        for k, v in obs.items():
            rows[k].append(v)
        obs, *_ = env.step(action)
    return _with_obs(env, demo, rows, obs)


def _by_states(env: gym.Env, demo: Demo, path: Path) -> Demo:
    obs, _ = env.reset(seed=demo.seed)
    model = scene_of(env).model
    if demo.states.shape[1] != mujoco.mj_stateSize(model, STATE):
        raise DemoFileError(
            f"{path}:{demo.name} has states of size {demo.states.shape[1]}; "
            f"{demo_env(env)} has {mujoco.mj_stateSize(model, STATE)}: another model"
        )
    rows: dict[str, list[np.ndarray]] = {k: [] for k in obs}
    for state in demo.states:
        for k, v in restore(env, state, demo.randomization)[0].items():
            rows[k].append(v)
    final, *_ = env.step(demo.actions[-1])
    return _with_obs(env, demo, rows, final)


def demo_env(env: gym.Env) -> str:
    """The env's Gymnasium id (its class name without one)."""
    spec = env.unwrapped.spec
    return spec.id if spec is not None else type(env.unwrapped).__name__


def _with_obs(
    env: gym.Env, demo: Demo, rows: dict[str, list[np.ndarray]], final: Mapping[str, np.ndarray]
) -> Demo:
    xml, fingerprint, mjb = scene_model(scene_of(env))
    return replace(
        demo,
        obs={k: np.stack(v) for k, v in rows.items()},
        final_obs=dict(final),
        model_file=xml,
        model_hash=fingerprint,
        model_mjb=mjb,
    )


def merge(
    inputs: Sequence[str | os.PathLike[str]],
    out: str | os.PathLike[str],
    *,
    overwrite: bool = False,
    valid_fraction: float = VALID_FRACTION,
) -> Written:
    """One file of all `inputs`' demos, in order. The inputs must hold demos of the same env
    and keywords, under different seeds."""
    if not inputs:
        raise SpecError("merge needs at least one input file")
    files = [DemoFile(p) for p in inputs]
    try:
        _not_an_input(out, [f.path for f in files])
        first = files[0]
        for f in files[1:]:
            if (f.env_name, f.env_kwargs) != (first.env_name, first.env_kwargs):
                raise DemoFileError(
                    f"{f.path} holds demos of {f.env_name} with {f.env_kwargs}, {first.path} of "
                    f"{first.env_name} with {first.env_kwargs}: merge files of one env"
                )
        demos = _demos_with_models(files)
        return _write(out, first.env_name, first.env_kwargs, demos, overwrite, valid_fraction)
    finally:
        for f in files:
            f.close()


def filter_demos(
    src: str | os.PathLike[str],
    out: str | os.PathLike[str],
    *,
    success: bool | None = None,
    min_length: int | None = None,
    max_length: int | None = None,
    seeds: Iterable[int] | None = None,
    overwrite: bool = False,
    valid_fraction: float = VALID_FRACTION,
) -> Written:
    """The demos of `src` that pass every given test: `success` (True: successes, False:
    failures), `min_length` <= steps <= `max_length`, seed in `seeds`."""
    keep_seeds = None if seeds is None else set(seeds)

    def keep(d: Demo) -> bool:
        return (
            (success is None or d.success == success)
            and (min_length is None or d.num_samples >= min_length)
            and (max_length is None or d.num_samples <= max_length)
            and (keep_seeds is None or d.seed in keep_seeds)
        )

    with DemoFile(src) as f:
        _not_an_input(out, [f.path])
        demos = _demos_with_models([f], keep)
        return _write(out, f.env_name, f.env_kwargs, demos, overwrite, valid_fraction)


def _demos_with_models(
    files: Sequence[DemoFile], keep: Callable[[Demo], bool] = lambda d: True
) -> Iterator[Demo]:
    for f in files:
        for d in f:
            if keep(d):
                yield replace(d, model_mjb=f.model_bytes(d.name))


def _not_an_input(out: str | os.PathLike[str], inputs: Iterable[Path]) -> None:
    target = Path(out).resolve()
    if any(target == p.resolve() for p in inputs):
        raise DemoFileError(f"{out} is an input too: write the result to another file")


def _write(
    out: str | os.PathLike[str],
    env_name: str,
    env_kwargs: Mapping[str, Any],
    demos: Iterable[Demo],
    overwrite: bool,
    valid_fraction: float,
) -> Written:
    """Write `demos` to a hidden file beside `out`, masks split, then rename it to `out`: a
    refusal or error on the way leaves nothing behind (and an existing `out` as it was)."""
    target = Path(out)
    valid_positions(0, valid_fraction)  # a bad fraction before any work
    if target.exists() and not overwrite:
        raise DemoFileError(f"{target} exists: pass --overwrite to replace it")
    partial = target.with_name(f".{target.name}.partial")
    n = 0
    try:
        with EpisodeWriter(partial, env_name, env_kwargs, overwrite=True) as w:
            for d in demos:
                w.write(d)
                n += 1
            w.split(valid_fraction)
        os.replace(partial, target)
    except BaseException:
        partial.unlink(missing_ok=True)
        raise
    return Written(target, n)


def parse_seeds(text: str) -> list[int]:
    """`--seeds 1,4,10-19` as a list of seeds."""
    out: list[int] = []
    for part in text.split(","):
        lo, dash, hi = part.strip().partition("-")
        try:
            first = int(lo)
            last = int(hi) if dash else first
        except ValueError:
            raise SpecError(
                f"--seeds takes integers and ranges like 1,4,10-19, got {text!r}"
            ) from None
        if last < first:
            raise SpecError(f"--seeds range {part.strip()} runs backwards")
        out.extend(range(first, last + 1))
    return out
