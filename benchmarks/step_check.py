"""Cost of `Scene.step()`'s divergence check against a bare `mujoco.mj_step`.

On the tabletop scene (Gen3 + 2F-85, 2 ms steps), interleaved in blocks in one process:
(a) raw MuJoCo: ``mujoco.mj_step(m, d)``;
(b) mjkdl: ``scene.step()`` with no robot handle (MuJoCo's step plus the warning-counter check);
(c) the check alone, as a fraction of (a): the comparison `Scene.step` makes inline
    (``scene._faults != _NO_FAULTS``, MuJoCo's fault counters against zeros) timed in a
    lambda, less the cost of calling an empty lambda.
The figures are medians of the per-block ratios to (a).

    python benchmarks/step_check.py
"""

from __future__ import annotations

import argparse
import statistics
import time

import mujoco
from scenes import tabletop_spec
from tqdm import tqdm

import mjkdl as mjk
from mjkdl.scene import _NO_FAULTS


def _per_step(fn, steps: int) -> float:
    start = time.perf_counter()
    for _ in range(steps):
        fn()
    return (time.perf_counter() - start) / steps


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--blocks", type=int, default=40)
    parser.add_argument("--steps", type=int, default=500)
    args = parser.parse_args()

    with mjk.Scene.build(tabletop_spec()) as scene:
        m, d = scene.model, scene.data
        raw = mujoco.MjData(m)
        mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
        mujoco.mj_resetDataKeyframe(m, raw, m.key("home").id)
        step_raw = lambda: mujoco.mj_step(m, raw)  # noqa: E731
        faults = scene._faults
        check = lambda: faults != _NO_FAULTS  # noqa: E731
        empty = lambda: None  # noqa: E731
        ratios_step, ratios_check, raw_us = [], [], []
        for _ in tqdm(range(args.blocks), desc="blocks", disable=None, leave=False):
            a = _per_step(step_raw, args.steps)
            b = _per_step(scene.step, args.steps)
            c = _per_step(check, args.steps) - _per_step(empty, args.steps)
            raw_us.append(a * 1e6)
            ratios_step.append(b / a)
            ratios_check.append(c / a)
    print(f"raw mj_step:                  {statistics.median(raw_us):8.2f} us/step")
    print(f"scene.step() / raw mj_step:   {statistics.median(ratios_step):8.3f}x")
    print(f"divergence check / mj_step:   {100 * statistics.median(ratios_check):8.2f} %")


if __name__ == "__main__":
    main()
