"""`python -m mjkdl.hw.franka_sim`: a simulated Franka arm and hand for libfranka clients."""

from __future__ import annotations

import argparse
import logging
import signal
import sys

from mjkdl.errors import MjkdlError

from .scene import SCENES
from .server import FrankaSimServer


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m mjkdl.hw.franka_sim",
        description="A MuJoCo-simulated Franka arm and hand serving the Franka Control "
        "Interface: point libfranka, pylibfranka, franky or panda-py at --host.",
    )
    parser.add_argument(
        "--host", default="127.0.0.1", help="address to serve (default %(default)s)"
    )
    parser.add_argument(
        "--model",
        choices=("panda", "fr3"),
        default="panda",
        help="limits to enforce; fr3 keeps the Panda's kinematics (no FR3 model)",
    )
    timing = parser.add_mutually_exclusive_group()
    timing.add_argument(
        "--realtime",
        action="store_true",
        help="wall-clock 1 kHz; late commands count as lost (the default)",
    )
    timing.add_argument(
        "--lockstep",
        action="store_true",
        help="during a motion, each state waits for its command (deterministic)",
    )
    parser.add_argument(
        "--scene",
        choices=SCENES,
        default="pick",
        help="pick: a floor, a table and a cube; empty: the arm alone, for hardware in the loop "
        "(the client's scene simulates the rest) (default %(default)s)",
    )
    parser.add_argument(
        "--reality",
        default=None,
        help="how the arm differs from the nominal simulation: a preset (nominal, "
        "panda-gaz2019: the Panda's identified joint friction) or a JSON file of "
        "mjkdl.hw.franka_sim.reality.Reality's fields (default: nominal)",
    )
    parser.add_argument("--viewer", action="store_true", help="show the scene in MuJoCo's viewer")
    parser.add_argument(
        "--command-timeout",
        type=float,
        default=1.0,
        help="lockstep: seconds without a command before the arm stops",
    )
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s", stream=sys.stderr)
    try:
        server = FrankaSimServer(
            args.host,
            args.model,
            lockstep=args.lockstep,
            viewer=args.viewer,
            command_timeout=args.command_timeout,
            scene=args.scene,
            reality=args.reality,
        )
    except MjkdlError as err:
        print(f"franka_sim: {err}", file=sys.stderr)
        return 2
    signal.signal(signal.SIGTERM, lambda *_: server.stop())
    signal.signal(signal.SIGINT, lambda *_: server.stop())
    server.serve_forever()
    return 0


if __name__ == "__main__":
    sys.exit(main())
