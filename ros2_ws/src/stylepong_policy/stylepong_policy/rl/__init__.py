"""Reinforcement learning, structured like rsl_rl: networks, normaliser, rollout storage, PPO, runner,
plus the config, the training logs and the actor export."""
