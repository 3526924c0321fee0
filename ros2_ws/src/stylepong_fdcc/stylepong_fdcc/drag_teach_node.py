"""`ros2 run stylepong_fdcc drag_teach`: drag the arm by its force/torque sensor (FDCC, see fdcc_solver.py).

Subscribes  /joint_states (sensor_msgs/JointState), /force_torque_sensor_broadcaster/wrench
            (geometry_msgs/WrenchStamped: the wrench the environment applies on the tool, frame tool0),
            ~/target_pose (geometry_msgs/PoseStamped in base_link; used when stiffness > 0)
Publishes   /forward_position_controller/commands (std_msgs/Float64MultiArray: 6 joint positions, URDF order)
Services    /drag_teach/tare (std_srvs/Trigger), /drag_teach/enable (std_srvs/SetBool)
Parameters  PARAMETERS below, defaults in config/drag_teach.yaml (read at start-up). A bad one stops the
            node with one line on stderr and exit code 2 (stylepong_common.node_support).

The control cycle runs at 500 Hz beside two 500 Hz subscriptions on a Python process, so the work around
the controller is kept small (benchmarks/40_drag_teach.py): joint states and wrenches are read from their
serialized bytes (`sensor_messages`), the clock is read without building a Time object, and the command
message is built once and refilled.
"""

from __future__ import annotations

import array
import gc
import math
import sys
import time
from typing import Any

import numpy as np
from geometry_msgs.msg import PoseStamped, WrenchStamped
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from std_srvs.srv import SetBool, Trigger

from stylepong_common.node_support import Param, ParameterError, ThrottledLog, declare_parameters, run_node
from stylepong_description import robot_model
from stylepong_fdcc.cycle_statistics import CycleStatistics
from stylepong_fdcc.drag_teach_controller import DragTeachController
from stylepong_fdcc.fdcc_config import DYNAMICS_MODELS, FdccConfig
from stylepong_fdcc.sensor_messages import JointStateReader, wrench_from_cdr

PROGRAM = 'drag_teach'
BASE_FRAMES = ('', robot_model.BASE_FRAME, 'base')
CONTROL_RATE_RANGE_HZ = (10.0, 2000.0)

# Defaults come from FdccConfig, so the YAML file and the code agree. Bounds here are what a parameter
# alone must satisfy; FdccConfig.validate checks the rest (strictly positive values, clamp below rejection).
_DEFAULTS = FdccConfig()


def _setting(
    name: str,
    description: str,
    low: float | None = None,
    high: float | None = None,
    length: int | None = None,
    choices: tuple[str, ...] = (),
) -> Param:
    """The parameter that sets FdccConfig's field `name`, with the field's default (a vector as a list)."""
    default = getattr(_DEFAULTS, name)
    return Param(
        name,
        list(default) if isinstance(default, tuple) else default,
        description,
        low=low,
        high=high,
        length=length,
        choices=choices,
    )


PARAMETERS = (
    Param(
        'control_rate_hz',
        500.0,
        'control cycle rate; commands are published at this rate',
        low=CONTROL_RATE_RANGE_HZ[0],
        high=CONTROL_RATE_RANGE_HZ[1],
    ),
    Param('start_enabled', True, 'publish commands from start-up (else wait for /drag_teach/enable)'),
    Param('tare_on_enable', True, 'take the sensor bias when control is enabled (and at start-up)'),
    _setting('damping', 'K_D: x, y, z in N s/m, rx, ry, rz in N m s/rad (base_link axes)', low=0.0, length=6),
    _setting('stiffness', 'K_P: x, y, z in N/m, rx, ry, rz in N m/rad; 0 = free dragging', low=0.0, length=6),
    _setting('joint_damping_nms_per_rad', 'joint-space damping, N m s/rad', low=0.0),
    _setting(
        'dynamics_model', "'virtual' (light FZI-style links) or 'urdf' (the URDF's inertias)", choices=DYNAMICS_MODELS
    ),
    _setting('virtual_link_mass_kg', 'virtual model: mass of each link but the last', low=0.0),
    _setting('virtual_link_inertia_kg_m2', 'virtual model: their rotational inertia', low=0.0),
    _setting('virtual_end_mass_kg', 'virtual model: mass of the last link', low=0.0),
    _setting('virtual_end_inertia_kg_m2', 'virtual model: its rotational inertia', low=0.0),
    _setting('max_late_periods', 'a longer gap between cycles (a stall) is integrated as this many periods', low=1.0),
    _setting('gravity_compensation', "remove the paddle's weight from the sensor wrench"),
    _setting('lowpass_cutoff_hz', 'first-order low-pass on the wrench', low=0.0),
    _setting('force_deadband_n', 'force magnitudes below this are ignored', low=0.0),
    _setting('torque_deadband_nm', 'torque magnitudes below this are ignored', low=0.0),
    _setting('max_force_n', 'force magnitude clamp', low=0.0),
    _setting('max_torque_nm', 'torque magnitude clamp', low=0.0),
    _setting('reject_force_n', 'wrenches with a larger force are rejected as sensor faults', low=0.0),
    _setting('reject_torque_nm', 'wrenches with a larger torque are rejected as sensor faults', low=0.0),
    _setting('tare_window_s', 'the bias is the mean reading over this window', low=0.0),
    _setting('position_margin_rad', 'joints stay this far inside the URDF position limits', low=0.0),
    _setting('velocity_limit_scale', "fraction of the URDF's joint velocity limits", low=0.0, high=1.0),
    _setting('acceleration_limit_rad_s2', 'joint acceleration limits, rad/s^2', low=0.0, length=6),
    _setting('watchdog_timeout_s', 'no fresh wrench or joint state for this long: decelerate and hold', low=0.0),
    _setting('resume_ramp_s', 'after a hold, the wrench fades back in over this time', low=0.0),
)

STATE_MESSAGES = {
    'waiting': 'waiting for joint states and wrenches (and a tare window) before publishing',
    'running': 'running: following the sensor wrench',
    'holding': 'holding: no fresh wrench or joint state, decelerating to rest',
    'disabled': 'disabled',
}


def fdcc_config(values: dict[str, Any]) -> FdccConfig:
    """The solver's settings from the checked parameter values; ParameterError names a bad combination."""
    fields = set(FdccConfig.__dataclass_fields__)
    config = FdccConfig(
        nominal_period_s=1.0 / values['control_rate_hz'],
        **{k: tuple(v) if isinstance(v, list) else v for k, v in values.items() if k in fields},
    )
    try:
        config.validate()
    except ValueError as error:
        raise ParameterError(str(error)) from None
    return config


def quaternion_to_rotation(x: float, y: float, z: float, w: float) -> np.ndarray | None:
    """Rotation matrix of a quaternion (normalised here); None if it is not finite or near zero."""
    q = np.array([w, x, y, z], dtype=float)
    norm = float(np.linalg.norm(q))
    if not math.isfinite(norm) or norm < 1e-6:
        return None
    w, x, y, z = q / norm
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def float64_array(values: np.ndarray) -> array.array:
    """`values` as the array.array('d') a float64[] message field stores: assigned as such, rclpy's setter
    skips its per-element type and range checks (a float64 array has passed them by construction)."""
    out = array.array('d')
    out.frombytes(np.ascontiguousarray(values, dtype=np.float64).tobytes())
    return out


class DragTeachNode(Node):
    """The drag_teach node: FDCC on the wrench and joint-state topics, joint position commands out."""

    def __init__(self, **kwargs):
        super().__init__(PROGRAM, **kwargs)
        values = declare_parameters(self, PARAMETERS)
        config = fdcc_config(values)
        self.controller = DragTeachController(
            config, enabled=values['start_enabled'], tare_on_enable=values['tare_on_enable']
        )
        self.stats = CycleStatistics(config.nominal_period_s)
        self.warnings = ThrottledLog(self.get_logger())
        self._joint_reader = JointStateReader(robot_model.JOINT_NAMES)
        self._clock_handle = self.get_clock().handle
        self._state = ''
        self._command_msg = Float64MultiArray()

        self.command_pub = self.create_publisher(Float64MultiArray, '/forward_position_controller/commands', 10)
        # raw: the callbacks read the few numbers they need from the bytes (sensor_messages).
        self.create_subscription(JointState, '/joint_states', self._on_joint_state, qos_profile_sensor_data, raw=True)
        self.create_subscription(
            WrenchStamped, '/force_torque_sensor_broadcaster/wrench', self._on_wrench, qos_profile_sensor_data, raw=True
        )
        self.create_subscription(PoseStamped, '~/target_pose', self._on_target_pose, 10)
        self.create_service(Trigger, '/drag_teach/tare', self._on_tare)
        self.create_service(SetBool, '/drag_teach/enable', self._on_enable)
        self.create_timer(config.nominal_period_s, self._on_tick)
        self.get_logger().info(
            f'FDCC at {values["control_rate_hz"]:g} Hz, {config.dynamics_model} model, damping {list(config.damping)}, '
            f'stiffness {list(config.stiffness)}; {"enabled" if values["start_enabled"] else "disabled"}'
        )
        # Everything built so far lives as long as the node: taking it out of the collector's full passes
        # keeps those passes (tens of milliseconds over rclpy, numpy and Pinocchio) out of the control cycle.
        gc.collect()
        gc.freeze()

    def _now_s(self) -> float:
        """The node's clock (ROS time under use_sim_time) in seconds, without building an rclpy Time."""
        handle = self._clock_handle
        with handle:
            return handle.get_now().nanoseconds * 1e-9

    # --- inputs ---
    def _on_joint_state(self, raw: bytes) -> None:
        positions, _, _ = self._joint_reader.positions(raw)
        if positions is None:
            self.warnings.warn(
                'joint names',
                f'joint state rejected: it must name every joint of {robot_model.JOINT_NAMES} with a position',
            )
            return
        fault = self.controller.on_joint_positions(positions, self._now_s())
        if fault:
            self.warnings.warn('joint values', f'joint state rejected: {fault}')

    def _on_wrench(self, raw: bytes) -> None:
        fault = self.controller.on_wrench(wrench_from_cdr(raw), self._now_s())
        if fault:
            self.warnings.warn(
                'wrench', lambda: f'wrench rejected ({self.controller.rejected_wrenches} so far): {fault}'
            )

    def _on_target_pose(self, msg: PoseStamped) -> None:
        if msg.header.frame_id not in BASE_FRAMES:
            self.warnings.warn(
                'target frame',
                f'target pose rejected: frame {msg.header.frame_id!r}, expected {robot_model.BASE_FRAME!r}',
            )
            return
        p, o = msg.pose.position, msg.pose.orientation
        rotation = quaternion_to_rotation(o.x, o.y, o.z, o.w)
        position = np.array([p.x, p.y, p.z])
        if rotation is None or not np.all(np.isfinite(position)):
            self.warnings.warn('target values', 'target pose rejected: non-finite position or orientation')
            return
        self.controller.set_target(position, rotation)

    # --- services ---
    def _on_tare(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        try:
            bias = self.controller.tare(self._now_s())
        except RuntimeError as error:
            response.success, response.message = False, str(error)
        else:
            response.success = True
            response.message = (
                f'bias force {np.round(bias[:3], 3).tolist()} N, torque {np.round(bias[3:], 4).tolist()} N m (tool0)'
            )
            self.get_logger().info(f'tared: {response.message}')
        return response

    def _on_enable(self, request: SetBool.Request, response: SetBool.Response) -> SetBool.Response:
        self.controller.set_enabled(bool(request.data))
        response.success = True
        response.message = (
            'enabled: synchronising with the measured joints' if request.data else 'disabled: no commands are published'
        )
        self.get_logger().info(response.message)
        return response

    # --- the control cycle ---
    def _on_tick(self) -> None:
        now_s = self._now_s()
        started_s = time.perf_counter()
        result = self.controller.tick(now_s)
        if result.command is not None:
            self._command_msg.data = float64_array(result.command)
            self.command_pub.publish(self._command_msg)
        self.stats.record(now_s, time.perf_counter() - started_s)
        if result.state != self._state:
            # Throttled per state: a flaky sensor toggles between running and holding many times a second.
            log = self.warnings.warn if result.state == 'holding' else self.warnings.info
            log(result.state, STATE_MESSAGES[result.state])
            self._state = result.state

    def log_statistics(self) -> None:
        s = self.stats.summary()
        if s.get('ticks', 0) < 2:
            return
        self.get_logger().info(
            f'{s["ticks"]} cycles in {s["duration_s"]:.1f} s: {s["rate_hz"]:.1f} Hz, {s["missed_ticks"]} missed, '
            f'compute mean {s["compute_mean_s"] * 1e6:.0f} us, p99 {s["compute_p99_s"] * 1e6:.0f} us; '
            f'{self.controller.rejected_wrenches} wrenches and {self.controller.rejected_joint_states} '
            'joint states rejected'
        )

    def close(self) -> None:
        """On the way out (stylepong_common.node_support.run_node): what the cycles achieved."""
        self.log_statistics()


def main(args: list[str] | None = None) -> int:
    """Entry point of the drag_teach executable."""
    return run_node(PROGRAM, DragTeachNode, args)


if __name__ == '__main__':
    sys.exit(main())
