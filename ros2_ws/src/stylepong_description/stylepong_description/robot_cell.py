"""The facts of the robot's cell that the robot side reads as well as the simulator: the arm's home pose,
the policy's rate, the table, and the ball's flight and bounce on the table.

The player runs on a robot computer without the simulator, yet its actor was trained around this home pose,
at this rate, with the goal and ball checked against this table; the simulator's world (`stylepong_sim.
world_spec`) takes the same numbers from here, so the two sides cannot drift apart.
The player carries the measured ball forward over its sensing delay with the same flight and bounce.
Frame `world`: origin on the floor under the table centre, x along the table from the robot's end (x < 0)
to the opponent's end, y to the robot's left, z up.
"""

from __future__ import annotations

import math

# The frame every ball, goal and marker is given in (the module's docstring says where it lies). Messages
# name it in header.frame_id; a real cell's tf tree must call its root this for the player to accept a ball.
FRAME_WORLD = 'world'

# The strokes a demonstration is labelled with and a ball asks for: towards the paddle, to the robot's left
# (+y) or to its right. The recorder's labels, the virtual teacher's swings, the dataset's label names and
# the per-direction metrics all use these words in this order (the order is the dataset's label indices).
STROKE_LABELS = ('forward', 'leftward', 'rightward')

# Home pose (URDF joint order): paddle centre at about (-1.47, 0.11, 0.89) m, handle up, face normal +x.
HOME_JOINT_POSITIONS_RAD = (0.0, -1.9, 1.9, -1.57, -1.57, -1.57)

# The rate at which an actor acts, in training and on the robot (one command per period).
POLICY_RATE_HZ = 60.0

# The table (ITTF) and its halves.
TABLE_LENGTH_M = 2.74
TABLE_WIDTH_M = 1.525
HALF_LENGTH_M = TABLE_LENGTH_M / 2.0
HALF_WIDTH_M = TABLE_WIDTH_M / 2.0

# A ball whose centre leaves this box (|x|, |y| below the bounds; z above the floor) has left the cell.
CELL_HALF_EXTENT_M = (5.0, 4.0)

# The table's playing surface above the floor (ITTF).
TABLE_HEIGHT_M = 0.76

# The UR5 base stands on a pedestal behind the robot's end line, facing +x. From there the paddle
# (tool flange to blade centre 0.175 m) reaches balls that bounce on the robot's half and rise past
# the end line, across the table's width. Behind it a ball is out of play (the ball estimator's volume).
ROBOT_BASE_POSITION_M = (-HALF_LENGTH_M - 0.45, 0.0, TABLE_HEIGHT_M - 0.10)

# The ball (ITTF) in flight: gravity and air drag, a = -k |v| v with k = rho C_D A / (2 m).
GRAVITY_M_S2 = 9.81
BALL_MASS_KG = 0.0027
BALL_RADIUS_M = 0.020
AIR_DENSITY_KG_M3 = 1.18
DRAG_COEFFICIENT = 0.47
BALL_AREA_M2 = math.pi * BALL_RADIUS_M**2
# About 0.129 1/m (Koc's fitted 0.1414).
DRAG_K_PER_M = 0.5 * AIR_DENSITY_KG_M3 * DRAG_COEFFICIENT * BALL_AREA_M2 / BALL_MASS_KG
# Where the ball's centre is when its bottom touches the table top.
TABLE_CONTACT_HEIGHT_M = TABLE_HEIGHT_M + BALL_RADIUS_M

# The ball's bounce on the table (MPI ball models): the normal velocity reversed and scaled by the
# restitution (ITTF: a 30 cm drop rebounds about 23 cm), the tangential velocity scaled by the factor.
TABLE_RESTITUTION = 0.89
TABLE_TANGENTIAL_FACTOR = 0.70
