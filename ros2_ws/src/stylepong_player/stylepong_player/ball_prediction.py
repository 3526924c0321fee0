"""Where the ball is now: a measured ball state carried forward over its age, through a bounce on the table.

A ball tracker's message shows the ball some 25 ms before it arrives (exposure, stereo, filtering), and the
player steps a little later still. The actor was trained with ball observations up to 25 ms old and actions
up to one period late; behind a UR controller's servoj look-ahead (30 ms or more) the two delays add up to
more than it has seen. Carrying the ball forward to the step's time removes the sensing part: the actor then
sees a ball 0 s old, inside its training range, whatever the tracker's latency.

The flight is the simulator's (gravity and quadratic air drag, robot_cell's constants), integrated with
semi-implicit Euler; a ball whose bottom reaches the table top over the table bounces with the table's
nominal restitution and tangential factor. Plain Python floats: a few hundred operations per step, faster
than numpy on 3-vectors.
"""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from stylepong_description import robot_cell

STEP_S = 0.002  # integration step; over 50 ms it errs by well under a millimetre


def over_table(x_m: float, y_m: float) -> bool:
    """Whether a point's (x, y) lies over the table's top."""
    return abs(x_m) <= robot_cell.HALF_LENGTH_M and abs(y_m) <= robot_cell.HALF_WIDTH_M


def predict_ball(
    position_m: Sequence[float], velocity_m_s: Sequence[float], horizon_s: float
) -> tuple[np.ndarray, np.ndarray]:
    """The ball's position and velocity horizon_s (>= 0) after the given state."""
    x, y, z = (float(c) for c in position_m)
    vx, vy, vz = (float(c) for c in velocity_m_s)
    remaining_s = max(float(horizon_s), 0.0)
    while remaining_s > 1e-12:
        dt = min(STEP_S, remaining_s)
        remaining_s -= dt
        drag = robot_cell.DRAG_K_PER_M * math.sqrt(vx * vx + vy * vy + vz * vz)
        vx -= drag * vx * dt
        vy -= drag * vy * dt
        vz -= (robot_cell.GRAVITY_M_S2 + drag * vz) * dt
        x_next, y_next, z_next = x + vx * dt, y + vy * dt, z + vz * dt
        if vz < 0.0 and z >= robot_cell.TABLE_CONTACT_HEIGHT_M > z_next and over_table(x_next, y_next):
            # The bounce, at the instant of contact within the step: up from the table for the rest of it.
            before = (z - robot_cell.TABLE_CONTACT_HEIGHT_M) / (z - z_next)
            vx *= robot_cell.TABLE_TANGENTIAL_FACTOR
            vy *= robot_cell.TABLE_TANGENTIAL_FACTOR
            vz *= -robot_cell.TABLE_RESTITUTION
            z_next = robot_cell.TABLE_CONTACT_HEIGHT_M + vz * dt * (1.0 - before)
        x, y, z = x_next, y_next, z_next
    return np.array([x, y, z]), np.array([vx, vy, vz])
