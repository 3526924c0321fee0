"""The batched training world in torch: N cells stepped together, their kinematics and their incoming balls."""
