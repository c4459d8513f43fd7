"""A policy deployed on an arm: episodes in the loop (`robot_ip`), stopped by a key or Ctrl+C,
every fault named, the arm at rest whenever the run ends.

The env is built with `robot_ip` (`mjkdl.hw.in_the_loop`): each `step` holds the policy's
action for one control period while the arm's position target moves there along it, one
interpolated target per 1 ms tick of the arm. The policy is asked for one action per control
step; a LeRobot policy's period is its dataset's (`policy.at_policy_rate`).

Ending a run: Enter on the terminal (`StopKey`, when stdin is one) or Ctrl+C (SIGINT) stop it
(`DeploymentStopped`); a fault of the arm (reflex, limit violation), of its connection (the
server or the network gone) or of the policy (it raised, or returned an unusable action) ends
it as a `DeploymentFault` naming the cause. Either way the arm is first brought to rest (the
connection's stopping motion: zero velocity, then the motion finished, the robot holding
where it stopped) and the message says where it rests.
"""

from __future__ import annotations

import os
import select
import sys
import threading
from collections.abc import Callable, Mapping, Sequence
from typing import Any, TextIO

import gymnasium as gym
import numpy as np

from ..errors import MjkdlError, SpecError
from .episodes import EpisodeResult, Video, make_env, run_episode
from .policy import Obs, Policy, PolicyError, PolicySource, describe, make_policy

EXIT_FAULT = 3  # `python -m mjkdl.demos evaluate --robot-ip`: a fault ended the run
EXIT_STOPPED = 130  # ... the user stopped it (the shell's code for Ctrl+C)
_AT_REST = 0.01  # rad/s: the connection's own "at rest" joint speed


class _RunEnded(MjkdlError):
    """A run that ended early, with the arm at rest. `episodes`: those that ended before."""

    def __init__(self, message: str, episodes: Sequence[EpisodeResult] = ()) -> None:
        super().__init__(message)
        self.episodes = list(episodes)


class DeploymentStopped(_RunEnded):
    """The user stopped the run (Enter, Ctrl+C); the arm is at rest. `episodes`: those that
    ended before."""


class DeploymentFault(_RunEnded, RuntimeError):
    """A fault ended the run (the arm's, its connection's or the policy's: `__cause__`); the
    arm is at rest. `episodes`: those that ended before."""


class StopKey:
    """Enter (a line: empty, `q`, anything) on `stream` asks the run to stop, when `stream` is
    a terminal (stdin by default); watched by a thread until `close()`, checked once per
    control step."""

    def __init__(self, stream: TextIO | None = None) -> None:
        self.stream = sys.stdin if stream is None else stream
        self.pressed = threading.Event()
        self._closed = threading.Event()
        self.active = bool(self.stream is not None and self.stream.isatty())
        if self.active:
            threading.Thread(target=self._watch, daemon=True).start()

    def _watch(self) -> None:
        # The descriptor, polled: a thread blocked in the stream's readline would hold its
        # buffer's lock when the interpreter shuts down, which aborts the process.
        fd = self.stream.fileno()
        while not self._closed.is_set():
            if select.select([fd], [], [], 0.05)[0]:
                if os.read(fd, 4096):  # a terminal in canonical mode hands over whole lines
                    self.pressed.set()
                return  # b"": the end of the input, no key

    def close(self) -> None:
        """Stop watching the terminal."""
        self._closed.set()


class _Stop(Exception):
    """The stop key was pressed (raised at the next control step)."""


class _Guarded:
    """The policy, asked once per control step: the stop key is checked first, and what the
    policy raises comes back as a PolicyError naming it."""

    def __init__(self, policy: Policy, source: PolicySource, key: StopKey) -> None:
        self.policy, self.source, self.key = policy, source, key

    def __call__(self, obs: Obs) -> Any:
        if self.key.pressed.is_set():
            raise _Stop
        try:
            return self.policy(obs)
        except Exception as err:
            raise PolicyError(
                f"policy {describe(self.source)} raised {type(err).__name__}: {err}"
            ) from err

    def reset(self) -> None:
        reset = getattr(self.policy, "reset", None)
        if callable(reset):
            reset()


def rest(env: gym.Env, lost: bool = False) -> str:
    """Bring the env's arm to rest and close its connection (the connection's stopping
    motion); where the arm rests, in words. `lost`: the connection to the arm was lost."""
    link = getattr(env.unwrapped, "hardware", None)
    if link is None:
        return "no arm was connected"
    conn = link.connection
    lost = lost or not (conn.alive or conn.closed)  # the loop ended: the arm is out of reach
    link.close()
    if lost:
        return (
            f"the connection to the arm at {conn.address} is lost, so nothing here can move "
            "it: a Franka arm stops by itself once commands stop coming (its communication "
            "reflex)"
        )
    s = conn.state()
    speed = float(np.abs(s.dq).max())
    q = np.round(s.q, 4).tolist()
    if speed < _AT_REST:
        return f"the arm is at rest (joint speeds <= {speed:.1e} rad/s) at q = {q}"
    return (
        f"the arm still moved at {speed:.3f} rad/s when its connection closed (at q = {q}); "
        "the robot's own stop ends the motion"
    )


def deploy(
    env_id: str,
    env_kwargs: Mapping[str, Any],
    source: PolicySource,
    seeds: Sequence[int],
    *,
    videos: Mapping[int, Video] | None = None,
    on_episode: Callable[[EpisodeResult], None] | None = None,
    stop_key: StopKey | None = None,
) -> list[EpisodeResult]:
    """One episode per seed of `source` on the env with the arm (`env_kwargs` holds
    `robot_ip`), in this process; `on_episode` is told each result. Before the first, stderr
    says what runs where, at how many actions per second (and how a LeRobot policy executes
    its chunks). The end, whatever it is, leaves the arm at rest (see the module doc)."""
    key = stop_key if stop_key is not None else StopKey()
    videos = dict(videos or {})
    results: list[EpisodeResult] = []
    env = make_env(env_id, env_kwargs)
    unwrapped: Any = env.unwrapped
    try:  # a policy that does not load is bad input, as without an arm (nothing moved)
        if getattr(unwrapped, "hardware", None) is None:
            raise SpecError(
                f"--robot-ip: {type(unwrapped).__name__} is no mjkdl task env with the arm in "
                "the loop (TaskEnv's robot_ip)"
            )
        policy = _Guarded(make_policy(source, env), source, key)
    except BaseException:
        env.close()
        key.close()
        raise
    how = getattr(policy.policy, "execution", "")  # a LeRobot policy's chunks
    print(
        f"deploying {describe(source)} on the arm at {unwrapped.hardware.address}: "
        f"{1.0 / unwrapped.control_timestep:g} actions/s{', ' + how if how else ''}",
        file=sys.stderr,
        flush=True,
    )
    seed: int | None = None
    try:
        for seed in seeds:
            result = run_episode(env, policy, seed, video=videos.get(seed), source=source)
            results.append(result)
            if on_episode is not None:
                on_episode(result)
    except (KeyboardInterrupt, _Stop) as err:
        by = "Ctrl+C" if isinstance(err, KeyboardInterrupt) else "the stop key (Enter)"
        where = _where(env, seed, results)
        raise DeploymentStopped(f"stopped by {by} {where}; {rest(env)}", results) from None
    except Exception as err:
        from ..hw.faults import ArmConnectionError

        where, lost = _where(env, seed, results), isinstance(err, ArmConnectionError)
        raise DeploymentFault(
            f"a fault ended the run {where}: {type(err).__name__}: {err}; {rest(env, lost)}",
            results,
        ) from err
    finally:
        env.close()
        key.close()
    return results


def _where(env: gym.Env, seed: int | None, results: Sequence[EpisodeResult]) -> str:
    done = f"{len(results)} episodes done, {sum(r.success for r in results)} successful"
    if seed is None:
        return f"before the first episode ({done})"
    steps = getattr(env.unwrapped, "elapsed_steps", 0)
    return f"at seed {seed}, after {steps} control steps ({done})"
