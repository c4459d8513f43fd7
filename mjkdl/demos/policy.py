"""Where actions come from: a scripted expert, random actions, `module:fn`, a saved LeRobot
policy (`lerobot:PATH`, see `mjkdl.demos.lerobot_policy`) or a saved Stable-Baselines3 model
(`sb3:PATH.zip`, `mjkdl.demos.sb3_policy`).

The `module:fn` convention: `fn(env)` is called once per env (in each worker process) and
returns the policy, a callable `policy(obs) -> action`; when it also has `reset()`, that is
called at the start of every episode (after `env.reset`).
"""

from __future__ import annotations

import importlib
import math
from collections.abc import Callable, Mapping
from typing import Any, Protocol

import gymnasium as gym
import numpy as np

from ..errors import MjkdlError

Obs = Mapping[str, np.ndarray]
PolicySource = str | Callable[[gym.Env], "Policy"]
"""`"expert"`, `"random"`, `"module:fn"`, or a callable `fn(env) -> policy`."""


class PolicyError(MjkdlError, ValueError):
    """A policy that cannot be loaded or returned an unusable action."""


class Policy(Protocol):
    """What acts in an episode: `policy(obs) -> action`."""

    def __call__(self, obs: Obs) -> Any: ...


class _Random:
    """Uniform samples of the action space (the episode runner seeds it per episode)."""

    def __init__(self, env: gym.Env) -> None:
        self._space = env.action_space

    def __call__(self, obs: Obs) -> Any:
        return self._space.sample()


def describe(source: PolicySource) -> str:
    """How a source is named in messages."""
    return source if isinstance(source, str) else getattr(source, "__qualname__", repr(source))


# Sources named `PREFIX:...` that a higher module builds (`lerobot:PATH`: lerobot_policy.py,
# `sb3:PATH.zip`: sb3_policy.py), and how to read the rate each acts at.
_PREFIXED: dict[str, Callable[[str, gym.Env], Policy]] = {}
_RATES: dict[str, Callable[[str], float | None]] = {}


def register_source(
    prefix: str,
    make: Callable[[str, gym.Env], Policy],
    rate: Callable[[str], float | None] | None = None,
) -> None:
    """Let `make_policy` build sources `PREFIX:...` with `make(source, env)`; `rate(source)`
    gives the actions per second the policy was trained at (None: the env's control rate)."""
    _PREFIXED[prefix] = make
    if rate is not None:
        _RATES[prefix] = rate


def policy_rate(source: PolicySource) -> float | None:
    """Actions per second `source` acts at, where it says (a LeRobot policy: its dataset's
    fps); None where it acts at the env's control rate (experts, `module:fn`, SB3)."""
    if not isinstance(source, str):
        return None
    rate = _RATES.get(source.split(":", 1)[0])
    return None if rate is None else rate(source)


def at_policy_rate(source: PolicySource, env_kwargs: Mapping[str, Any]) -> dict[str, Any]:
    """`env_kwargs` with the control period of the policy's rate (`control_timestep` =
    1 / `policy_rate`); a `control_timestep` given otherwise is refused, naming both."""
    kwargs = dict(env_kwargs)
    fps = policy_rate(source)
    if fps is None:
        return kwargs
    period = 1.0 / fps
    given = kwargs.setdefault("control_timestep", period)
    number = isinstance(given, (int, float)) and not isinstance(given, bool)
    if number and not math.isclose(float(given), period, rel_tol=1e-9):
        raise PolicyError(
            f"policy {describe(source)} acts at {fps:g} actions/s (control_timestep "
            f"{period:g} s); --env-kwargs sets control_timestep {given}: leave it out"
        )
    return kwargs  # a given value that is no number: the env's own check names it


def make_policy(source: PolicySource, env: gym.Env) -> Policy:
    """The policy `source` gives for `env` (see the module docstring)."""
    if source == "random":
        return _Random(env)
    if source == "expert":
        return _expert(env)
    if isinstance(source, str) and source.split(":", 1)[0] in _PREFIXED:
        return _PREFIXED[source.split(":", 1)[0]](source, env)
    if isinstance(source, str):
        factory = load_factory(source)
    elif callable(source):
        factory = source
    else:
        raise PolicyError(
            f"policy must be 'expert', 'random', 'module:fn' or a callable fn(env), got {source!r}"
        )
    policy = factory(env)
    if not callable(policy):
        raise PolicyError(
            f"{describe(source)}(env) must return a callable policy(obs) -> action, "
            f"got {type(policy).__name__}"
        )
    return policy


def load_factory(spec: str) -> Callable[[gym.Env], Policy]:
    """`module:fn` imported; errors name the module or the function."""
    module_name, sep, attr = spec.partition(":")
    if not sep or not module_name or not attr:
        raise PolicyError(
            f"--policy must look like module:fn (e.g. my_policies:make), got {spec!r}"
        )
    try:
        module = importlib.import_module(module_name)
    except ImportError as err:
        raise PolicyError(f"--policy {spec}: cannot import module {module_name!r}: {err}") from None
    fn = getattr(module, attr, None)
    if not callable(fn):
        public = [n for n in dir(module) if not n.startswith("_") and callable(getattr(module, n))]
        raise PolicyError(
            f"--policy {spec}: module {module_name!r} has no callable {attr!r}; "
            f"it has: {', '.join(public) or 'nothing callable'}"
        )
    return fn


def _expert(env: gym.Env) -> Policy:
    """The task's scripted expert; an env without one is an `UnknownNameError` listing the
    tasks that have one."""
    from ..task.experts import expert_for

    return expert_for(env)


def checked_action(
    action: object, space: gym.Space, source: PolicySource, seed: int, step: int
) -> Any:
    """`action` checked against the action space (a Box: an array of its shape with finite
    entries), or a PolicyError naming the policy, the seed and the step."""
    if not isinstance(space, gym.spaces.Box):
        if space.contains(action):
            return action
        where = f"policy {describe(source)} (seed {seed}, step {step})"
        raise PolicyError(f"{where} returned {action!r}, which the action space {space} lacks")
    try:
        a = np.asarray(action, dtype=space.dtype)
    except (TypeError, ValueError):
        a = None
    if a is not None and a.shape == space.shape and math.isfinite(float(a.sum(dtype=np.float64))):
        return a
    where = f"policy {describe(source)} (seed {seed}, step {step})"
    if a is None:
        raise PolicyError(f"{where} returned {action!r}, not an array of numbers")
    if a.shape != space.shape:
        raise PolicyError(
            f"{where} returned an action of shape {a.shape}; the env takes {space.shape}"
        )
    bad = np.flatnonzero(~np.isfinite(a)).tolist()
    raise PolicyError(f"{where} returned non-finite entries at {bad}: {a.tolist()}")
