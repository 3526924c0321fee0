"""The facts of the robot's cell that the robot side reads as well as the simulator: the arm's home pose,
the policy's rate and the table's size.

The player runs on a robot computer without the simulator, yet its actor was trained around this home pose,
at this rate, with the goal and ball checked against this table; the simulator's world (`stylepong_sim.
world_spec`) takes the same numbers from here, so the two sides cannot drift apart.
Frame `world`: origin on the floor under the table centre, x along the table from the robot's end (x < 0)
to the opponent's end, y to the robot's left, z up.
"""
from __future__ import annotations

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
