"""`python -m mjkdl.demos collect | replay | teleop | evaluate | convert | merge | filter |
export-lerobot`."""

from __future__ import annotations

import argparse
import functools
import sys
import warnings
from collections.abc import Sequence
from pathlib import Path

from ..errors import MjkdlError
from .deploy import EXIT_FAULT, EXIT_STOPPED, DeploymentFault, DeploymentStopped
from .episodes import EpisodeResult
from .hdf5 import VALID_FRACTION
from .policy import PolicySource, at_policy_rate


def _policy_flags(p: argparse.ArgumentParser) -> None:
    g = p.add_mutually_exclusive_group(required=True)
    g.add_argument("--expert", action="store_true", help="the task's scripted expert")
    g.add_argument("--random", action="store_true", help="uniform random actions")
    g.add_argument(
        "--policy",
        metavar="MODULE:FN",
        help="MODULE:FN, fn(env) returns a policy(obs) -> action (with an optional reset()); "
        "lerobot:PATH, a policy lerobot-train saved; robomimic:CKPT, a checkpoint robomimic's "
        "train.py saved; or sb3:PATH.zip, a Stable-Baselines3 model",
    )


def _source(args: argparse.Namespace) -> PolicySource:
    if args.expert:
        return "expert"
    if args.random:
        return "random"
    return str(args.policy)


def _run_flags(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "env_id",
        metavar="ENV_ID",
        help="a Gymnasium id, e.g. mjkdl/PandaPickCube-v0 (evaluate: or a demonstration file, "
        "its env and model)",
    )
    _policy_flags(p)
    p.add_argument("--episodes", type=int, required=True, help="episodes to run")
    p.add_argument(
        "--seed",
        type=int,
        default=None,
        help="first seed (then seed+1, ...); default 0, or after the last one with --append",
    )
    p.add_argument("--env-kwargs", default="", metavar="JSON", help="gymnasium.make keywords")
    p.add_argument("--workers", type=int, default=1, help="worker processes (default 1)")


def parser() -> argparse.ArgumentParser:
    """The command line's parser (its `--help` texts are the reference)."""
    from .teleop import KEYS_HELP

    top = argparse.ArgumentParser(
        prog="python -m mjkdl.demos",
        description="Demonstrations: collect, replay, teleoperate, evaluate, export.",
    )
    sub = top.add_subparsers(dest="command", required=True)

    p = sub.add_parser("collect", help="record episodes of a policy into an HDF5 file")
    _run_flags(p)
    p.add_argument("--out", required=True, help="HDF5 file to write (robomimic layout)")
    p.add_argument("--keep-failures", action="store_true", help="keep unsuccessful episodes")
    p.add_argument("--append", action="store_true", help="add to an existing file")
    p.add_argument("--overwrite", action="store_true", help="replace an existing file")

    p = sub.add_parser("replay", help="replay a recorded demo, exactly")
    p.add_argument("file", metavar="FILE")
    p.add_argument("--demo", default="all", help="demo index or 'all' (default)")
    p.add_argument("--mode", choices=("actions", "states"), default="actions")
    p.add_argument("--video", default=None, help="MP4 of the replay (one demo)")

    p = sub.add_parser(
        "teleop",
        help="drive the arm by hand and record demos",
        description="Drive the arm with a keyboard or a SpaceMouse in the viewer; record demos.",
        epilog=KEYS_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("env_id", metavar="ENV_ID")
    p.add_argument("--device", default="keyboard", help="keyboard (default) or spacemouse")
    p.add_argument("--out", required=True, help="HDF5 file (appended to when it exists)")
    p.add_argument(
        "--seed", type=int, default=None, help="first seed (default: after the file's last)"
    )
    p.add_argument("--env-kwargs", default="", metavar="JSON")
    p.add_argument("--speed", type=float, default=1.0, help="fraction of full speed (0-1]")
    p.add_argument("--deadzone", type=float, default=0.1, help="SpaceMouse dead zone [0-1)")
    p.add_argument("--demos", type=int, default=None, help="stop after this many demos")

    p = sub.add_parser("evaluate", help="success rate of a policy over many seeds")
    _run_flags(p)
    p.add_argument(
        "--state-keys",
        default=None,
        metavar="K1,K2",
        help="with --policy lerobot:PATH: the observation.state keys the export used",
    )
    p.add_argument("--video", default=None, metavar="DIR", help="MP4s of the first episodes")
    p.add_argument("--videos", type=int, default=3, help="how many episodes to film")
    p.add_argument(
        "--robot-ip",
        default=None,
        metavar="HOST",
        help="deploy on the Franka arm at HOST, in the loop (docs/hardware.md): Enter or Ctrl+C "
        f"stop it (exit {EXIT_STOPPED}), a fault ends it (exit {EXIT_FAULT}), the arm at rest",
    )

    p = sub.add_parser(
        "convert", help="regenerate observations for other env keywords (cameras, sizes, keys)"
    )
    p.add_argument("file", metavar="IN")
    p.add_argument("out", metavar="OUT")
    p.add_argument(
        "--env-kwargs", default="", metavar="JSON", help="keywords updating the recorded ones"
    )
    p.add_argument(
        "--mode",
        choices=("actions", "states"),
        default="actions",
        help="replay the actions exactly (default) or set the recorded states",
    )
    p.add_argument("--overwrite", action="store_true", help="replace an existing OUT")
    _valid_fraction_flag(p)

    p = sub.add_parser("merge", help="one file of several files' demos (same env, new masks)")
    p.add_argument("files", metavar="IN", nargs="+")
    p.add_argument("--out", required=True)
    p.add_argument("--overwrite", action="store_true", help="replace an existing --out")
    _valid_fraction_flag(p)

    p = sub.add_parser("filter", help="the demos that pass tests, in a new file (new masks)")
    p.add_argument("file", metavar="IN")
    p.add_argument("out", metavar="OUT")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--success", action="store_true", help="successful demos only")
    g.add_argument("--failures", action="store_true", help="unsuccessful demos only")
    p.add_argument("--min-length", type=int, default=None, help="at least this many steps")
    p.add_argument("--max-length", type=int, default=None, help="at most this many steps")
    p.add_argument("--seeds", default=None, help="seeds to keep, e.g. 1,4,10-19")
    p.add_argument("--overwrite", action="store_true", help="replace an existing OUT")
    _valid_fraction_flag(p)

    p = sub.add_parser("export-lerobot", help="write a LeRobot v3.0 dataset")
    p.add_argument("file", metavar="FILE")
    p.add_argument("--root", required=True, help="dataset folder to create")
    p.add_argument("--repo-id", default="", help="name recorded in meta/info.json")
    p.add_argument("--task", default="", help="task description (default: the env id)")
    p.add_argument(
        "--writer",
        choices=("auto", "lerobot", "pyarrow"),
        default="auto",
        help="lerobot's own LeRobotDataset, or pyarrow + ffmpeg (auto: lerobot where it imports)",
    )
    p.add_argument(
        "--state-keys",
        default=None,
        metavar="K1,K2",
        help="observations in observation.state (default: the robot's proprioception; "
        "privileged ones such as cube_pose only when named)",
    )
    return top


def main(argv: Sequence[str] | None = None) -> int:
    """Run one command; a bad input prints its message and returns 2."""
    args = parser().parse_args(argv)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("default")
            return _dispatch(args)
    except MjkdlError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2


def _dispatch(args: argparse.Namespace) -> int:
    return {
        "collect": _collect,
        "replay": _replay,
        "teleop": _teleop,
        "evaluate": _evaluate,
        "export-lerobot": _export,
        "convert": _convert,
        "merge": _merge,
        "filter": _filter,
    }[args.command](args)


def _convert(args: argparse.Namespace) -> int:
    from .convert import convert
    from .episodes import parse_env_kwargs

    kwargs = parse_env_kwargs(args.env_kwargs)
    w = convert(
        args.file,
        args.out,
        kwargs,
        mode=args.mode,
        overwrite=args.overwrite,
        valid_fraction=args.valid_fraction,
    )
    print(f"{w.path}: {w.demos} demos, observations by {args.mode}")
    return 0


def _valid_fraction_flag(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--valid-fraction",
        type=float,
        default=VALID_FRACTION,
        help=f"share of the demos in mask/valid (default {VALID_FRACTION})",
    )


def _merge(args: argparse.Namespace) -> int:
    from .convert import merge

    w = merge(args.files, args.out, overwrite=args.overwrite, valid_fraction=args.valid_fraction)
    print(f"{w.path}: {w.demos} demos from {len(args.files)} files")
    return 0


def _filter(args: argparse.Namespace) -> int:
    from .convert import filter_demos, parse_seeds

    w = filter_demos(
        args.file,
        args.out,
        success=True if args.success else False if args.failures else None,
        min_length=args.min_length,
        max_length=args.max_length,
        seeds=None if args.seeds is None else parse_seeds(args.seeds),
        overwrite=args.overwrite,
        valid_fraction=args.valid_fraction,
    )
    print(f"{w.path}: {w.demos} demos kept")
    return 0


def _collect(args: argparse.Namespace) -> int:
    from .collect import collect
    from .episodes import parse_env_kwargs

    r = collect(
        args.env_id,
        _source(args),
        args.out,
        episodes=args.episodes,
        seed=args.seed,
        env_kwargs=parse_env_kwargs(args.env_kwargs),
        workers=args.workers,
        keep_failures=args.keep_failures,
        append=args.append,
        overwrite=args.overwrite,
    )
    print(f"{r.path}: kept {r.kept} of {r.episodes} episodes ({r.successes} successful)")
    return 0


def _replay(args: argparse.Namespace) -> int:
    from .episodes import Video
    from .replay import replay_all

    demos = None if args.demo == "all" else [int(args.demo) if args.demo.isdigit() else args.demo]
    if args.video and demos is None:
        print("error: --video films one demo: add --demo i", file=sys.stderr)
        return 2
    video = Video(Path(args.video)) if args.video else None
    worst = 0.0
    for r in replay_all(args.file, demos, mode=args.mode, video=video):
        if r.mode == "actions":
            at = "" if r.first_mismatch < 0 else f", first at step {r.first_mismatch}"
            print(f"{r.demo}: {r.steps} steps, max state error {r.max_state_error:g}{at}")
            worst = max(worst, r.max_state_error)
        else:
            px = "no cameras" if r.max_pixel_error < 0 else f"{r.max_pixel_error} levels"
            print(f"{r.demo}: {r.steps} states set, camera frames differ by at most {px}")
    return 0 if worst == 0.0 else 1


def _teleop(args: argparse.Namespace) -> int:
    from .episodes import parse_env_kwargs
    from .teleop import teleop

    n = teleop(
        args.env_id,
        args.out,
        device=args.device,
        seed=args.seed,
        env_kwargs=parse_env_kwargs(args.env_kwargs),
        speed=args.speed,
        deadzone=args.deadzone,
        demos=args.demos,
    )
    print(f"{args.out}: {n} demos saved")
    return 0


def _evaluate(args: argparse.Namespace) -> int:
    from .episodes import parse_env_kwargs
    from .evaluate import evaluate

    source = _source(args)
    kwargs = at_policy_rate(source, parse_env_kwargs(args.env_kwargs))
    if args.state_keys is not None and isinstance(source, str) and source.startswith("lerobot:"):
        from .lerobot_policy import lerobot_policy

        keys = [k for k in args.state_keys.split(",") if k]
        source = functools.partial(lerobot_policy, source, state_keys=keys)
    try:
        ev = evaluate(
            args.env_id,
            source,
            episodes=args.episodes,
            seed=0 if args.seed is None else args.seed,
            env_kwargs=kwargs,
            video_dir=args.video,
            videos=args.videos,
            workers=args.workers,
            robot_ip=args.robot_ip,
        )
    except (DeploymentStopped, DeploymentFault) as end:
        for e in end.episodes:
            _print_episode(e)
        print(
            f"{'stopped' if isinstance(end, DeploymentStopped) else 'error'}: {end}",
            file=sys.stderr,
        )
        return EXIT_STOPPED if isinstance(end, DeploymentStopped) else EXIT_FAULT
    for e in ev.episodes:
        _print_episode(e)
    print(ev.summary())
    return 0


def _print_episode(e: EpisodeResult) -> None:
    print(f"seed {e.seed}: success={e.success} return={e.total_reward:.3f} length={e.length}")


def _export(args: argparse.Namespace) -> int:
    from .lerobot import export_lerobot

    keys = None if args.state_keys is None else [k for k in args.state_keys.split(",") if k]
    out = export_lerobot(
        args.file,
        args.root,
        repo_id=args.repo_id,
        task=args.task,
        writer=args.writer,
        state_keys=keys,
    )
    print(f"{out.root}: {out.episodes} episodes, {out.frames} frames (written by {out.writer})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
