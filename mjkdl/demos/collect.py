"""Collection: episodes from seeds S, S+1, ... into one HDF5 file, in seed order."""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from tqdm import tqdm

from ..errors import SpecError
from ..task._check import integer
from .episodes import is_demo_file, run_seeds
from .hdf5 import DemoFile, DemoFileError, EpisodeWriter
from .policy import PolicySource


@dataclass(frozen=True)
class CollectResult:
    """What a collection wrote: episodes run, demos kept, and the file."""

    path: Path
    episodes: int
    kept: int
    successes: int


def collect(
    env_id: str,
    policy: PolicySource,
    out: str | os.PathLike[str],
    *,
    episodes: int,
    seed: int | None = None,
    env_kwargs: Mapping[str, Any] | None = None,
    workers: int = 1,
    keep_failures: bool = False,
    append: bool = False,
    overwrite: bool = False,
    progress: bool = True,
) -> CollectResult:
    """Run `episodes` episodes (seeds `seed`, `seed + 1`, ...) and write the successful ones
    (all with `keep_failures`) to `out`, each flushed as it is written. An existing `out` is
    refused unless `append` (add to it) or `overwrite` (replace it). `seed` defaults to 0, or
    when appending to the seed after the file's last; a seed the file holds is refused."""
    if isinstance(env_id, str) and is_demo_file(env_id):
        raise SpecError(
            f"collect records into a Gymnasium id's env, got the demonstration file {env_id} "
            "(evaluate and replay take files)"
        )
    episodes = integer(episodes, "--episodes")
    held = _held_seeds(out) if append else []
    seed = 1 + max(held, default=-1) if seed is None else integer(seed, "--seed", least=0)
    kwargs = dict(env_kwargs or {})
    seeds = range(seed, seed + episodes)
    again = sorted(set(held).intersection(seeds))
    if again:
        raise DemoFileError(
            f"{out} already holds seeds {again[:5]}{' ...' if len(again) > 5 else ''}: the same "
            f"seed twice is the same demo twice; leave out --seed to continue at {max(held) + 1}"
        )
    results = run_seeds(env_id, kwargs, policy, seeds, record=True, workers=workers)
    kept = successes = 0
    with (
        EpisodeWriter(out, env_id, kwargs, append=append, overwrite=overwrite) as writer,
        tqdm(total=episodes, desc=f"collect {env_id}", unit="ep", disable=not progress) as bar,
    ):
        for result in results:
            successes += result.success
            if (result.success or keep_failures) and result.data is not None:
                writer.write(result.data)
                kept += 1
            elif result.data is not None:
                writer.add_model(result.data)  # later episodes of its worker come without it
            bar.update()
            bar.set_postfix(kept=kept)
        path = writer.path
    return CollectResult(path, episodes, kept, successes)


def _held_seeds(out: str | os.PathLike[str]) -> list[int]:
    if not Path(out).exists():
        return []
    with DemoFile(out) as f:
        return f.seeds
