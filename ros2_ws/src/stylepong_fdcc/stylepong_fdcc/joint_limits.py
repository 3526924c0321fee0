"""Joint limits of the simulated arm (docs/DESIGN.md, "FDCC safety layer").

Positions stay `position_margin_rad` inside the URDF's (the arm brakes at the acceleration limit before
reaching them), velocities within `velocity_limit_scale` x the URDF's and accelerations within
`acceleration_limit_rad_s2`. Velocity and acceleration are limited by scaling the whole joint vector, so
the tool keeps its direction.
"""

from __future__ import annotations

import numpy as np

from stylepong_description.robot_model import JointLimits
from stylepong_fdcc.fdcc_config import FdccConfig


def command_limits(config: FdccConfig) -> JointLimits:
    """The limits drag_teach's commands keep: the URDF's narrowed by the config's margin, scale and accelerations."""
    return JointLimits.for_commands(
        config.position_margin_rad, config.velocity_limit_scale, config.acceleration_limit_rad_s2
    )


def uniform_scale(vector: np.ndarray, bound: np.ndarray) -> float:
    """Largest factor <= 1 that brings every |vector_i| within bound_i."""
    magnitude = np.abs(vector)
    over = magnitude > bound
    if not np.any(over):
        return 1.0
    return float(np.min(bound[over] / magnitude[over]))


def limit_motion(
    q: np.ndarray, qdot: np.ndarray, qdot_wanted: np.ndarray, dt_s: float, limits: JointLimits
) -> tuple[np.ndarray, np.ndarray]:
    """Next (q, qdot) from the wanted velocity, within acceleration, velocity and position limits."""
    delta = qdot_wanted - qdot
    new_qdot = qdot + uniform_scale(delta, limits.acceleration_rad_s2 * dt_s) * delta
    new_qdot = new_qdot * uniform_scale(new_qdot, limits.velocity_rad_s)
    # Brake towards a position limit so that the acceleration limit can still stop the joint there.
    room = np.where(new_qdot > 0, limits.upper_rad - q, q - limits.lower_rad)
    braking_speed = np.sqrt(2.0 * limits.acceleration_rad_s2 * np.clip(room, 0.0, None))
    new_qdot = np.clip(new_qdot, -braking_speed, braking_speed)
    new_q = q + new_qdot * dt_s
    clipped = np.clip(new_q, limits.lower_rad, limits.upper_rad)
    new_qdot = np.where(clipped != new_q, 0.0, new_qdot)
    return clipped, new_qdot


def decelerate(qdot: np.ndarray, dt_s: float, limits: JointLimits) -> np.ndarray:
    """Joint velocity one step later on a straight-line stop at the acceleration limits."""
    time_to_stop_s = float(np.max(np.abs(qdot) / limits.acceleration_rad_s2))
    if time_to_stop_s <= dt_s:
        return np.zeros_like(qdot)
    return qdot * (1.0 - dt_s / time_to_stop_s)
