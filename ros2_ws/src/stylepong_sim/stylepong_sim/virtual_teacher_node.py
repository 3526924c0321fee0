"""`ros2 run stylepong_sim virtual_teacher --ros-args -p swing:=forward`: a person dragging one stroke.

Pushes the simulated paddle through /sim/hand_wrench (geometry_msgs/WrenchStamped, world axes, the
torque about the gripped point `grip_frame`) so that drag_teach moves the arm along a table-tennis
stroke (teacher.py), and brackets the stroke with /recorder/start (stylepong_msgs/StartClip, label =
the swing) and /recorder/stop (std_srvs/Trigger). Steps: wait for joint states (and for someone
commanding the arm, i.e. drag_teach), bring the paddle to the ready pose, start the recorder, play the
stroke, stop the recorder, let go, exit (exit code 0 when a clip was recorded). Each take varies like a
person's (teacher.sample_variation): `seed` picks the take (the same seed, the same stroke), `variation`
scales how far it departs from the nominal stroke (0: the nominal stroke). Defaults:
config/virtual_teacher.yaml.
Subscribes /joint_states, /forward_position_controller/commands (only to see that the arm is driven).
"""
from __future__ import annotations

import signal
import sys

import numpy as np
import rclpy
from geometry_msgs.msg import WrenchStamped
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.experimental import EventsExecutor
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data
from rclpy.signals import SignalHandlerOptions
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from std_srvs.srv import Trigger

from stylepong_description import robot_model as rm
from stylepong_msgs.srv import StartClip
from stylepong_sim.teacher import SWINGS, TeacherConfig, VirtualTeacher, sample_variation

_DEFAULTS = TeacherConfig()
PARAMETERS = {
    'swing': ('forward', f'the stroke to teach: {", ".join(SWINGS)}'),
    'label': ('', 'clip label sent to /recorder/start (empty: the swing)'),
    'seed': (0, 'which take of the stroke (non-negative; the same seed gives the same take)'),
    'variation': (1.0, 'how far the take departs from the nominal stroke, 0-1 of teacher.VARIATION_RANGES '
                       '(0: nominal)'),
    'rate_hz': (500.0, 'rate of the hand wrench'),
    'use_recorder': (True, 'bracket the stroke with /recorder/start and /recorder/stop'),
    'wait_timeout_s': (30.0, 'give up when joint states, drag_teach or the recorder are not there by then'),
    'wait_for_commands': (True, 'push only once someone (drag_teach) commands the arm'),
    'exit_when_done': (True, 'exit after the stroke (else stay, hand released, until Ctrl-C)'),
    'grip_frame': (rm.TOOL_FRAME, 'robot frame whose origin the simulator applies /sim/hand_wrench at'),
    'wrench_frame_id': ('world', 'header frame of the hand wrench (its axes)'),
    'joint_state_timeout_s': (0.1, 'older joint states: the hand lets go until fresh ones arrive'),
    'lead_in_s': (_DEFAULTS.lead_in_s, 'recorded at rest at the ready pose before the back-swing'),
    'backswing_s': (_DEFAULTS.backswing_s, 'duration of the back-swing'),
    'forward_swing_s': (_DEFAULTS.forward_swing_s, 'back-swing to follow-through, through the hitting point'),
    'end_hold_s': (_DEFAULTS.end_hold_s, 'recorded at rest after the follow-through'),
    'hand_stiffness_n_per_m': (_DEFAULTS.hand_stiffness_n_per_m, "the hand's grip stiffness"),
    'expected_damping_ns_per_m': (_DEFAULTS.expected_damping_ns_per_m, 'how heavy the person expects the arm to feel'),
    'max_force_n': (_DEFAULTS.max_force_n, 'the hardest the hand pushes'),
}


class VirtualTeacherNode(Node):
    """The virtual teacher: pushes the paddle through one stroke on /sim/hand_wrench, recording it as a clip."""
    def __init__(self, **kwargs):
        super().__init__('virtual_teacher', **kwargs)
        for name, (default, description) in PARAMETERS.items():
            self.declare_parameter(name, default, ParameterDescriptor(description=description, read_only=True,
                                                                       dynamic_typing=True))
        p = {name: self.get_parameter(name).value for name in PARAMETERS}
        for name, (default, _) in PARAMETERS.items():
            if isinstance(default, float) and isinstance(p[name], int) and not isinstance(p[name], bool):
                p[name] = float(p[name])
            if type(p[name]) is not type(default):
                raise ValueError(f'parameter {name} must be {type(default).__name__}, got {p[name]!r}')
        if p['swing'] not in SWINGS:
            raise ValueError(f'swing must be one of {SWINGS}, got {p["swing"]!r}')
        if not 10.0 <= p['rate_hz'] <= 2000.0:
            raise ValueError(f'rate_hz must be within 10-2000, got {p["rate_hz"]}')
        if p['seed'] < 0:
            raise ValueError(f'seed must be non-negative, got {p["seed"]}')
        if not 0.0 <= p['variation'] <= 1.0:
            raise ValueError(f'variation must be within 0-1, got {p["variation"]}')
        config = TeacherConfig(**{k: p[k] for k in TeacherConfig.__dataclass_fields__ if k in p})
        variation = sample_variation(p['swing'], p['seed'], p['variation'])
        self.teacher = VirtualTeacher(p['swing'], config, grip_frame=p['grip_frame'], variation=variation)
        self.p = p
        self.label = p['label'] or p['swing']
        self.exit_code: int | None = None   # set when the node is done
        self._q: np.ndarray | None = None
        self._qdot = np.zeros(rm.NUM_JOINTS)
        self._joint_time_s: float | None = None
        self._commanded = not p['wait_for_commands']
        self._started_s = self._now_s()
        self._bracket = 'idle'              # idle -> starting -> recording -> stopping -> done
        self._announced = ''

        self.wrench_pub = self.create_publisher(WrenchStamped, '/sim/hand_wrench', 10)
        # Reused at every tick (publishing copies it): filling fields is cheaper than a new message.
        self._wrench_msg = WrenchStamped()
        self._wrench_msg.header.frame_id = p['wrench_frame_id']
        self.create_subscription(JointState, '/joint_states', self._on_joint_state, qos_profile_sensor_data)
        self._command_sub = None if self._commanded else self.create_subscription(
            Float64MultiArray, '/forward_position_controller/commands', self._on_command, 10)
        self.start_client = self.create_client(StartClip, '/recorder/start')
        self.stop_client = self.create_client(Trigger, '/recorder/stop')
        self.create_timer(1.0 / p['rate_hz'], self._on_tick)
        path = self.teacher.path
        self.get_logger().info(f'teaching a {p["swing"]} stroke '
                               f'({path.stroke_s:.2f} s, a {path.duration_s:.2f} s clip), '
                               f'label {self.label!r}, seed {p["seed"]}, variation {p["variation"]}: '
                               f'amplitude x{variation.amplitude_scale:.3f}, hit at {variation.hit_fraction:.3f} '
                               f'of the forward swing')

    def _now_s(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def _say(self, text: str) -> None:
        if text != self._announced:
            self.get_logger().info(text)
            self._announced = text

    # --- inputs ---
    def _on_joint_state(self, msg: JointState) -> None:
        names = list(msg.name)   # once per message, not once per joint (500 messages a second)
        try:
            index = [names.index(n) for n in rm.JOINT_NAMES]
            q = np.array([msg.position[i] for i in index], dtype=float)
            qdot = np.array([msg.velocity[i] for i in index], dtype=float) if len(msg.velocity) == len(msg.name) \
                else np.zeros(rm.NUM_JOINTS)
        except (ValueError, IndexError):
            self.get_logger().warn('joint state without all UR5 joints ignored', throttle_duration_sec=1.0)
            return
        if not (np.all(np.isfinite(q)) and np.all(np.isfinite(qdot))):
            self.get_logger().warn('non-finite joint state ignored', throttle_duration_sec=1.0)
            return
        self._q, self._qdot, self._joint_time_s = q, qdot, self._now_s()

    def _on_command(self, msg: Float64MultiArray) -> None:
        self._commanded = True
        if self._command_sub is not None:   # seen once is enough: stop taking 500 messages a second
            self.destroy_subscription(self._command_sub)
            self._command_sub = None

    # --- output ---
    def _publish(self, wrench: np.ndarray) -> None:
        msg = self._wrench_msg
        msg.header.stamp = self.get_clock().now().to_msg()
        f, t = msg.wrench.force, msg.wrench.torque
        f.x, f.y, f.z, t.x, t.y, t.z = (float(v) for v in wrench)
        self.wrench_pub.publish(msg)

    def release_hand(self) -> None:
        """Let go: publish a zero wrench (the simulator keeps the last one it got)."""
        self.teacher.release()
        self._publish(np.zeros(6))

    def _finish(self, code: int, text: str) -> None:
        if code == 0:   # rclpy ties a severity to its call site: one call per severity
            self.get_logger().info(text)
        else:
            self.get_logger().error(text)
        self.release_hand()
        if self.p['exit_when_done'] or code != 0:
            self.exit_code = code

    # --- the cycle ---
    def _on_tick(self) -> None:
        now = self._now_s()
        if self.exit_code is not None or self.teacher.phase == 'released':
            self._publish(np.zeros(6))
            return
        fresh = self._joint_time_s is not None and now - self._joint_time_s <= self.p['joint_state_timeout_s']
        if not (fresh and self._commanded):
            self._publish(np.zeros(6))
            what = 'joint states' if not fresh else 'drag_teach commanding the arm'
            self._say(f'waiting for {what}')
            if now - self._started_s > self.p['wait_timeout_s'] and self.teacher.phase == 'approach':
                self._finish(2, f'no {what} after {self.p["wait_timeout_s"]:.0f} s: giving up')
            return
        wrench = self.teacher.update(now, self._q, self._qdot)
        self._publish(wrench)
        phase = self.teacher.phase
        if phase == 'ready' and self._bracket == 'idle':
            self._request_start(now)
        elif phase == 'finished' and self._bracket in ('idle', 'recording'):
            self._request_stop()
        else:
            self._say({'approach': 'bringing the paddle to the ready pose', 'settling': 'settling at the ready pose',
                       'stroke': f'playing the {self.p["swing"]} stroke'}.get(phase, self._announced))

    # --- recorder bracket ---
    def _request_start(self, now: float) -> None:
        if not self.p['use_recorder']:
            self.teacher.begin_stroke(now)
            return
        if not self.start_client.service_is_ready() or not self.stop_client.service_is_ready():
            self._say('waiting for the recorder (/recorder/start, /recorder/stop)')
            if now - self._started_s > self.p['wait_timeout_s']:
                self._finish(2, f'no recorder after {self.p["wait_timeout_s"]:.0f} s: giving up')
            return
        self._bracket = 'starting'
        self.start_client.call_async(StartClip.Request(label=self.label)).add_done_callback(self._on_started)

    def _on_started(self, future) -> None:
        response = future.result()
        if response is None or not response.success:
            reason = 'no answer' if response is None else response.message
            self._finish(3, f'/recorder/start failed: {reason}')
            return
        self._bracket = 'recording'
        self.get_logger().info(f'recording {self.label!r} into {response.bag_path}')
        self.teacher.begin_stroke(self._now_s())

    def _request_stop(self) -> None:
        if self._bracket == 'idle':
            self._bracket = 'done'
            self._finish(0, 'stroke done (not recorded)')
            return
        self._bracket = 'stopping'
        self.stop_client.call_async(Trigger.Request()).add_done_callback(self._on_stopped)

    def _on_stopped(self, future) -> None:
        response = future.result()
        self._bracket = 'done'
        if response is None or not response.success:
            self._finish(3, f'/recorder/stop failed: {"no answer" if response is None else response.message}')
        else:
            self._finish(0, f'clip {self.label!r} recorded: {response.message}')

    def stop_recording_now(self, executor, timeout_s: float = 2.0) -> None:
        """On Ctrl-C mid-stroke: close the clip rather than leave the recorder writing."""
        if self._bracket not in ('starting', 'recording') or not self.stop_client.service_is_ready():
            return
        future = self.stop_client.call_async(Trigger.Request())
        executor.spin_until_future_complete(future, timeout_sec=timeout_s)
        self._bracket = 'done'


def main(args=None) -> int:
    """Entry point of the virtual_teacher executable."""
    # Our own Ctrl-C handling: a flag, not an exception inside a callback, and the context outlives it
    # so that the node can still let go of the paddle and close the clip.
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    try:
        node = VirtualTeacherNode()
    except (ValueError, RuntimeError) as error:
        print(f'virtual_teacher: {error}', file=sys.stderr)
        rclpy.try_shutdown()
        return 1
    interrupted = []
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda number, frame: interrupted.append(number))
    # The events executor costs a fraction of the standard one's CPU time per callback (1000+ a second).
    executor = EventsExecutor()
    executor.add_node(node)
    try:
        while rclpy.ok() and node.exit_code is None and not interrupted:
            executor.spin_once(timeout_sec=0.1)
        if interrupted:
            node.get_logger().info('interrupted: letting go of the paddle')
            node.release_hand()
            node.stop_recording_now(executor)
            code = 130
        else:
            code = node.exit_code if node.exit_code is not None else 1
        for _ in range(5):                   # make sure the zero wrench gets out
            node.release_hand()
            executor.spin_once(timeout_sec=0.01)
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return code


if __name__ == '__main__':
    sys.exit(main())
