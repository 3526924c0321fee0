"""`ros2 run stylepong_fdcc drag_teach`: drag the arm by its force/torque sensor (FDCC, see fdcc.py).

Subscribes  /joint_states (sensor_msgs/JointState), /force_torque_sensor_broadcaster/wrench
            (geometry_msgs/WrenchStamped: the wrench the environment applies on the tool, frame tool0),
            ~/target_pose (geometry_msgs/PoseStamped in base_link; used when stiffness > 0)
Publishes   /forward_position_controller/commands (std_msgs/Float64MultiArray: 6 joint positions, URDF order)
Services    /drag_teach/tare (std_srvs/Trigger), /drag_teach/enable (std_srvs/SetBool)
Parameters  config/drag_teach.yaml (read at start-up).
"""
from __future__ import annotations

import math
import sys
import time

import numpy as np
import rclpy
from geometry_msgs.msg import PoseStamped, WrenchStamped
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.executors import ExternalShutdownException
from rclpy.experimental import EventsExecutor
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from std_srvs.srv import SetBool, Trigger

from stylepong_description import robot_model as rm
from stylepong_fdcc.fdcc import CycleStatistics, DragTeachController, FdccConfig

BASE_FRAMES = ('', rm.BASE_FRAME, 'base')
WARN_THROTTLE_S = 1.0

# name: (default, description). Defaults come from FdccConfig, so the YAML file and the code agree.
_DEFAULTS = FdccConfig()
PARAMETERS = {
    'control_rate_hz': (500.0, 'control cycle rate; commands are published at this rate'),
    'start_enabled': (True, 'publish commands from start-up (else wait for /drag_teach/enable)'),
    'tare_on_enable': (True, 'take the sensor bias when control is enabled (and at start-up)'),
    'damping': (list(_DEFAULTS.damping), 'K_D: x, y, z in N s/m, rx, ry, rz in N m s/rad (base_link axes)'),
    'stiffness': (list(_DEFAULTS.stiffness), 'K_P: x, y, z in N/m, rx, ry, rz in N m/rad; 0 = free dragging'),
    'joint_damping_nms_per_rad': (_DEFAULTS.joint_damping_nms_per_rad, 'joint-space damping, N m s/rad'),
    'dynamics_model': (_DEFAULTS.dynamics_model, "'virtual' (light FZI-style links) or 'urdf' (the URDF's inertias)"),
    'virtual_link_mass_kg': (_DEFAULTS.virtual_link_mass_kg, 'virtual model: mass of each link but the last'),
    'virtual_link_inertia_kg_m2': (_DEFAULTS.virtual_link_inertia_kg_m2, 'virtual model: their rotational inertia'),
    'virtual_end_mass_kg': (_DEFAULTS.virtual_end_mass_kg, 'virtual model: mass of the last link'),
    'virtual_end_inertia_kg_m2': (_DEFAULTS.virtual_end_inertia_kg_m2, 'virtual model: its rotational inertia'),
    'max_late_periods': (_DEFAULTS.max_late_periods, 'a longer gap between cycles (a stall) is integrated as this many periods'),
    'gravity_compensation': (_DEFAULTS.gravity_compensation, "remove the paddle's weight from the sensor wrench"),
    'lowpass_cutoff_hz': (_DEFAULTS.lowpass_cutoff_hz, 'first-order low-pass on the wrench'),
    'force_deadband_n': (_DEFAULTS.force_deadband_n, 'force magnitudes below this are ignored'),
    'torque_deadband_nm': (_DEFAULTS.torque_deadband_nm, 'torque magnitudes below this are ignored'),
    'max_force_n': (_DEFAULTS.max_force_n, 'force magnitude clamp'),
    'max_torque_nm': (_DEFAULTS.max_torque_nm, 'torque magnitude clamp'),
    'reject_force_n': (_DEFAULTS.reject_force_n, 'wrenches with a larger force are rejected as sensor faults'),
    'reject_torque_nm': (_DEFAULTS.reject_torque_nm, 'wrenches with a larger torque are rejected as sensor faults'),
    'tare_window_s': (_DEFAULTS.tare_window_s, 'the bias is the mean reading over this window'),
    'position_margin_rad': (_DEFAULTS.position_margin_rad, 'joints stay this far inside the URDF position limits'),
    'velocity_limit_scale': (_DEFAULTS.velocity_limit_scale, "fraction of the URDF's joint velocity limits"),
    'acceleration_limit_rad_s2': (list(_DEFAULTS.acceleration_limit_rad_s2), 'joint acceleration limits, rad/s^2'),
    'watchdog_timeout_s': (_DEFAULTS.watchdog_timeout_s, 'no fresh wrench or joint state for this long: decelerate and hold'),
    'resume_ramp_s': (_DEFAULTS.resume_ramp_s, 'after a hold, the wrench fades back in over this time'),
}


def quaternion_to_rotation(x: float, y: float, z: float, w: float) -> np.ndarray | None:
    """Rotation matrix of a quaternion (normalised here); None if it is not finite or near zero."""
    q = np.array([w, x, y, z], dtype=float)
    norm = float(np.linalg.norm(q))
    if not math.isfinite(norm) or norm < 1e-6:
        return None
    w, x, y, z = q / norm
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def typed_parameter(name: str, value, default):
    """The parameter's value in its default's type (ints accepted for floats); ValueError otherwise."""
    def bad() -> ValueError:
        return ValueError(f'parameter {name} must be {type(default).__name__}'
                          f'{" of numbers" if isinstance(default, list) else ""}, got {value!r}')
    if isinstance(default, bool):
        if not isinstance(value, bool):
            raise bad()
        return value
    if isinstance(default, float):
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise bad()
        return float(value)
    if isinstance(default, list):
        if isinstance(value, (str, bytes)) or not hasattr(value, '__len__') or any(isinstance(v, bool) or not isinstance(v, (int, float))
                                                       for v in value):
            raise bad()
        return [float(v) for v in value]
    if not isinstance(value, type(default)):
        raise bad()
    return value


class DragTeachNode(Node):
    def __init__(self, **kwargs):
        super().__init__('drag_teach', **kwargs)
        for name, (default, description) in PARAMETERS.items():
            # dynamic typing: `-p control_rate_hz:=250` (an integer) must work as well as 250.0
            descriptor = ParameterDescriptor(description=description, read_only=True, dynamic_typing=True)
            self.declare_parameter(name, default, descriptor)
        value = {name: typed_parameter(name, self.get_parameter(name).value, default)
                 for name, (default, _) in PARAMETERS.items()}
        rate_hz = value['control_rate_hz']
        if not 10.0 <= rate_hz <= 2000.0:
            raise ValueError(f'control_rate_hz must be within 10-2000 Hz, got {rate_hz}')
        config_fields = set(FdccConfig.__dataclass_fields__)
        config = FdccConfig(nominal_period_s=1.0 / rate_hz,
                            **{k: tuple(v) if isinstance(v, list) else v for k, v in value.items() if k in config_fields})
        config.validate()  # a bad parameter stops the node here with a clear message
        self.controller = DragTeachController(config, enabled=bool(value['start_enabled']),
                                              tare_on_enable=bool(value['tare_on_enable']))
        self.stats = CycleStatistics(config.nominal_period_s)
        self._index_cache: tuple[tuple[str, ...], np.ndarray | None] = ((), None)
        self._state = ''
        self._last_warning: dict[str, float] = {}

        self.command_pub = self.create_publisher(Float64MultiArray, '/forward_position_controller/commands', 10)
        self.create_subscription(JointState, '/joint_states', self._on_joint_state, qos_profile_sensor_data)
        self.create_subscription(WrenchStamped, '/force_torque_sensor_broadcaster/wrench', self._on_wrench,
                                 qos_profile_sensor_data)
        self.create_subscription(PoseStamped, '~/target_pose', self._on_target_pose, 10)
        self.create_service(Trigger, '/drag_teach/tare', self._on_tare)
        self.create_service(SetBool, '/drag_teach/enable', self._on_enable)
        self.create_timer(config.nominal_period_s, self._on_tick)
        self.get_logger().info(
            f'FDCC at {rate_hz:g} Hz, {config.dynamics_model} model, damping {list(config.damping)}, '
            f'stiffness {list(config.stiffness)}; {"enabled" if value["start_enabled"] else "disabled"}')

    def _now_s(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def _warn(self, kind: str, text, info: bool = False) -> None:
        """A warning (or info) throttled per kind of event. `text` may be a callable: under a flood of
        bad messages the message is built, and the logger called, only once per WARN_THROTTLE_S."""
        now = time.monotonic()
        if now - self._last_warning.get(kind, -math.inf) < WARN_THROTTLE_S:
            return
        self._last_warning[kind] = now
        text = text() if callable(text) else text
        if info:   # rclpy ties a severity to its call site: one call per severity
            self.get_logger().info(text)
        else:
            self.get_logger().warn(text)

    # --- inputs ---
    def _joint_indices(self, names) -> np.ndarray | None:
        names = tuple(names)
        if names != self._index_cache[0]:
            try:
                indices = np.array([names.index(n) for n in rm.JOINT_NAMES])
            except ValueError:
                indices = None
            self._index_cache = (names, indices)
        return self._index_cache[1]

    def _on_joint_state(self, msg: JointState) -> None:
        indices = self._joint_indices(msg.name)
        if indices is None or len(msg.position) != len(msg.name):
            self._warn('joint names', f'joint state rejected: it must name every joint of {rm.JOINT_NAMES} with a position')
            return
        fault = self.controller.on_joint_positions(np.asarray(msg.position, dtype=float)[indices], self._now_s())
        if fault:
            self._warn('joint values', f'joint state rejected: {fault}')

    def _on_wrench(self, msg: WrenchStamped) -> None:
        f, t = msg.wrench.force, msg.wrench.torque
        fault = self.controller.on_wrench(np.array([f.x, f.y, f.z, t.x, t.y, t.z]), self._now_s())
        if fault:
            self._warn('wrench', lambda: f'wrench rejected ({self.controller.rejected_wrenches} so far): {fault}')

    def _on_target_pose(self, msg: PoseStamped) -> None:
        if msg.header.frame_id not in BASE_FRAMES:
            self._warn('target frame', f'target pose rejected: frame {msg.header.frame_id!r}, expected {rm.BASE_FRAME!r}')
            return
        p, o = msg.pose.position, msg.pose.orientation
        rotation = quaternion_to_rotation(o.x, o.y, o.z, o.w)
        position = np.array([p.x, p.y, p.z])
        if rotation is None or not np.all(np.isfinite(position)):
            self._warn('target values', 'target pose rejected: non-finite position or orientation')
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
            response.message = (f'bias force {np.round(bias[:3], 3).tolist()} N, '
                                f'torque {np.round(bias[3:], 4).tolist()} N m (tool0)')
            self.get_logger().info(f'tared: {response.message}')
        return response

    def _on_enable(self, request: SetBool.Request, response: SetBool.Response) -> SetBool.Response:
        self.controller.set_enabled(bool(request.data))
        response.success = True
        response.message = 'enabled: synchronising with the measured joints' if request.data else \
            'disabled: no commands are published'
        self.get_logger().info(response.message)
        return response

    # --- the control cycle ---
    def _on_tick(self) -> None:
        now_s = self._now_s()
        started = time.perf_counter()
        result = self.controller.tick(now_s)
        if result.command is not None:
            self.command_pub.publish(Float64MultiArray(data=result.command.tolist()))
        self.stats.record(now_s, time.perf_counter() - started)
        if result.state != self._state:
            reasons = {'waiting': 'waiting for joint states and wrenches (and a tare window) before publishing',
                       'running': 'running: following the sensor wrench',
                       'holding': 'holding: no fresh wrench or joint state, decelerating to rest',
                       'disabled': 'disabled'}
            # Throttled per state: a flaky sensor toggles between running and holding many times a second.
            self._warn(result.state, reasons[result.state], info=result.state != 'holding')
            self._state = result.state

    def log_statistics(self) -> None:
        s = self.stats.summary()
        if s.get('ticks', 0) < 2:
            return
        self.get_logger().info(
            f'{s["ticks"]} cycles in {s["duration_s"]:.1f} s: {s["rate_hz"]:.1f} Hz, {s["missed_ticks"]} missed, '
            f'compute mean {s["compute_mean_s"] * 1e6:.0f} us, p99 {s["compute_p99_s"] * 1e6:.0f} us; '
            f'{self.controller.rejected_wrenches} wrenches and {self.controller.rejected_joint_states} joint states rejected')


def main(args=None) -> int:
    rclpy.init(args=args)
    try:
        node = DragTeachNode()
    except (ValueError, RuntimeError) as error:
        print(f'drag_teach: {error}', file=sys.stderr)
        rclpy.try_shutdown()
        return 1
    try:
        # The events executor: the standard one spends three quarters of this node's CPU time deciding
        # what to run next (1500 callbacks/s). Its spin() would not return to Python for Ctrl-C, hence
        # spin_once in a loop.
        executor = EventsExecutor()
        executor.add_node(node)
        while rclpy.ok():
            executor.spin_once(timeout_sec=0.1)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.log_statistics()
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
