"""The table-tennis cell: the one place for its geometry, physical constants and incoming balls.

Frame `world`: origin on the floor under the table centre, x along the table from the robot's end
(x < 0) to the opponent's end, y to the robot's left, z up. Read by the MuJoCo cell (`ur5_sim`), the
referee and the batched training world; nothing else may hold a copy of these numbers.
Sources: ITTF rules (table, net, ball), MPI table-tennis ball models (drag, restitution).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

# Shared with the robot side (the player), so defined there: the home pose, the policy's rate, the table,
# the cell's extent, the ball's flight (gravity, drag) and its nominal bounce on the table.
from stylepong_description.robot_cell import (  # noqa: F401  (world_spec's names for them)
    AIR_DENSITY_KG_M3,
    BALL_AREA_M2,
    BALL_MASS_KG,
    BALL_RADIUS_M,
    CELL_HALF_EXTENT_M,
    DRAG_COEFFICIENT,
    DRAG_K_PER_M,
    GRAVITY_M_S2,
    HALF_LENGTH_M,
    HALF_WIDTH_M,
    HOME_JOINT_POSITIONS_RAD,
    POLICY_RATE_HZ,
    ROBOT_BASE_POSITION_M,
    TABLE_CONTACT_HEIGHT_M,
    TABLE_HEIGHT_M,
    TABLE_LENGTH_M,
    TABLE_RESTITUTION,
    TABLE_TANGENTIAL_FACTOR,
    TABLE_WIDTH_M,
)

# --- Table and net (ITTF) -------------------------------------------------------------------------
TABLE_THICKNESS_M = 0.03
NET_HEIGHT_M = 0.1525  # above the playing surface
NET_LENGTH_M = 1.83  # 15.25 cm overhang on each side
NET_THICKNESS_M = 0.01
NET_TOP_HEIGHT_M = TABLE_HEIGHT_M + NET_HEIGHT_M  # the net's top edge above the floor
# The net as a box: its lower and upper corners (m).
NET_BOX_LOW_M = (-NET_THICKNESS_M / 2, -NET_LENGTH_M / 2, TABLE_HEIGHT_M)
NET_BOX_HIGH_M = (NET_THICKNESS_M / 2, NET_LENGTH_M / 2, NET_TOP_HEIGHT_M)

# --- Ball: its mass, size, drag (a = -DRAG_K |v| v; the air density randomised 1.18-1.20) and the table's
# contact height are imported above. Where the ball's centre is when its side touches a face of the net;
# every simulator and the incoming-ball solvers test contacts against these.
NET_FACE_CONTACT_X_M = NET_THICKNESS_M / 2.0 + BALL_RADIUS_M

# --- Contacts (restitution = normal velocity ratio; tangential factor = tangential velocity ratio) --
TABLE_RESTITUTION_RANGE = (0.86, 0.92)
TABLE_TANGENTIAL_FACTOR_RANGE = (0.68, 0.73)
PADDLE_RESTITUTION = 0.78
PADDLE_RESTITUTION_RANGE = (0.74, 0.82)
PADDLE_TANGENTIAL_FACTOR = 0.75  # rubber grips the ball: most tangential speed relative to the blade kept
NET_RESTITUTION = 0.1
NET_TANGENTIAL_FACTOR = 0.5
# Robot links other than the blade (handle, wrist, arm): painted aluminium, the ball bounces off but
# the referee fails the rally anyway.
ROBOT_LINK_RESTITUTION = 0.6
ROBOT_LINK_TANGENTIAL_FACTOR = 0.8

# --- Robot placement (the base's position: robot_cell) ------------------------------------------
ROBOT_BASE_YAW_RAD = 0.0

# The robot stands on a pedestal (floor to base). Geometry only: the arm never reaches it.
PEDESTAL_HALF_SIZE_M = (0.12, 0.12)

# --- Arm servo: a UR-like joint position servo (ros2_control forward_position_controller on a UR5) ---
# Both simulators (MuJoCo cell, batched world) implement exactly this law, every physics step dt:
#   reference:  q_ref <- q_ref + clip(q_cmd - q_ref, -v_max dt, +v_max dt)   (v_max = URDF velocity limit)
#               v_ref  = (change of q_ref in this step) / dt
#   torque:     tau = clip(Kp (q_ref - q) + Kd (v_ref - qdot), -effort, +effort)     (URDF effort limits)
#               plus ideal gravity compensation of every robot body (paddle included), outside the clip
#   dynamics:   M(q) + diag(ARM_ARMATURE) is the joint-space inertia; no joint friction
#   safety:     after integration, qdot is clipped to +-v_max (the controller's speed limit)
# The damping term is integrated implicitly by MuJoCo (integrator implicitfast); at dt = 1 ms the gains
# below are well inside the explicit stability limit too (Kd dt / I < 0.4, omega dt < 0.1).
# Armature: reflected rotor inertia of the harmonic drives (gear ratio about 100), which a real UR's
# joints have and the URDF lacks.
ARM_ARMATURE_KG_M2 = (0.1, 0.1, 0.1, 0.1, 0.1, 0.1)
ARM_KP_NM_PER_RAD = (4000.0, 4000.0, 4000.0, 1000.0, 1000.0, 1000.0)
ARM_KD_NMS_PER_RAD = (200.0, 200.0, 200.0, 40.0, 40.0, 40.0)

# --- Time -----------------------------------------------------------------------------------------
# The cell's physics step. At 1 ms a ball at up to 15 m/s moves at most 15 mm per step, less than its
# radius, so the contacts checked at a step's end position (net top, blade rim, robot links) are never
# missed; MuJoCo's own soft ball contacts would need this step too, and at 1/120 s they gave rebounds
# from nearly none to many times too strong (docs/DESIGN.md, "Analytic ball contacts").
PHYSICS_DT_S = 0.001
BALL_TIMEOUT_S = 3.0  # a rally not decided by then is a TIMEOUT
BALL_LIFETIME_S = 5.0  # a ball still in the cell this long after its launch is removed


def on_table(x_m: Any, y_m: Any) -> Any:
    """Whether a point (x, y) lies over the table. Floats, numpy arrays and torch tensors alike (the
    referee's rules use it for one ball and for a batch)."""
    return (abs(x_m) <= HALF_LENGTH_M) & (abs(y_m) <= HALF_WIDTH_M)


def off_table(x_m: Any, y_m: Any) -> Any:
    """Whether a point (x, y) lies outside the table's footprint; floats, arrays and tensors alike."""
    return (abs(x_m) > HALF_LENGTH_M) | (abs(y_m) > HALF_WIDTH_M)


def yaw_rotation(yaw_rad: float) -> np.ndarray:
    """Rotation matrix about the world z axis by `yaw_rad`.

    Pinocchio's rpyToMatrix: the virtual teacher's recorded strokes were made with it, and it differs
    from a cos/sin matrix in the last bit, so it is the one definition.
    """
    # Imported here, not at the top: the referee and the cell read this module without Pinocchio.
    import pinocchio as pin

    return pin.utils.rpyToMatrix(0.0, 0.0, yaw_rad)


def robot_base_pose() -> tuple[np.ndarray, np.ndarray]:
    """The robot base in the world: (rotation 3x3, position m), from ROBOT_BASE_YAW_RAD and _POSITION_M."""
    return yaw_rotation(ROBOT_BASE_YAW_RAD), np.array(ROBOT_BASE_POSITION_M)


# --- Incoming balls -------------------------------------------------------------------------------
# Seeds of the incoming balls: training and validation seeds stay below FIRST_EVALUATION_SEED and
# evaluation seeds start at it, so no reported figure comes from a world the policy was trained or
# selected in (docs/DESIGN.md, "Evaluation protocol"). Read by train, select_checkpoint, evaluate and
# rally_eval.
FIRST_EVALUATION_SEED = 1000
# The reported evaluation: this many seeds from FIRST_EVALUATION_SEED, this many balls each (the defaults of
# evaluate, paper_tables and style_confusion). Through ROS (rally_eval, tools/sim2sim.sh) a ball takes seconds
# of wall time, so the same seeds serve ROS_EVALUATION_BALLS_PER_SEED balls each: the first balls of each seed.
EVALUATION_SEEDS = 10
EVALUATION_BALLS_PER_SEED = 200
ROS_EVALUATION_BALLS_PER_SEED = 20
# A rally's goal: a region of this radius on the opponent's half, its centre drawn per ball (the task
# and rally_eval).
GOAL_RADIUS_M = 0.25
# The serve solvers (sample_incoming_ball here, batched_launcher for batches) search the launch
# elevation within this bracket, follow a flight to its first bounce for at most MAX_FLIGHT_S and the
# rebound towards the paddle's reach for at most REBOUND_HORIZON_S.
AIM_ELEVATION_RANGE_RAD = (math.radians(-30.0), math.radians(45.0))
MAX_FLIGHT_S = 2.0
REBOUND_HORIZON_S = 1.5


@dataclass(frozen=True)
class IncomingBallDistribution:
    """Serves from the opponent's end that bounce once on the robot's half and then come within reach.

    The launch point is above the far end of the opponent's half (where a returned ball leaves an
    opponent's paddle); the first bounce point is uniform over a
    patch of the robot's half that is wide enough to need forward, leftward and rightward strokes;
    the launch speed is uniform in [speed_min, speed_max]; the direction is solved (with drag) so that
    the ball lands on the drawn bounce point, taking the flatter of the two trajectories that clear
    the net. A draw is kept only if its rebound (nominal table coefficients) passes through the
    paddle's reachable region before it could bounce again: ball centre within reach_radius_m of
    reach_centre_m (about the UR5's shoulder; the paddle centre reaches 1.09 m from there) and at
    least min_hit_height_m above the floor.
    """

    launch_x_m: tuple[float, float] = (HALF_LENGTH_M - 0.45, HALF_LENGTH_M)
    launch_y_m: tuple[float, float] = (-0.45, 0.45)
    launch_z_m: tuple[float, float] = (TABLE_HEIGHT_M + 0.15, TABLE_HEIGHT_M + 0.40)
    bounce_x_m: tuple[float, float] = (-0.95, -0.35)
    bounce_y_m: tuple[float, float] = (-0.55, 0.55)
    speed_m_s: tuple[float, float] = (4.0, 6.6)
    net_clearance_m: float = 0.03
    reach_centre_m: tuple[float, float, float] = (
        ROBOT_BASE_POSITION_M[0],
        ROBOT_BASE_POSITION_M[1],
        ROBOT_BASE_POSITION_M[2] + 0.1,
    )
    reach_radius_m: float = 0.9
    min_hit_height_m: float = TABLE_HEIGHT_M + 0.1
    max_draws: int = 200


INCOMING = IncomingBallDistribution()
SPEED_RANGES_M_S = {'all': INCOMING.speed_m_s, 'low': (4.0, 4.8), 'high': (5.8, 6.6)}


@dataclass
class BallLaunch:
    """A drawn serve: launch position and velocity, and the point where it bounces."""

    position_m: np.ndarray
    velocity_m_s: np.ndarray
    bounce_point_m: np.ndarray = field(default_factory=lambda: np.zeros(2))


def drag_acceleration(velocity_m_s, drag_k_per_m: float = DRAG_K_PER_M):
    """Air drag on the ball, a = -k |v| v. Works on numpy arrays and torch tensors (last axis = xyz)."""
    speed = ((velocity_m_s * velocity_m_s).sum(-1)) ** 0.5
    return -drag_k_per_m * speed[..., None] * velocity_m_s


def contact_response(relative_velocity_m_s, normal, restitution, tangential_factor):
    """Outgoing velocity, relative to the surface, of a ball hitting it (the MPI simulators' law).

    The normal component is reversed and scaled by the restitution, the tangential one scaled by the
    tangential factor; a ball already leaving the surface is unchanged. Arrays of shape (..., 3) with
    unit normals pointing out of the surface; numpy arrays and torch tensors alike.
    """
    normal_speed = (relative_velocity_m_s * normal).sum(-1)[..., None]
    normal_part = normal_speed * normal
    tangential_part = relative_velocity_m_s - normal_part
    outgoing = tangential_factor * tangential_part - restitution * normal_part
    approaching = normal_speed < 0
    return outgoing * approaching + relative_velocity_m_s * ~approaching


def fly_to_table(
    position_m: np.ndarray, velocity_m_s: np.ndarray, dt_s: float = PHYSICS_DT_S, max_time_s: float = MAX_FLIGHT_S
) -> tuple[np.ndarray, np.ndarray, float, float]:
    """Integrate free flight until the ball's bottom reaches the table plane (or max_time_s).

    Returns (position at contact, velocity at contact, time of flight, lowest clearance over the net:
    height of the ball's bottom above the net's top when it crosses x = 0, +inf if it never does).
    Semi-implicit Euler at dt_s, interpolated linearly to the contact instant.
    """
    p = np.array(position_m, dtype=float)
    v = np.array(velocity_m_s, dtype=float)
    gravity = np.array([0.0, 0.0, -GRAVITY_M_S2])
    contact_z = TABLE_CONTACT_HEIGHT_M
    net_clearance = math.inf
    t = 0.0
    while t < max_time_s:
        v_new = v + (gravity + drag_acceleration(v)) * dt_s
        p_new = p + v_new * dt_s
        if (p[0] > 0.0) != (p_new[0] > 0.0):
            frac = p[0] / (p[0] - p_new[0])
            z_at_net = p[2] + frac * (p_new[2] - p[2])
            net_clearance = z_at_net - BALL_RADIUS_M - NET_TOP_HEIGHT_M
        if p_new[2] <= contact_z < p[2]:
            frac = (p[2] - contact_z) / (p[2] - p_new[2])
            return p + frac * (p_new - p), v + frac * (v_new - v), t + frac * dt_s, net_clearance
        p, v, t = p_new, v_new, t + dt_s
    return p, v, t, net_clearance


def _aim(start_m: np.ndarray, target_xy_m: np.ndarray, speed_m_s: float) -> np.ndarray | None:
    """Launch velocity of the given speed whose flight lands on target_xy (the flatter solution).

    The heading points at the target; the elevation is found by bisection on the landing distance,
    which grows with elevation up to the maximum-range angle.
    """
    horizontal = target_xy_m - start_m[:2]
    distance = float(np.linalg.norm(horizontal))
    heading = horizontal / distance

    def velocity(elevation_rad: float) -> np.ndarray:
        return speed_m_s * np.array(
            [math.cos(elevation_rad) * heading[0], math.cos(elevation_rad) * heading[1], math.sin(elevation_rad)]
        )

    def landing_distance(elevation_rad: float) -> float:
        landing, _, _, _ = fly_to_table(start_m, velocity(elevation_rad), dt_s=0.002)
        return float(np.dot(landing[:2] - start_m[:2], heading))

    low, high = AIM_ELEVATION_RANGE_RAD
    if landing_distance(low) > distance or landing_distance(high) < distance:
        return None
    for _ in range(30):
        mid = 0.5 * (low + high)
        if landing_distance(mid) < distance:
            low = mid
        else:
            high = mid
    return velocity(0.5 * (low + high))


def rebound_reaches(
    contact_position_m: np.ndarray,
    contact_velocity_m_s: np.ndarray,
    distribution: IncomingBallDistribution = INCOMING,
    dt_s: float = 0.004,
) -> bool:
    """Does the ball, bouncing off the table here, pass through the paddle's reachable region?"""
    up = np.array([0.0, 0.0, 1.0])
    v = contact_response(np.asarray(contact_velocity_m_s, float), up, TABLE_RESTITUTION, TABLE_TANGENTIAL_FACTOR)
    p = np.array(contact_position_m, dtype=float)
    centre = np.array(distribution.reach_centre_m)
    gravity = np.array([0.0, 0.0, -GRAVITY_M_S2])
    for _ in range(int(REBOUND_HORIZON_S / dt_s)):
        v = v + (gravity + drag_acceleration(v)) * dt_s
        p = p + v * dt_s
        if p[2] < TABLE_CONTACT_HEIGHT_M:  # fell back to table level: out of play or a 2nd bounce
            return False
        if p[2] >= distribution.min_hit_height_m and np.sum((p - centre) ** 2) <= distribution.reach_radius_m**2:
            return True
    return False


def sample_incoming_ball(
    rng: np.random.Generator,
    speed_range_m_s: tuple[float, float] | None = None,
    distribution: IncomingBallDistribution = INCOMING,
) -> BallLaunch:
    """Draw one incoming ball. Reproducible: the same generator state gives the same ball."""
    speed_lo, speed_hi = speed_range_m_s or distribution.speed_m_s
    for _ in range(distribution.max_draws):
        start = np.array(
            [
                rng.uniform(*distribution.launch_x_m),
                rng.uniform(*distribution.launch_y_m),
                rng.uniform(*distribution.launch_z_m),
            ]
        )
        bounce = np.array([rng.uniform(*distribution.bounce_x_m), rng.uniform(*distribution.bounce_y_m)])
        speed = rng.uniform(speed_lo, speed_hi)
        velocity = _aim(start, bounce, speed)
        if velocity is None:
            continue
        contact_p, contact_v, _, clearance = fly_to_table(start, velocity)
        if clearance >= distribution.net_clearance_m and rebound_reaches(contact_p, contact_v, distribution):
            return BallLaunch(position_m=start, velocity_m_s=velocity, bounce_point_m=bounce)
    raise RuntimeError(f'no incoming ball found for speeds {speed_lo}-{speed_hi} m/s; check the distribution')


def incoming_ball_for_seed(
    seed: int, speed_range_m_s: tuple[float, float] | None = None, distribution: IncomingBallDistribution = INCOMING
) -> BallLaunch:
    """The incoming ball that `seed` names: what `/sim/launch_ball` with randomize=true launches.

    speed_range_m_s None or (0, 0) means the distribution's default range.
    """
    if speed_range_m_s is not None and speed_range_m_s[0] == 0.0 and speed_range_m_s[1] == 0.0:
        speed_range_m_s = None
    return sample_incoming_ball(np.random.default_rng(seed), speed_range_m_s, distribution)
