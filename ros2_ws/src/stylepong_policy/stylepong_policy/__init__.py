"""Training bridge (bags to reference motions), PPO + AMP training, evaluation and the 60 Hz player."""
