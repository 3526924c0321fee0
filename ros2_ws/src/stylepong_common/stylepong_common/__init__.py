"""Shared helpers of the StylePong nodes (ROS 2 wiring only; no robot or task knowledge)."""
