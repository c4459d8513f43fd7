"""The sim-to-real gap, measured: PickCube success in the simulation, in the loop against the
nominal simulated arm, and in the loop against the "real" preset, for three policies.

The policies (rows, `--policies`): "expert", the scripted expert; "bc", robomimic's BC trained
on expert demonstrations recorded in the plain simulation; "bc-rand", the same BC trained on
demonstrations recorded under domain randomisation (`RANDOMIZATION`, given to `gym.make` as
`randomization=`). Every simulated episode runs `arm_drive="franka_impedance"` (the arm's own
joint impedance, the law the server's arm runs). The settings (columns, `--settings`): "sim",
the task env (no randomisation); "nominal", `TaskEnv(robot_ip=...)` against `python -m
mjkdl.hw.franka_sim --lockstep --scene empty`; "panda-gaz2019", the same server with
`--reality panda-gaz2019` (the Panda's identified joint friction), the "real" arm. Each cell:
`--seeds` episodes on seeds from `--eval-seed` (apart from the demonstrations' seeds 0, 1,
...), success at the episode's end with its 95 % Wilson interval. BC (`--algo`): robomimic's BC
(an MLP of `LAYERS`) or BC-RNN (an LSTM, `RNN_HORIZON`, `RNN_HIDDEN`), with the settings of
robomimic's paper configs for machine-generated low-dimensional data (no GMM; BC's learning
rate 1e-3), `--epochs` epochs of 100 gradient steps of batch 100 on one torch thread, on the
low-dimensional observations `OBS_KEYS`, from `--demos` successful demonstrations.
Everything goes to `--out` (demonstrations, robomimic's runs and logs); `--reuse` evaluates
the checkpoints it holds instead of training again, or trains on the demonstrations it holds.

robomimic, torch and the franka extra in one environment (robomimic pins its own torch):

    pip install robomimic==0.3.0 pylibfranka==0.21.3 panda-python==1.1.1 franky-control==2.0.0
    nice python benchmarks/sim_to_real.py [--demos 200] [--epochs 200] [--seeds 40] [--out DIR]
    nice python benchmarks/sim_to_real.py --policies expert --settings sim,nominal
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import subprocess
import sys
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import gymnasium as gym
import scenes  # noqa: F401  (points MENAGERIE_ROOT at the shared Menagerie when unset)

import mjkdl.demos.robomimic  # noqa: F401  (torch's Triton before any EGL context)
from mjkdl.demos import collect, make_env, make_policy, run_episode, wilson_interval
from mjkdl.hw.faults import HardwareError, ReflexError, WatchdogWarning

TASK = "mjkdl/PandaPickCube-v0"
DRIVE = {"arm_drive": "franka_impedance"}
# cube_pose: its orientation, which the expert turns the hand to
OBS_KEYS = ["panda_tcp_pos", "panda_tcp_quat", "panda_gripper", "cube_rel", "cube_pose"]
# What varies per training episode in (c): the arm's and the cube's masses (the controller's
# model stays nominal), joint damping (standing in for the joint friction the simulation
# lacks), armature, contact friction, and noise on the actions and on what the policy sees.
RANDOMIZATION = {
    "body_mass": [0.8, 1.2],
    "joint_damping": [0.5, 3.0],
    "joint_armature": [0.8, 1.2],
    "geom_friction": [0.7, 1.3],
    "action_noise": 0.05,
    "observation_noise": {"panda_tcp_pos": 0.001, "cube_rel": 0.002},
}
POLICIES = ("expert", "bc", "bc-rand")  # (a), (b), (c)
ALGOS = ("bc", "bc-rnn")  # robomimic's BC (an MLP) or BC-RNN (an LSTM)
SETTINGS = ("sim", "nominal", "panda-gaz2019")  # the simulation, then the loop's realities
RETRIES = 2
# robomimic's train.py sets torch to 2 threads; on a shared 2-core machine they spin-wait for
# each other (one run here: 37x the CPU time of 1 thread per gradient step), so it runs on one.
ONE_THREAD = (
    "import sys, torch; torch.set_num_threads(1); torch.set_num_threads = lambda n: None; "
    "from mjkdl.demos.robomimic import main; main(sys.argv[1:])"
)
LAYERS = [256, 256]  # the MLP's hidden layers (robomimic's default: 1024, 1024)
RNN_HORIZON, RNN_HIDDEN = 10, 400  # BC-RNN: robomimic's paper configs (an LSTM of 2 layers)


@dataclass
class Cell:
    """One policy in one setting: successes of episodes, the seeds that failed (to pair the
    settings' failures: a lockstep loop repeats); reflexes (counted as failures), lost
    connections (run again) and stops of the arm's watchdog on the way."""

    successes: int = 0
    episodes: int = 0
    reflexes: int = 0
    faults: int = 0
    watchdogs: int = 0
    failed: list[int] = field(default_factory=list)

    @property
    def rate(self) -> float:
        return self.successes / self.episodes


def record(out: Path, demos: int, randomized: bool, workers: int) -> int:
    """`demos` successful expert demonstrations in `out` (seeds 0, 1, ... until that many
    succeeded): the episodes it took."""
    kwargs = {**DRIVE, "randomization": RANDOMIZATION} if randomized else DRIVE
    seed, kept = 0, 0
    while kept < demos:
        more = {"append": seed > 0, "overwrite": seed == 0, "progress": False}
        got = collect(TASK, "expert", out, episodes=demos - kept, seed=seed, env_kwargs=kwargs,
                      workers=workers, **more)  # fmt: skip
        seed, kept = seed + got.episodes, kept + got.kept
    return seed


def train(data: Path, folder: Path, epochs: int, algo: str) -> Path:
    """robomimic's BC (`algo` "bc") or BC-RNN ("bc-rnn") on `data` (its train.py, through
    `mjkdl.demos.robomimic`), with the settings robomimic's paper configs give
    machine-generated low-dimensional data (`scripts/generate_paper_configs.py`): the last
    epoch's checkpoint."""
    from robomimic.config import config_factory

    c = config_factory("bc")
    with c.unlocked():
        c.train.data = str(data)
        c.train.output_dir = str(folder)
        c.train.num_epochs = epochs
        c.train.batch_size = 100
        c.train.cuda = False
        c.algo.actor_layer_dims = LAYERS
        # machine-generated data: one mode, no GMM; BC's learning rate 1e-3
        c.algo.gmm.enabled = False
        c.algo.optim_params.policy.learning_rate.initial = 1e-3
        if algo == "bc-rnn":
            c.train.seq_length = c.algo.rnn.horizon = RNN_HORIZON
            c.algo.rnn.enabled = True
            c.algo.rnn.hidden_dim = RNN_HIDDEN
            c.algo.actor_layer_dims = []  # the LSTM's output straight to the action
            c.algo.optim_params.policy.learning_rate.initial = 1e-4
        c.experiment.name = "bc"
        c.experiment.epoch_every_n_steps = 100
        c.experiment.rollout.enabled = False  # evaluated below, in each setting
        c.experiment.render_video = False
        c.experiment.save.every_n_epochs = epochs
        c.observation.modalities.obs.low_dim = OBS_KEYS
        c.observation.modalities.obs.rgb = []
    shutil.rmtree(folder, ignore_errors=True)  # train.py asks before it overwrites a run
    cfg = folder.with_suffix(".json")
    cfg.write_text(json.dumps(c, indent=2))
    log = folder.with_suffix(".log")
    with log.open("w") as f:
        cmd = [sys.executable, "-c", ONE_THREAD, "train", "--config", str(cfg)]
        subprocess.run(cmd, stdout=f, stderr=subprocess.STDOUT, check=True)
    (ckpt,) = folder.glob(f"bc/*/models/model_epoch_{epochs}.pth")
    return ckpt


class Server:
    """`python -m mjkdl.hw.franka_sim --lockstep --scene empty --reality NAME` on a loopback
    address of its own; `restart()` serves a fresh arm."""

    def __init__(self, reality: str) -> None:
        self.host = f"127.{os.getpid() % 250 + 1}.252.1"
        self._cmd = [sys.executable, "-m", "mjkdl.hw.franka_sim", "--host", self.host]
        self._cmd += ["--lockstep", "--scene", "empty", "--command-timeout", "10"]
        self._cmd += ["--reality", reality]
        self._start()

    def _start(self) -> None:
        self._proc = subprocess.Popen(self._cmd, stderr=subprocess.PIPE, text=True)
        assert self._proc.stderr is not None
        self._proc.stderr.readline()  # it listens

    def restart(self) -> None:
        self.close()
        self._start()

    def close(self) -> None:
        self._proc.terminate()
        self._proc.wait(30)


def cell(source: str, server: Server | None, seeds: int, seed: int) -> Cell:
    """`source` on seeds `seed`, `seed + 1`, ... in the simulation (no `server`) or in the loop
    against `server`: the episodes `evaluate` runs, except that an episode the arm ends with a
    reflex counts as a failure (the arm recovers at its next command), and one whose
    connection is lost or never made (libfranka's UDP timeout, or no answer, when this
    loaded machine starves the client or the server) is run again against a restarted
    server, up to `RETRIES` times."""
    out = Cell()
    # lockstep: each tick of the arm waits for its step's command, so a loop run repeats
    kwargs = DRIVE if server is None else {"robot_ip": server.host, "lockstep": True}
    env: gym.Env | None = None
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", WatchdogWarning)
        try:
            for s in range(seed, seed + seeds):
                for attempt in range(RETRIES + 1):
                    try:
                        if env is None:
                            env = make_env(TASK, kwargs)
                            policy = make_policy(source, env)
                        success = run_episode(env, policy, s, source=source).success
                        out.successes += success
                        if not success:
                            out.failed.append(s)
                    except ReflexError:
                        out.reflexes += 1
                        out.failed.append(s)
                    except HardwareError:
                        if server is None or attempt == RETRIES:
                            raise
                        out.faults += 1
                        if env is not None:
                            env.close()
                            env = None
                        server.restart()
                        continue
                    out.episodes += 1
                    break
        finally:
            if env is not None:
                env.close()
    out.watchdogs = sum(issubclass(w.category, WatchdogWarning) for w in caught)
    return out


def show(c: Cell) -> str:
    lo, hi = wilson_interval(c.successes, c.episodes)
    out = f"{100 * c.rate:.0f} % ({c.successes}/{c.episodes}, {100 * lo:.0f}–{100 * hi:.0f})"
    notes = [f"{n} {what}" for n, what in ((c.reflexes, "reflexes"), (c.faults, "lost "
             "connections"), (c.watchdogs, "watchdog stops")) if n]  # fmt: skip
    return out + (f" [{', '.join(notes)}]" if notes else "")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--demos", type=int, default=200, help="demonstrations per BC policy")
    parser.add_argument("--epochs", type=int, default=200, help="BC epochs (100 steps each)")
    parser.add_argument("--algo", choices=ALGOS, default="bc", help="robomimic's BC or BC-RNN")
    parser.add_argument("--seeds", type=int, default=20, help="episodes per cell")
    parser.add_argument("--eval-seed", type=int, default=10_000, help="first evaluation seed")
    parser.add_argument("--workers", type=int, default=1, help="processes recording demos")
    parser.add_argument("--out", type=Path, default=Path("sim_to_real_out"))
    parser.add_argument("--reuse", action="store_true", help="keep checkpoints --out holds")
    parser.add_argument("--policies", default=",".join(POLICIES), help="rows, comma-separated")
    parser.add_argument("--settings", default=",".join(SETTINGS), help="columns, comma-separated")
    args = parser.parse_args()
    rows, columns = args.policies.split(","), args.settings.split(",")
    for given, known in ((rows, POLICIES), (columns, SETTINGS)):
        if not set(given) <= set(known):
            parser.error(f"{sorted(set(given) - set(known))} not among {', '.join(known)}")
    args.out.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    policies = {"expert": "expert"} if "expert" in rows else {}
    for name in (r for r in rows if r != "expert"):
        policies[name] = f"robomimic:{bc_policy(name, args)}"
    results: dict[str, dict[str, Cell]] = {p: {} for p in policies}
    for setting in columns:
        server = None if setting == "sim" else Server(setting)
        try:
            for name, source in policies.items():
                t = time.perf_counter()
                res = cell(source, server, args.seeds, args.eval_seed)
                results[name][setting] = res
                print(f"{name}, {setting}: {show(res)} ({time.perf_counter() - t:.0f} s), "
                      f"failed: seeds {res.failed}", flush=True)  # fmt: skip
        finally:
            if server is not None:
                server.close()
    print()
    print(f"{TASK}, {args.demos} demos, {args.algo}, {args.epochs} epochs, {args.seeds} seeds "
          f"per cell from {args.eval_seed}; {platform.node()}, {os.cpu_count()} cores; "
          f"{(time.perf_counter() - start) / 60:.1f} min")  # fmt: skip
    print(f"| policy | {' | '.join(columns)} |")
    print("|---|" + "---|" * len(columns))
    for name, r in results.items():
        print(f"| {name} | {' | '.join(show(r[k]) for k in columns)} |")
    if {"sim", "panda-gaz2019"} <= set(columns):
        for name, r in results.items():
            loss = 100 * (r["sim"].rate - r["panda-gaz2019"].rate)
            print(f"{name}: {loss:.0f} points lost from sim to panda-gaz2019")


def bc_policy(name: str, args: argparse.Namespace) -> Path:
    """The checkpoint of BC policy `name` ("bc", "bc-rand") of `--algo`: recorded and trained
    here, or with `--reuse` the one `--out` holds (or trained on the demonstrations it
    holds)."""
    randomized = name == "bc-rand"
    data = args.out / f"demos_{name}.hdf5"
    folder = args.out / f"{name}-{args.algo}"
    done = sorted(folder.glob(f"bc/*/models/model_epoch_{args.epochs}.pth"))
    if args.reuse and done:
        print(f"{name}: {done[-1]} (--reuse)", flush=True)
        return done[-1]
    t = time.perf_counter()
    if args.reuse and data.is_file():
        got = f"{data} (--reuse)"
    else:
        got = f"{args.demos} demos of {record(data, args.demos, randomized, args.workers)} "
        got += f"expert episodes in {time.perf_counter() - t:.0f} s"
    t = time.perf_counter()
    ckpt = train(data, folder, args.epochs, args.algo)
    print(f"{name}: {got}, trained in {time.perf_counter() - t:.0f} s: {ckpt}", flush=True)
    return ckpt


if __name__ == "__main__":
    main()
