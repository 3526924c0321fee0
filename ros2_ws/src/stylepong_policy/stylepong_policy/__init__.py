"""Learning and evaluation: `training/`, `evaluation/`, `reports/`, `shipping/`, `experiments/`, and the
algorithms in `rl/` (README.md lists the modules)."""

import os

# Before torch or onnxruntime start their thread pools, which every entry point of this package reaches
# through this file: idle OpenMP threads sleep instead of spinning. On 2 cores shared with other work,
# spinning threads made a PPO update 4-5x slower than one thread; sleeping ones cost about nothing.
os.environ.setdefault('OMP_WAIT_POLICY', 'PASSIVE')
