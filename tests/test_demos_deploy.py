"""Policies deployed on an arm (`evaluate(..., robot_ip=...)`, `--robot-ip`) against the lockstep
simulated Franka (`--scene empty`): one action per control step and a reset per episode, the
policy's own rate, Ctrl+C and the stop key, faults of the policy and of the connection, each
ending with the arm at rest; Stable-Baselines3 models as policies (`sb3:PATH.zip`)."""

from __future__ import annotations

import ast
import json
import os
import pty
import re
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import (
    ROOT,
    franka_sim,
    import_extra,
    menagerie,
    needs_extra,
    sigint_as_from_a_terminal,
)

from mjkdl import SpecError
from mjkdl.demos import (
    DeploymentFault,
    DeploymentStopped,
    PolicyError,
    StopKey,
    evaluate,
    make_env,
    make_policy,
    policy_rate,
)
from mjkdl.demos.lerobot_policy import chunk_execution
from mjkdl.demos.policy import at_policy_rate

PICK = "mjkdl/PandaPickCube-v0"
REACH = "mjkdl/PandaReach-v0"


@pytest.fixture(autouse=True)
def _panda() -> None:
    menagerie("franka_emika_panda")


@pytest.fixture(scope="module")
def arm() -> Iterator[str]:
    """A lockstep simulated Franka serving the arm alone, as deployments in the loop want."""
    needs_extra("franka")
    with franka_sim("--lockstep", "--scene", "empty", "--command-timeout", "10") as sim:
        yield sim.host


def arm_state(host: str) -> tuple[np.ndarray, np.ndarray]:
    """(q, dq) of the server's arm, read through a connection of its own."""
    from mjkdl.hw.connection import ArmConnection

    conn = ArmConnection(host, "panda")
    try:
        s = conn.state()
        return s.q, s.dq
    finally:
        conn.close()


# ---------------------------------------------------------------------- without an arm


def _lerobot_folder(tmp_path: Path, fps: float, env_fps: float | None = None) -> Path:
    """What lerobot-train saves beside a policy (train_config.json) and its dataset's info."""
    root = tmp_path / "dataset"
    (root / "meta").mkdir(parents=True)
    (root / "meta" / "info.json").write_text(json.dumps({"fps": fps}))
    model = tmp_path / "pretrained_model"
    model.mkdir()
    env = None if env_fps is None else {"type": "x", "fps": env_fps}
    train = {"dataset": {"repo_id": "me/pick", "root": str(root)}, "env": env}
    (model / "train_config.json").write_text(json.dumps(train))
    return model


def test_a_lerobot_policy_acts_at_its_datasets_rate(tmp_path: Path) -> None:
    model = _lerobot_folder(tmp_path, 20)
    assert policy_rate(f"lerobot:{model}") == 20.0
    assert policy_rate("expert") is None and policy_rate("sb3:x.zip") is None
    assert at_policy_rate(f"lerobot:{model}", {"time_limit": 2}) == {
        "time_limit": 2,
        "control_timestep": 0.05,
    }
    assert at_policy_rate("expert", {}) == {}  # experts, SB3, module:fn: the env's rate
    env = make_env(REACH, at_policy_rate(f"lerobot:{model}", {}))
    assert env.unwrapped.control_timestep == 0.05
    env.close()
    with pytest.raises(PolicyError, match=r"acts at 20 actions/s \(control_timestep 0.05 s\); "
                       r"--env-kwargs sets control_timestep 0.1: leave it out"):  # fmt: skip
        at_policy_rate(f"lerobot:{model}", {"control_timestep": 0.1})
    assert policy_rate(f"lerobot:{_lerobot_folder(tmp_path / 'e', 20, 30)}") == 30.0  # env's
    assert policy_rate(f"lerobot:{tmp_path}") is None  # no train_config.json: the env's rate


def test_chunk_execution_follows_the_policys_config() -> None:
    from types import SimpleNamespace as C

    act = C(chunk_size=100, n_action_steps=100, temporal_ensemble_coeff=None)
    assert chunk_execution(act) == "chunk-wise: 100 actions of each chunk of 100, then a new chunk"
    act = C(chunk_size=100, n_action_steps=1, temporal_ensemble_coeff=0.01)
    assert chunk_execution(act) == "temporal ensembling (coefficient 0.01, chunks of 100)"
    diffusion = C(horizon=16, n_action_steps=8)
    assert (
        chunk_execution(diffusion) == "chunk-wise: 8 actions of each chunk of 16, then a new chunk"
    )
    assert chunk_execution(C()) == "one action per call"


def test_the_stop_key_reads_a_terminal_only() -> None:
    main, side = pty.openpty()
    with open(side, closefd=True) as terminal:
        key = StopKey(terminal)
        assert key.active and not key.pressed.wait(0.2)
        os.write(main, b"\n")  # Enter
        assert key.pressed.wait(5)
        key.close()
    os.close(main)
    with open(__file__) as file:  # not a terminal: nothing watched, never pressed
        key = StopKey(file)
        assert not key.active and not key.pressed.wait(0.1)


def test_robot_ip_refuses_workers_and_a_second_address() -> None:
    with pytest.raises(SpecError, match=r"--robot-ip: the arm takes one client, run --workers 1"):
        evaluate(REACH, "expert", episodes=1, workers=2, robot_ip="127.0.0.1", progress=False)
    with pytest.raises(SpecError, match=r"give the address once"):
        evaluate(REACH, "expert", episodes=1, robot_ip="h", env_kwargs={"robot_ip": "h"})


# ---------------------------------------------------------------------- Stable-Baselines3


def test_an_sb3_model_is_a_policy_source(tmp_path: Path) -> None:
    sb3 = import_extra("rl", "stable_baselines3")
    from gymnasium.wrappers import FlattenObservation

    env = make_env(REACH, {"max_episode_steps": 5})
    sac = sb3.SAC("MultiInputPolicy", env, buffer_size=10, seed=0)
    sac.save(tmp_path / "sac")
    policy = make_policy(f"sb3:{tmp_path / 'sac.zip'}", env)
    assert policy.algorithm == "SAC"
    obs, _ = env.reset(seed=0)
    want, _ = sac.predict(obs, deterministic=True)
    assert np.array_equal(policy(obs), want)
    flat = FlattenObservation(env)  # a model trained on the flattened observation
    ppo = sb3.PPO("MlpPolicy", flat, n_steps=8, batch_size=8, seed=0)
    ppo.save(tmp_path / "ppo")
    policy = make_policy(f"sb3:{tmp_path / 'ppo.zip'}", env)
    assert policy.algorithm == "PPO"
    want, _ = ppo.predict(flat.observation(obs), deterministic=True)
    assert np.array_equal(policy(obs), want)
    ev = evaluate(REACH, f"sb3:{tmp_path / 'ppo.zip'}", episodes=2,
                  env_kwargs={"max_episode_steps": 5}, progress=False)  # fmt: skip
    assert [e.length for e in ev.episodes] == [5, 5]
    pick = make_env(PICK)
    with pytest.raises(PolicyError, match=r"sb3:.*sac.zip \(SAC\) takes observations Dict"):
        make_policy(f"sb3:{tmp_path / 'sac.zip'}", pick)
    with pytest.raises(PolicyError, match=r"sb3:.*nothing.zip: no such file"):
        make_policy(f"sb3:{tmp_path / 'nothing.zip'}", env)
    (tmp_path / "bad.zip").write_text("not a zip")
    with pytest.raises(PolicyError, match=r"not a model Stable-Baselines3 saved"):
        make_policy(f"sb3:{tmp_path / 'bad.zip'}", env)
    env.close()
    pick.close()


# ---------------------------------------------------------------------- on the arm


class Chunked:
    """A chunked policy as LeRobot's ACT is driven: `select_action` pops a queue it refills
    with a chunk of `n` actions, `reset()` clears it; counts what it was asked."""

    def __init__(self, env: Any, n: int = 4) -> None:
        from mjkdl.task.experts import expert_for

        self.expert, self.n = expert_for(env), n
        self.queue: list[np.ndarray] = []
        self.calls = self.chunks = self.resets = 0

    def __call__(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        self.calls += 1
        if not self.queue:
            self.chunks += 1
            first = np.asarray(self.expert(obs), dtype=np.float32)
            self.queue = [first] * self.n
        return self.queue.pop(0)

    def reset(self) -> None:
        self.resets += 1
        self.queue = []
        self.expert.reset()


def test_a_chunked_policy_runs_one_action_per_control_step_on_the_arm(arm: str) -> None:
    made: list[Chunked] = []

    def chunked(env: Any) -> Chunked:
        made.append(Chunked(env))
        return made[-1]

    ev = evaluate(PICK, chunked, episodes=2, robot_ip=arm, progress=False,
                  env_kwargs={"max_episode_steps": 6})  # fmt: skip
    (policy,) = made
    assert [e.length for e in ev.episodes] == [6, 6]
    assert (policy.calls, policy.resets, policy.chunks) == (12, 2, 4)  # 2 chunks per episode
    _, dq = arm_state(arm)  # the run closed its connection with the arm at rest
    assert np.abs(dq).max() < 0.01


def test_policy_faults_end_the_run_with_the_arm_at_rest(arm: str) -> None:
    def raises(env: Any) -> Any:
        steps = iter(range(100))

        def policy(obs: dict[str, np.ndarray]) -> np.ndarray:
            if next(steps) == 3:
                raise ValueError("the camera is unplugged")
            a = np.zeros(env.action_space.shape, np.float32)
            a[2] = -0.5  # the TCP down: the arm moves when the fault comes
            return a

        return policy

    with pytest.raises(DeploymentFault) as caught:
        evaluate(PICK, raises, episodes=1, robot_ip=arm, progress=False)
    text = str(caught.value)
    assert re.search(
        r"a fault ended the run at seed 0, after 3 control steps \(0 episodes done, 0 "
        r"successful\): PolicyError: policy .*raises.* raised ValueError: the camera is "
        r"unplugged; the arm is at rest \(joint speeds <= .* rad/s\) at q = \[",
        text,
    ), text
    assert isinstance(caught.value.__cause__, PolicyError)
    speed = float(re.search(r"joint speeds <= (\S+) rad/s", text).group(1))
    assert speed < 0.01
    rest_q = np.array(ast.literal_eval(text[text.index("at q = ") + 7 :]))
    q, dq = arm_state(arm)  # held where the run left it
    np.testing.assert_allclose(q, rest_q, atol=2e-3)
    assert np.abs(dq).max() < 0.01

    def nan(env: Any) -> Any:
        return lambda obs: np.full(env.action_space.shape, np.nan)

    with pytest.raises(DeploymentFault, match=r"at seed 4, after 0 control steps .*PolicyError: "
                       r"policy .*nan.* \(seed 4, step 0\) returned non-finite entries at "
                       r"\[0, 1, 2, 3, 4, 5, 6\].*; the arm is at rest"):  # fmt: skip
        evaluate(PICK, nan, episodes=1, seed=4, robot_ip=arm, progress=False)


def test_the_stop_key_ends_the_run_with_the_arm_at_rest(arm: str) -> None:
    main, side = pty.openpty()
    terminal = open(side)  # noqa: SIM115  (closed below)
    key = StopKey(terminal)

    def pressing(env: Any) -> Any:
        steps = iter(range(100))

        def policy(obs: dict[str, np.ndarray]) -> np.ndarray:
            if next(steps) == 2:  # Enter during the third step
                os.write(main, b"\n")
                assert key.pressed.wait(5)
            a = np.zeros(env.action_space.shape, np.float32)
            a[1] = 0.5
            return a

        return policy

    try:
        with pytest.raises(DeploymentStopped) as caught:
            evaluate(PICK, pressing, episodes=2, robot_ip=arm, stop_key=key, progress=False)
    finally:
        terminal.close()
        os.close(main)
    assert re.match(
        r"stopped by the stop key \(Enter\) at seed 0, after 3 control steps \(0 episodes done, "
        r"0 successful\); the arm is at rest \(joint speeds <= ",
        str(caught.value),
    ), str(caught.value)
    assert caught.value.episodes == []


def _deploy_cli(arm: str, stdin: int) -> subprocess.Popen:
    """`python -m mjkdl.demos evaluate PICK --expert --robot-ip arm`, started."""
    return subprocess.Popen(
        [sys.executable, "-m", "mjkdl.demos", "evaluate", PICK, "--expert", "--episodes", "100",
         "--robot-ip", arm],
        stdin=stdin, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        env={**os.environ, "PYTHONPATH": f"{ROOT}:{ROOT / 'tests'}"},
        preexec_fn=sigint_as_from_a_terminal,
    )  # fmt: skip


def _stopped(proc: subprocess.Popen, arm: str, stop: Any) -> tuple[int, str]:
    """Stop the run with `stop()` once it moves the arm; (exit code, the `stopped:` line)."""
    try:
        assert proc.stdout is not None
        assert "rate-limited" in proc.stdout.readline()  # connected
        time.sleep(8.0)  # home, then the expert's first steps (or episodes: 100 take minutes)
        stop()
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert "Traceback" not in err, err[-2000:]
    assert f"deploying expert on the arm at {arm}: 10 actions/s\n" in err, err[-2000:]
    line = [ln for ln in err.splitlines() if ln.startswith("stopped: ")]
    assert line, err[-2000:]
    return proc.returncode, line[0]


def test_ctrl_c_brings_the_arm_to_rest_and_exits_130(arm: str) -> None:
    proc = _deploy_cli(arm, subprocess.DEVNULL)
    code, line = _stopped(proc, arm, lambda: proc.send_signal(signal.SIGINT))
    assert code == 130
    assert re.match(
        r"stopped: stopped by Ctrl\+C at seed \d+, after \d+ control steps \(\d+ episodes done, "
        r"\d+ successful\); the arm is at rest \(joint speeds <= \S+ rad/s\) at q = \[",
        line,
    ), line
    rest_q = np.array(ast.literal_eval(line[line.index("at q = ") + 7 :]))
    q, dq = arm_state(arm)
    np.testing.assert_allclose(q, rest_q, atol=2e-3)
    assert np.abs(dq).max() < 0.01


def test_enter_on_the_terminal_stops_the_command_and_bad_input_exits_2(arm: str) -> None:
    main, side = pty.openpty()
    try:
        proc = _deploy_cli(arm, side)
        code, line = _stopped(proc, arm, lambda: os.write(main, b"\n"))
    finally:
        os.close(main)
        os.close(side)
    assert code == 130
    assert re.match(r"stopped: stopped by the stop key \(Enter\) at seed \d+, after \d+ control "
                    r"steps .*; the arm is at rest \(joint speeds <= ", line), line  # fmt: skip
    r = subprocess.run(
        [sys.executable, "-m", "mjkdl.demos", "evaluate", PICK, "--policy", "sb3:nothing.zip",
         "--episodes", "1", "--robot-ip", arm],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert r.returncode == 2 and "error: --policy sb3:nothing.zip: no such file" in r.stderr


def test_a_lost_server_is_a_fault_naming_the_connection() -> None:
    needs_extra("franka")
    with franka_sim("--lockstep", "--scene", "empty") as sim:

        def kills(env: Any) -> Any:
            steps = iter(range(100))

            def policy(obs: dict[str, np.ndarray]) -> np.ndarray:
                if next(steps) == 2:
                    sim.proc.kill()
                    sim.proc.wait()
                return np.zeros(env.action_space.shape, np.float32)

            return policy

        with pytest.raises(DeploymentFault) as caught:
            evaluate(PICK, kills, episodes=1, robot_ip=sim.host, progress=False)
    text = str(caught.value)
    assert re.search(r"a fault ended the run at seed 0, after \d control steps .*: "
                     r"ArmConnectionError: .*", text), text  # fmt: skip
    assert text.endswith(
        f"the connection to the arm at {sim.host} is lost, so nothing here can move it: a "
        "Franka arm stops by itself once commands stop coming (its communication reflex)"
    ), text


def test_a_reflex_is_a_fault_with_the_arm_at_rest() -> None:
    """Against the server's pick scene (its own table, which the env's scene does not know of)
    a policy driving the hand straight down ends in the robot's reflex."""
    needs_extra("franka")
    with franka_sim("--lockstep", "--command-timeout", "10", "--scene", "pick") as sim:

        def down(env: Any) -> Any:
            a = np.zeros(env.action_space.shape, np.float32)
            a[2] = env.action_space.low[2]  # the TCP down at full speed
            return lambda obs: a

        with pytest.raises(DeploymentFault) as caught:
            evaluate(PICK, down, episodes=1, robot_ip=sim.host, progress=False)
        _, dq = arm_state(sim.host)
    text = str(caught.value)
    assert re.search(r"a fault ended the run at seed 0, after \d+ control steps \(0 episodes "
                     r"done, 0 successful\): ReflexError: .*reflex.*serve `--scene empty`.*; "
                     r"the arm is at rest \(joint speeds <= ", text, re.S), text  # fmt: skip
    assert np.abs(dq).max() < 0.01
