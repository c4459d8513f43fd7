"""Benchmark mjkdl.ik.IKSolver on the Kinova Gen3 from MuJoCo Menagerie.

    python benchmarks/ik_solver.py [--targets 1000] [--menagerie DIR]

Targets are the pinch_site poses of random in-limit configurations (np.random.default_rng(0);
unlimited joints drawn in [-pi, pi]); every solve starts from the Gen3 home pose.  Success is
re-checked independently: FK of the returned q within 1e-6 m / 1e-5 rad and q within limits.
Times are single wall-clock measurements per solve (time.perf_counter), after one warm-up pass.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np
import pinocchio as pin

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from mjkdl.ik import IKSolver

HOME = np.array([0.0, 0.2618, 3.1416, -2.2689, 0.0, 0.9599, 1.5708])
TOL_POS, TOL_ROT = 1e-6, 1e-5


def load_gen3(menagerie: Path) -> tuple[pin.Model, int, np.ndarray, np.ndarray]:
    """The Gen3 model, its pinch_site frame and joint limits with ±inf for unlimited joints."""
    model = pin.buildModelFromMJCF(str(menagerie / "kinova_gen3" / "gen3.xml"))
    if not model.existFrame("pinch_site"):  # older parsers do not import MJCF sites
        body = model.getFrameId("bracelet_link")
        frame = model.frames[body]
        site = pin.SE3(np.diag([1.0, -1.0, -1.0]), np.array([0.0, 0.0, -0.061525]))
        model.addFrame(
            pin.Frame("pinch_site", frame.parentJoint, body, frame.placement * site, pin.OP_FRAME)
        )
    lower = model.lowerPositionLimit.copy()
    upper = model.upperPositionLimit.copy()
    lower[lower < -1e10] = -np.inf  # some parsers write ±max-float for unlimited joints
    upper[upper > 1e10] = np.inf
    return model, model.getFrameId("pinch_site"), lower, upper


def main() -> None:
    """Run the benchmark and print the figures."""
    default_root = os.environ.get("MENAGERIE_ROOT", "/work/shared/menagerie")
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--targets", type=int, default=1000)
    parser.add_argument("--menagerie", type=Path, default=Path(default_root))
    args = parser.parse_args()

    model, fid, lower, upper = load_gen3(args.menagerie)
    data = model.createData()
    sample_lo = np.where(np.isfinite(lower), lower, -np.pi)
    sample_hi = np.where(np.isfinite(upper), upper, np.pi)
    qs = np.random.default_rng(0).uniform(sample_lo, sample_hi, size=(args.targets, model.nq))
    targets = []
    for q in qs:
        pin.framesForwardKinematics(model, data, q)
        targets.append(data.oMf[fid].copy())

    solver = IKSolver(model, fid, lower, upper, tol_pos=TOL_POS, tol_rot=TOL_ROT)
    for target in targets[:100]:  # warm-up
        solver.solve(target, HOME)

    times, results = [], []
    clock = time.perf_counter
    for target in targets:
        t0 = clock()
        res = solver.solve(target, HOME)
        times.append(clock() - t0)
        results.append(res)

    ok = 0
    for target, res in zip(targets, results, strict=True):
        pin.framesForwardKinematics(model, data, res.q)
        pose = data.oMf[fid]
        pos = np.linalg.norm(pose.translation - target.translation)
        rot = np.linalg.norm(pin.log3(pose.rotation.T @ target.rotation))
        within = bool(np.all(res.q >= lower) and np.all(res.q <= upper))
        ok += bool(res.success and within and pos <= TOL_POS and rot <= TOL_ROT)

    ms = np.array(times) * 1e3
    n = len(targets)
    print(f"IKSolver on Kinova Gen3 pinch_site, {n} targets, seed = home pose")
    print(f"  success          {ok / n * 100:.2f} % ({ok}/{n}, limits respected)")
    print(f"  median           {np.median(ms):.4f} ms")
    print(f"  p95              {np.percentile(ms, 95):.4f} ms")
    print(f"  mean             {ms.mean():.4f} ms (max {ms.max():.3f} ms)")
    print(f"  mean iterations  {np.mean([r.iterations for r in results]):.2f}")
    print(f"  mean restarts    {np.mean([r.restarts for r in results]):.3f}")


if __name__ == "__main__":
    main()
