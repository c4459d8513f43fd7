"""Collection: episodes from seeds S, S+1, ... into one HDF5 file, in seed order."""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from tqdm import tqdm

from ..task._check import integer
from .episodes import run_seeds
from .hdf5 import EpisodeWriter
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
    seed: int = 0,
    env_kwargs: Mapping[str, Any] | None = None,
    workers: int = 1,
    keep_failures: bool = False,
    append: bool = False,
    overwrite: bool = False,
    progress: bool = True,
) -> CollectResult:
    """Run `episodes` episodes (seeds `seed`, `seed + 1`, ...) and write the successful ones
    (all with `keep_failures`) to `out`, each flushed as it is written. An existing `out` is
    refused unless `append` (add to it) or `overwrite` (replace it)."""
    episodes = integer(episodes, "--episodes")
    seed = integer(seed, "--seed", least=0)
    kwargs = dict(env_kwargs or {})
    seeds = range(seed, seed + episodes)
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
            bar.update()
            bar.set_postfix(kept=kept)
        path = writer.path
    return CollectResult(path, episodes, kept, successes)
