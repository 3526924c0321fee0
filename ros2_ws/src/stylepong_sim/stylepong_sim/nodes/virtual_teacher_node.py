"""`ros2 run stylepong_sim virtual_teacher --ros-args -p swing:=forward`: a person dragging one stroke.

Pushes the simulated paddle through /sim/hand_wrench (geometry_msgs/WrenchStamped, world axes, the
torque about the gripped point `grip_frame`) so that drag_teach moves the arm along a table-tennis
stroke (teacher.py), and brackets the stroke with /recorder/start (stylepong_msgs/StartClip, label =
the swing) and /recorder/stop (std_srvs/Trigger). Steps: wait for joint states (and for someone
commanding the arm, i.e. drag_teach), bring the paddle to the ready pose, start the recorder, play the
stroke, stop the recorder, let go, exit (exit code 0 when a clip was recorded). Each take varies like a
person's (teacher.sample_variation): `seed` picks the take (the same seed, the same stroke), `variation`
scales how far it departs from the nominal stroke (0: the nominal stroke). `strokes_file` teaches hand-made
key poses instead of the shipped ones (a style: stroke_styles.py, config/styles/<name>.yaml), each take
checked before the drag (joint limits, the shoulder singularity, an unmistakable label).
Parameters: PARAMETERS below, defaults in config/virtual_teacher.yaml (read at start-up). A bad one stops the
node with one line on stderr and exit code 2 (stylepong_common.node_support).
Exit codes: 0 a clip was recorded (or, without the recorder, the stroke played); 2 a bad parameter, or joint
states, drag_teach or the recorder missing after wait_timeout_s; 3 the recorder refused; 130 Ctrl-C or
SIGTERM; 1 the ROS context shut down under the node.
Subscribes /joint_states, /forward_position_controller/commands (only to see that the arm is driven).
"""

from __future__ import annotations

import sys

import numpy as np
from geometry_msgs.msg import WrenchStamped
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from std_srvs.srv import Trigger

from stylepong_common.exit_codes import EXIT_INTERRUPTED, EXIT_STOPPED
from stylepong_common.node_support import Param, ParameterError, ThrottledLog, declare_parameters, run_node
from stylepong_description import robot_model
from stylepong_msgs.srv import StartClip
from stylepong_sim.teaching.stroke_styles import check_stroke, load_strokes_file, resolve_strokes_file
from stylepong_sim.teaching.teacher import (
    MAX_SIDE_REACH_M,
    MAX_SIDE_TURN_RAD,
    SWINGS,
    TeacherConfig,
    VirtualTeacher,
    check_side_reach,
    sample_variation,
)

PROGRAM = 'virtual_teacher'
RELEASE_REPEATS = 5  # on the way out, the zero wrench is sent this many times, 10 ms apart

_DEFAULTS = TeacherConfig()
PARAMETERS = (
    Param('swing', 'forward', 'the stroke to teach', choices=SWINGS),
    Param('label', '', 'clip label sent to /recorder/start (empty: the swing)'),
    Param('seed', 0, 'which take of the stroke (the same seed gives the same take)', low=0),
    Param(
        'variation',
        1.0,
        'how far the take departs from the nominal stroke, 0-1 of teacher.VARIATION_RANGES (0: nominal)',
        low=0.0,
        high=1.0,
    ),
    Param('rate_hz', 500.0, 'rate of the hand wrench', low=10.0, high=2000.0),
    Param('use_recorder', True, 'bracket the stroke with /recorder/start and /recorder/stop'),
    Param('wait_timeout_s', 30.0, 'give up when joint states, drag_teach or the recorder are not there by then'),
    Param('wait_for_commands', True, 'push only once someone (drag_teach) commands the arm'),
    Param('exit_when_done', True, 'exit after the stroke (else stay, hand released, until Ctrl-C)'),
    Param('grip_frame', robot_model.TOOL_FRAME, 'robot frame whose origin the simulator applies /sim/hand_wrench at'),
    Param('wrench_frame_id', 'world', 'header frame of the hand wrench (its axes)'),
    Param('joint_state_timeout_s', 0.1, 'older joint states: the hand lets go until fresh ones arrive'),
    Param('lead_in_s', _DEFAULTS.lead_in_s, 'recorded at rest at the ready pose before the back-swing'),
    Param('backswing_s', _DEFAULTS.backswing_s, 'duration of the back-swing'),
    Param('forward_swing_s', _DEFAULTS.forward_swing_s, 'back-swing to follow-through, through the hitting point'),
    Param('end_hold_s', _DEFAULTS.end_hold_s, 'recorded at rest after the follow-through'),
    Param('hand_stiffness_n_per_m', _DEFAULTS.hand_stiffness_n_per_m, "the hand's grip stiffness"),
    Param(
        'expected_damping_ns_per_m', _DEFAULTS.expected_damping_ns_per_m, 'how heavy the person expects the arm to feel'
    ),
    Param('max_force_n', _DEFAULTS.max_force_n, 'the hardest the hand pushes'),
    Param(
        'blade_pitch_rad',
        _DEFAULTS.blade_pitch_rad,
        'how far the blade is opened (face turned up) through '
        'the stroke (0.6: the shipped clips; 0: upright, the ball goes down)',
        low=0.0,
        high=1.0,
    ),
    Param(
        'side_turn_rad',
        _DEFAULTS.side_turn_rad,
        'how far a leftward or rightward stroke is turned towards its '
        'side about the shoulder pan (0: the nominal stroke)',
        low=0.0,
        high=MAX_SIDE_TURN_RAD,
    ),
    Param(
        'side_reach_m',
        _DEFAULTS.side_reach_m,
        'how far a leftward or rightward stroke is carried further to its '
        'side, the arm reaching out (0: the nominal stroke)',
        low=0.0,
        high=max(MAX_SIDE_REACH_M.values()),
    ),
    Param(
        'strokes_file',
        '',
        "hand-made key poses: a style's YAML (or its name, config/styles/<name>.yaml); empty: the shipped strokes",
    ),
)


def teacher_from(p: dict) -> VirtualTeacher:
    """The stroke the checked parameter values describe; ParameterError names a bad combination."""
    try:
        config = TeacherConfig(**{k: p[k] for k in TeacherConfig.__dataclass_fields__ if k in p})
        config.validate()
        check_side_reach(p['swing'], config)
    except ValueError as error:  # its messages name the field, and the fields are the parameters
        raise ParameterError(str(error)) from error
    variation = sample_variation(p['swing'], p['seed'], p['variation'])
    shape = None
    if p['strokes_file']:
        path = resolve_strokes_file(p['strokes_file'])
        try:
            strokes = load_strokes_file(path)
        except ValueError as error:
            raise ParameterError(f'parameter strokes_file: {error}') from error
        if p['swing'] not in strokes:
            raise ParameterError(
                f'parameter strokes_file: {path} has no {p["swing"]} stroke (it has {", ".join(strokes)})'
            )
        shape = strokes[p['swing']]
    try:
        teacher = VirtualTeacher(p['swing'], config, grip_frame=p['grip_frame'], variation=variation, shape=shape)
    except ValueError as error:  # swing, seed, variation and config are checked: what is left is the frame
        raise ParameterError(f'parameter grip_frame: {error}') from error
    if shape is not None:  # the take about to be dragged, with this config's tempo, pitch, turn and reach
        try:
            check_stroke(p['swing'], teacher.path)
        except ValueError as error:
            raise ParameterError(
                f'parameter strokes_file: {path}, {p["swing"]} take (seed {p["seed"]}): {error}'
            ) from error
    return teacher


class VirtualTeacherNode(Node):
    """The virtual teacher: pushes the paddle through one stroke on /sim/hand_wrench, recording it as a clip."""

    def __init__(self, **kwargs):
        super().__init__(PROGRAM, **kwargs)
        p = declare_parameters(self, PARAMETERS)
        self.teacher = teacher_from(p)
        self.p = p
        self.label = p['label'] or p['swing']
        self.exit_code: int | None = None  # set when the node is done (run_node's loop then ends)
        self._q: np.ndarray | None = None
        self._qdot = np.zeros(robot_model.NUM_JOINTS)
        self._joint_time_s: float | None = None
        self._commanded = not p['wait_for_commands']
        self._started_s = self._now_s()
        self._bracket = 'idle'  # idle -> starting -> recording -> stopping -> done
        self._announced = ''
        self._warnings = ThrottledLog(self.get_logger())

        self.wrench_pub = self.create_publisher(WrenchStamped, '/sim/hand_wrench', 10)
        # Reused at every tick (publishing copies it): filling fields is cheaper than a new message.
        self._wrench_msg = WrenchStamped()
        self._wrench_msg.header.frame_id = p['wrench_frame_id']
        self.create_subscription(JointState, '/joint_states', self._on_joint_state, qos_profile_sensor_data)
        self._command_sub = (
            None
            if self._commanded
            else self.create_subscription(
                Float64MultiArray, '/forward_position_controller/commands', self._on_command, 10
            )
        )
        self.start_client = self.create_client(StartClip, '/recorder/start')
        self.stop_client = self.create_client(Trigger, '/recorder/stop')
        self.create_timer(1.0 / p['rate_hz'], self._on_tick)
        path, variation = self.teacher.path, self.teacher.path.variation
        self.get_logger().info(
            f'teaching a {p["swing"]} stroke '
            f'({path.stroke_s:.2f} s, a {path.duration_s:.2f} s clip), '
            f'label {self.label!r}, seed {p["seed"]}, variation {p["variation"]}: '
            f'amplitude x{variation.amplitude_scale:.3f}, hit at {variation.hit_fraction:.3f} '
            f'of the forward swing'
        )

    def _now_s(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def _say(self, text: str) -> None:
        if text != self._announced:
            self.get_logger().info(text)
            self._announced = text

    # --- inputs ---
    def _on_joint_state(self, msg: JointState) -> None:
        names = list(msg.name)  # once per message, not once per joint (500 messages a second)
        try:
            index = [names.index(n) for n in robot_model.JOINT_NAMES]
            q = np.array([msg.position[i] for i in index], dtype=float)
            qdot = (
                np.array([msg.velocity[i] for i in index], dtype=float)
                if len(msg.velocity) == len(msg.name)
                else np.zeros(robot_model.NUM_JOINTS)
            )
        except (ValueError, IndexError):
            self._warnings.warn('joint names', 'joint state without all UR5 joints ignored')
            return
        if not (np.all(np.isfinite(q)) and np.all(np.isfinite(qdot))):
            self._warnings.warn('joint values', 'non-finite joint state ignored')
            return
        self._q, self._qdot, self._joint_time_s = q, qdot, self._now_s()

    def _on_command(self, msg: Float64MultiArray) -> None:
        self._commanded = True
        if self._command_sub is not None:  # seen once is enough: stop taking 500 messages a second
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
        if code == 0:  # rclpy ties a severity to its call site: one call per severity
            self.get_logger().info(text)
        else:
            self.get_logger().error(text)
        self.release_hand()
        if self.p['exit_when_done'] or code != 0:
            self.exit_code = code

    # --- the cycle ---
    def _on_tick(self) -> None:
        now = self._now_s()
        if self._started_s == 0.0:
            # On simulated time the clock reads 0 until the first /clock arrives: the wait for joint states
            # starts at the first tick that has a time, else it looks as if it began at the simulation's start.
            self._started_s = now
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
            self._say(
                {
                    'approach': 'bringing the paddle to the ready pose',
                    'settling': 'settling at the ready pose',
                    'stroke': f'playing the {self.p["swing"]} stroke',
                }.get(phase, self._announced)
            )

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

    @property
    def finished(self) -> bool:
        """Done (run_node ends its loop): `exit_code` says how."""
        return self.exit_code is not None

    def stop_recording_now(self, executor, timeout_s: float = 2.0) -> None:
        """On Ctrl-C mid-stroke: close the clip rather than leave the recorder writing."""
        if self._bracket not in ('starting', 'recording') or not self.stop_client.service_is_ready():
            return
        future = self.stop_client.call_async(Trigger.Request())
        executor.spin_until_future_complete(future, timeout_sec=timeout_s)
        self._bracket = 'done'

    def wind_down(self, executor, interrupted: bool) -> None:
        """After the loop (run_node), while the executor still serves the node: let go and close the clip."""
        if interrupted:
            self.get_logger().info('interrupted: letting go of the paddle')
            self.release_hand()
            self.stop_recording_now(executor)
            self.exit_code = EXIT_INTERRUPTED
        elif self.exit_code is None:
            self.exit_code = EXIT_STOPPED
        for _ in range(RELEASE_REPEATS):  # make sure the zero wrench gets out
            self.release_hand()
            executor.spin_once(timeout_sec=0.01)


def main(args: list[str] | None = None) -> int:
    """Entry point of the virtual_teacher executable."""
    # run_node's Ctrl-C handling sets a flag rather than raising inside a callback, and the context
    # outlives it, so that wind_down can still let go of the paddle and close the clip.
    return run_node(PROGRAM, VirtualTeacherNode, args)


if __name__ == '__main__':
    sys.exit(main())
