"""Training bridge (bags to reference motions), PPO + AMP training, evaluation and the 60 Hz player."""
import os

# Before torch or onnxruntime start their thread pools, which every entry point of this package reaches
# through this file: idle OpenMP threads sleep instead of spinning. On 2 cores shared with other work,
# spinning threads made a PPO update 4-5x slower than one thread; sleeping ones cost about nothing.
os.environ.setdefault('OMP_WAIT_POLICY', 'PASSIVE')
