"""How a joint position command becomes the joint drives' reference: the cells' actuator models, free of ROS.

Both cells (MuJoCo `cell.Cell`, PyBullet `bullet_cell.BulletCell`) turn the latest command on
/forward_position_controller/commands into a reference (position q_ref, velocity v_ref) every physics
step dt; each cell's own joint drive then tracks that reference within the URDF's torque limits (MuJoCo:
world_spec's PD servo; Bullet: its joint motor). Two laws:

`ideal` (IdealReference), world_spec's servo reference, what training assumes:
    q_ref <- q_ref + clip(q_cmd - q_ref, +-v_max dt),  v_ref = (change of q_ref) / dt     (v_max: URDF)

`ur_servoj` (ServojReference), an emulation of a UR behind ur_robot_driver's forward_position_controller,
which hands every command to URScript servoj:
    1. sampling: the controller reads the latest command at its own rate only (servo_rate_hz: 125 Hz on a
       CB3 UR5, 500 Hz on an e-Series); q_s is held between its ticks (commands in between are lost);
    2. look-ahead: servoj "smoothens the trajectory with this lookahead time": a first-order filter of
       time constant lookahead_s on the sampled target, q_f' = (q_s - q_f) / lookahead_s;
    3. gain: servoj's "proportional gain for following target position": the setpoint follows q_f at
       rate gain (read as 1/s), q_sp' = gain (q_f - q_sp), discretised exactly (stable at any gain);
    4. speed limit: |q_sp'| <= 180 deg/s on every joint (ur_description joint_limits.yaml);
    then q_ref = q_sp, v_ref = q_sp' for the cell's joint drive, whose torques stay within the URDF efforts
    (150 N m base/shoulder/elbow, 28 N m wrists: the UR5's rated torques).
  Where the constants come from: servo_rate_hz, lookahead_s (0.03-0.2 s, default 0.03) and gain (100-2000
  in URScript, the driver's default 2000; 3000 accepted as the driver's xacro allows) are the controller's
  and the driver's documented settings and ranges; 180 deg/s is the UR's published joint speed limit.
  What is guessed: the structure (a first-order look-ahead filter, a first-order gain loop: UR does not
  publish servoj's law) and reading gain in 1/s. Its delay on a ramp is about half a tick + lookahead_s +
  1/gain: 4 + 30 + 0.5 = 34.5 ms at 125 Hz and the driver's defaults, close to the 34 ms tracking delay
  measured with servoj (look-ahead 0.03 s) on a UR10e (Universal_Robots_Client_Library's issue tracker).
  No acceleration limit: UR publishes none (the torque limits bound it).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

IDEAL = 'ideal'
UR_SERVOJ = 'ur_servoj'
ACTUATORS = (IDEAL, UR_SERVOJ)
UR_JOINT_SPEED_LIMIT_RAD_S = math.radians(180.0)
SERVO_RATE_RANGE_HZ = (10.0, 1000.0)
LOOKAHEAD_RANGE_S = (0.03, 0.2)  # URScript servoj
GAIN_RANGE = (100.0, 3000.0)  # URScript says 100-2000; the driver's xacro accepts up to 3000
# Each ServojSettings field's allowed (low, high).
SETTING_RANGES = {'servo_rate_hz': SERVO_RATE_RANGE_HZ, 'lookahead_s': LOOKAHEAD_RANGE_S, 'gain': GAIN_RANGE}


@dataclass(frozen=True)
class ServojSettings:
    """servoj's settings: controller rate, look-ahead time and gain (ur_robot_driver's defaults)."""

    servo_rate_hz: float = 125.0
    lookahead_s: float = 0.03
    gain: float = 2000.0

    def __post_init__(self):
        for name, (low, high) in SETTING_RANGES.items():
            value = getattr(self, name)
            if not (math.isfinite(value) and low <= value <= high):
                raise ValueError(f'{name} must be within [{low}, {high}], got {value}')


class IdealReference:
    """world_spec's servo reference: towards the command at no more than the URDF velocity limit."""

    def __init__(self, home_rad: np.ndarray, max_speed_rad_s: np.ndarray):
        self._max_speed = np.asarray(max_speed_rad_s, dtype=float)
        self.reset(home_rad)

    def reset(self, q_rad: np.ndarray, time_s: float = 0.0) -> None:
        del time_s  # no clock of its own
        self.q_ref = np.array(q_rad, dtype=float)
        self.v_ref = np.zeros_like(self.q_ref)
        self._q_cmd = self.q_ref.copy()

    def command(self, q_cmd_rad: np.ndarray) -> None:
        self._q_cmd = np.array(q_cmd_rad, dtype=float)

    def step(self, time_s: float, dt_s: float) -> tuple[np.ndarray, np.ndarray]:
        """The reference after the step that ends at time_s."""
        del time_s  # the ideal servo reads every command at once
        limit = self._max_speed * dt_s
        move = np.clip(self._q_cmd - self.q_ref, -limit, limit)
        self.q_ref = self.q_ref + move
        self.v_ref = move / dt_s
        return self.q_ref, self.v_ref


class ServojReference:
    """The UR controller's servoj, as the module docstring states: sampled, looked ahead, gained, speed-limited."""

    def __init__(
        self,
        home_rad: np.ndarray,
        settings: ServojSettings = ServojSettings(),
        max_speed_rad_s: float = UR_JOINT_SPEED_LIMIT_RAD_S,
    ):
        self.settings = settings
        self._period_s = 1.0 / settings.servo_rate_hz
        self._max_speed = max_speed_rad_s
        self.reset(home_rad)

    def reset(self, q_rad: np.ndarray, time_s: float = 0.0) -> None:
        q = np.array(q_rad, dtype=float)
        self._q_cmd = q.copy()
        self._q_sampled = q.copy()
        self._q_filtered = q.copy()
        self.q_ref = q.copy()
        self.v_ref = np.zeros_like(q)
        self._next_tick = math.ceil(time_s / self._period_s - 1e-9)

    def command(self, q_cmd_rad: np.ndarray) -> None:
        self._q_cmd = np.array(q_cmd_rad, dtype=float)

    def step(self, time_s: float, dt_s: float) -> tuple[np.ndarray, np.ndarray]:
        """The setpoint after the step that ends at time_s (the controller ticks at k / servo_rate_hz)."""
        if time_s + 1e-9 >= self._next_tick * self._period_s:
            self._q_sampled = self._q_cmd
            self._next_tick = math.floor(time_s / self._period_s + 1e-9) + 1
        s = self.settings
        self._q_filtered = self._q_filtered + (1.0 - math.exp(-dt_s / s.lookahead_s)) * (
            self._q_sampled - self._q_filtered
        )
        limit = self._max_speed * dt_s
        move = np.clip((1.0 - math.exp(-s.gain * dt_s)) * (self._q_filtered - self.q_ref), -limit, limit)
        self.q_ref = self.q_ref + move
        self.v_ref = move / dt_s
        return self.q_ref, self.v_ref


def make_reference(
    actuator: str, home_rad: np.ndarray, urdf_max_speed_rad_s: np.ndarray, servoj: ServojSettings = ServojSettings()
) -> IdealReference | ServojReference:
    """The actuator model named `actuator` (one of ACTUATORS), at rest at home_rad."""
    if actuator == IDEAL:
        return IdealReference(home_rad, urdf_max_speed_rad_s)
    if actuator == UR_SERVOJ:
        return ServojReference(home_rad, servoj)
    raise ValueError(f'actuator must be one of {", ".join(ACTUATORS)}, got {actuator!r}')
