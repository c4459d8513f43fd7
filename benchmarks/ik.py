"""Robot.ik on the tutorial's Gen3 + 2F-85, TCP at the gripper's pinch site.

Targets are the TCP poses of random in-limit configurations (np.random.default_rng(0);
unlimited joints drawn in [-pi, pi]); every solve starts from the home pose. Success is
re-checked here: FK of the returned q within 1e-6 m / 1e-5 rad and q within the limits.
Reference (same task, this machine): KDL LMA in C++ 0.137 ms median at 99.86% (ignores
limits); mink 0.45 ms at 99.2%; plain damped least squares on Pinocchio 0.17 ms at 99.2%.

    python benchmarks/ik.py [--targets 1000] [--repeat 3]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import pinocchio as pin
from scenes import HOME, TOOL, tabletop_spec
from tqdm import tqdm

import mjkdl as mjk

TOL_POS, TOL_ROT = 1e-6, 1e-5


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--targets", type=int, default=1000)
    parser.add_argument("--repeat", type=int, default=3, help="timed passes; best kept per target")
    args = parser.parse_args()

    with mjk.Scene.build(tabletop_spec()) as scene:
        robot = scene.create_robot("base_link", "bracelet_link", tool=TOOL)
        limits = robot.joint_limits
        low = np.where(np.isfinite(limits[:, 0]), limits[:, 0], -np.pi)
        high = np.where(np.isfinite(limits[:, 1]), limits[:, 1], np.pi)
        qs = np.random.default_rng(0).uniform(low, high, size=(args.targets, robot.n_joints))
        targets = [robot.fk_frame(q) for q in qs]
        home = np.array(HOME)
        for target in targets[:100]:  # warm-up
            robot.ik(target, home)

        passes = []
        for _ in tqdm(range(max(1, args.repeat)), desc="passes", disable=None, leave=False):
            times, results = [], []
            for target in targets:
                t0 = time.perf_counter()
                results.append(robot.ik(target, home))
                times.append(time.perf_counter() - t0)
            passes.append(np.array(times) * 1e3)

        ok = 0
        for target, res in zip(targets, results, strict=True):
            pose = robot.fk_frame(res.q)
            pos = np.linalg.norm(pose.translation - target.translation)
            rot = np.linalg.norm(pin.log3(pose.rotation.T @ target.rotation))
            inside = bool(np.all(res.q >= limits[:, 0]) and np.all(res.q <= limits[:, 1]))
            ok += bool(res.success and inside and pos <= TOL_POS and rot <= TOL_ROT)

    n = len(targets)
    print(f"Robot.ik on Gen3 + 2F-85 (TCP g_pinch), {n} targets, seed = home pose")
    print(f"  success          {ok / n * 100:.2f} % ({ok}/{n}), limits respected")
    for label, ms in (("first pass", passes[0]), (f"best of {len(passes)}", np.min(passes, 0))):
        print(
            f"  {label + ':':16} median {np.median(ms):.4f} ms, p95 {np.percentile(ms, 95):.4f} ms"
            f"  (median vs KDL LMA 0.137 ms: {np.median(ms) / 0.137:.2f}x)"
        )
    print(f"  mean iterations  {np.mean([r.iterations for r in results]):.2f}")
    print(f"  mean restarts    {np.mean([r.restarts for r in results]):.3f}")


if __name__ == "__main__":
    main()
