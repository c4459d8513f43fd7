"""Many worlds of one task at once: `make_batch` -> `BatchEnv`, torch tensors (the `batch`
extra; the `warp` extra adds MuJoCo Warp for a GPU).

`env` holds the task (the CPU env's definition, batched); `engine` the small interface an
engine gives it; `cpu_engine` (MuJoCo's `mujoco.batch`) and `warp_engine` (MuJoCo Warp) are
the engines; `control`, `sensors`, `reset` and `cameras` the task's parts over all worlds;
`ppo` trains on it with rsl-rl (the `warp-rl` extra).
"""

from .engine import Engine, UnsupportedFeatureError
from .env import ENGINES, RANDOMIZED, BatchEnv, DeviceUnavailableError, make_batch

__all__ = [
    "ENGINES",
    "RANDOMIZED",
    "BatchEnv",
    "DeviceUnavailableError",
    "Engine",
    "UnsupportedFeatureError",
    "make_batch",
]
