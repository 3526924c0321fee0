"""`ros2 run stylepong_player player`: the trained actor at 60 Hz on a UR5 (real, or ur5_sim).

Subscribes  /joint_states (sensor_msgs/JointState, any joint order), /ball/state (stylepong_msgs/BallState,
            frame world, stamp = instant observed: the ball estimator's output, never the simulator's truth),
            /player/goal (geometry_msgs/PointStamped, frame world),
            /player/enable (std_msgs/Bool: true enables, false disables)
Publishes   /forward_position_controller/commands (std_msgs/Float64MultiArray: 6 positions, URDF order; with
            stream_commands one per joint state along the straight path to the latest 60 Hz command, else
            one per step),
            /player/status (std_msgs/String, JSON, status_rate_hz: state, at_home, period and its jitter,
            ball-stamp-to-command latency, arrival-to-command latency, inference time, counts, rejected
            messages by kind; times in ms)
Parameters  config/player.yaml (read at start-up; a bad one: one line on stderr, exit code 2). The actor
            is refused (one line naming the difference, exit code 2) unless its contract is this code's spec.
Clock       the node's: wall time, or /clock with use_sim_time:=true (ur5_sim), which it then follows at
            any speed. The logic, the state machine and the timing choice are in player_core.py.
"""

from __future__ import annotations

import json
import pathlib
import sys
import time

from geometry_msgs.msg import PointStamped
from rclpy.node import Node
from rclpy.qos import QoSProfile
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool, Float64MultiArray, String

from stylepong_common.node_support import Param, ParameterError, ThrottledLog, declare_parameters, run_node
from stylepong_description import robot_cell
from stylepong_msgs.msg import BallState
from stylepong_player import player_core as core
from stylepong_player import spec
from stylepong_player.actor_contract import ActorMismatchError

COMMAND_TOPIC = '/forward_position_controller/commands'
STATUS_TOPIC = '/player/status'


def _default_actor() -> str:
    """The shipped actor, models/amp_actor.pt (the .onnx beside it), where the training package that ships it
    is installed; a robot computer without it names its actor."""
    try:
        from ament_index_python.packages import get_package_share_directory

        return str(pathlib.Path(get_package_share_directory('stylepong_policy')) / 'models' / 'amp_actor.pt')
    except (ImportError, LookupError):
        return 'amp_actor.pt'


_D = core.PlayerConfig()


def _configured(name: str, description: str, **bounds) -> Param:
    """A row of the table whose default is PlayerConfig's field of the same name (a list for a tuple)."""
    default = getattr(_D, name)
    return Param(name, list(default) if isinstance(default, tuple) else default, description, **bounds)


_FIELD = robot_cell.HALF_LENGTH_M
PARAMETERS = (
    Param('actor', '', "exported actor, <name>.pt or <name>.onnx ('' = the shipped models/amp_actor.pt)"),
    Param('backend', 'onnx', 'onnx (onnxruntime, no torch) or torchscript', choices=core.BACKENDS),
    Param('start_enabled', False, 'enabled at start-up (else wait for /player/enable true)'),
    _configured(
        'goal_xy_m', "goal on the opponent's half until /player/goal says otherwise", length=2, low=-_FIELD, high=_FIELD
    ),
    _configured('position_margin_rad', 'commands stay this far inside the URDF position limits', low=0.0, high=0.5),
    _configured(
        'velocity_limit_scale', "commands move at most this share of the URDF's velocity limits", low=0.05, high=1.0
    ),
    _configured(
        'acceleration_limit_rad_s2', 'command acceleration limits per joint', length=spec.NUM_ACTIONS, low=1.0, high=2e3
    ),
    _configured('home_speed_rad_s', 'speed of the moves to home (ready)', low=0.05, high=3.0),
    _configured('home_acceleration_rad_s2', 'acceleration of the moves to home', low=0.1, high=50.0),
    _configured('home_tolerance_rad', 'at home: every joint this close to it', low=0.001, high=0.5),
    _configured(
        'joint_timeout_periods', 'no joint state accepted for this many periods: no commands', low=1.0, high=60.0
    ),
    _configured('ball_timeout_s', 'no ball accepted for this long: the ball is gone (ready)', low=0.02, high=2.0),
    _configured('max_ball_age_s', 'ball messages stamped longer ago than this are rejected', low=0.01, high=2.0),
    _configured('max_ball_speed_m_s', 'faster ball messages are rejected', low=1.0, high=100.0),
    _configured(
        'max_ball_velocity_std_m_s',
        'ball states whose velocity is less certain (largest per-axis std of velocity_covariance) are rejected',
        low=0.01,
        high=100.0,
    ),
    _configured(
        'stream_commands',
        'publish on every joint state the point on the straight path to '
        'the latest command (reached one period after its step); false: one command per 60 Hz period',
    ),
    _configured(
        'predict_ball',
        "carry the ball forward from its message's stamp to the step "
        '(flight and table bounce) before the actor sees it; false: the ball as the message says',
    ),
    Param('status_rate_hz', 2.0, '/player/status rate', low=0.1, high=50.0),
)


class PlayerNode(Node):
    """The player node: the exported actor at 60 Hz on ball and joint states, commands to the arm."""

    def __init__(self, **node_kwargs):
        super().__init__('player', **node_kwargs)
        value = declare_parameters(self, PARAMETERS)
        try:
            config = core.PlayerConfig(
                goal_xy_m=tuple(value['goal_xy_m']),
                position_margin_rad=value['position_margin_rad'],
                velocity_limit_scale=value['velocity_limit_scale'],
                acceleration_limit_rad_s2=tuple(value['acceleration_limit_rad_s2']),
                home_speed_rad_s=value['home_speed_rad_s'],
                home_acceleration_rad_s2=value['home_acceleration_rad_s2'],
                home_tolerance_rad=value['home_tolerance_rad'],
                joint_timeout_periods=value['joint_timeout_periods'],
                ball_timeout_s=value['ball_timeout_s'],
                max_ball_age_s=value['max_ball_age_s'],
                max_ball_speed_m_s=value['max_ball_speed_m_s'],
                max_ball_velocity_std_m_s=value['max_ball_velocity_std_m_s'],
                stream_commands=value['stream_commands'],
                predict_ball=value['predict_ball'],
            )
            config.validate()
        except ValueError as error:
            raise ParameterError(str(error)) from error
        actor_path = value['actor'] or _default_actor()
        actor = core.load_actor(actor_path, value['backend'])
        self.core = core.Player(config, actor)
        self.backend = value['backend']
        self._warnings = ThrottledLog(self.get_logger())
        self._command = Float64MultiArray()

        qos = QoSProfile(depth=10)
        self._command_pub = self.create_publisher(Float64MultiArray, COMMAND_TOPIC, qos)
        self._status_pub = self.create_publisher(String, STATUS_TOPIC, qos)
        self.create_subscription(JointState, '/joint_states', self._on_joint_state, qos)
        self.create_subscription(BallState, '/ball/state', self._on_ball, qos)
        self.create_subscription(PointStamped, '/player/goal', self._on_goal, qos)
        self.create_subscription(Bool, '/player/enable', self._on_enable, qos)
        self.create_timer(config.period_s, self._on_timer)
        self.create_timer(1.0 / value['status_rate_hz'], self._publish_status)
        if value['start_enabled']:
            self.core.set_enabled(True)
        # On wall time against a cell that publishes /clock every ball is rejected as decades old; say why once.
        self._clock_hint = None
        if not self.get_parameter('use_sim_time').value:
            self._clock_hint = self.create_subscription(Clock, '/clock', self._on_foreign_clock, qos)
        self.get_logger().info(
            f'player: {actor.backend} actor {actor.path} (spec {actor.metadata["spec_version"]}), '
            f'{config.rate_hz:g} Hz, {"enabled" if value["start_enabled"] else "disabled until /player/enable"}'
        )

    def _now_s(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    # --- inputs ------------------------------------------------------------------------------------
    def _on_joint_state(self, msg: JointState) -> None:
        now_s = self._now_s()
        problem = self.core.on_joint_state(msg.name, msg.position, msg.velocity, now_s)
        if problem:
            self._warnings.warn('joint_state', lambda: f'/joint_states rejected: {problem}')
        elif self.core.fallback_step_due(now_s):
            self._step(now_s, ball_driven=False)
        else:
            point = self.core.stream_command(now_s)
            if point is not None:
                self._publish(point)

    def _on_ball(self, msg: BallState) -> None:
        received_wall_s = time.perf_counter()
        now_s = self._now_s()
        stamp_s = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        p, v = msg.position, msg.velocity
        problem = self.core.on_ball(
            msg.header.frame_id, stamp_s, (p.x, p.y, p.z), (v.x, v.y, v.z), now_s, msg.velocity_covariance
        )
        if problem:
            self._warnings.warn('ball', lambda: f'/ball/state rejected: {problem}')
        elif self.core.ball_step_due(now_s):
            self._step(now_s, ball_driven=True, received_wall_s=received_wall_s)

    def _on_foreign_clock(self, _msg: Clock) -> None:
        if self._clock_hint is None:
            return
        self.destroy_subscription(self._clock_hint)
        self._clock_hint = None
        self.get_logger().warning(
            '/clock is published (a simulated cell) but this player runs on wall time: '
            'start it with --ros-args -p use_sim_time:=true'
        )

    def _on_goal(self, msg: PointStamped) -> None:
        problem = self.core.on_goal(msg.header.frame_id, msg.point.x, msg.point.y)
        if problem:
            self._warnings.warn('goal', lambda: f'/player/goal rejected: {problem}')
        else:
            self.get_logger().info(f'goal ({msg.point.x:.3f}, {msg.point.y:.3f}) m')

    def _on_enable(self, msg: Bool) -> None:
        before = self.core.state
        self.core.set_enabled(bool(msg.data))
        if self.core.state != before:
            self.get_logger().info(f'{"enabled: ready" if msg.data else "disabled: no commands"}')

    # --- the loop ----------------------------------------------------------------------------------
    def _on_timer(self) -> None:
        now_s = self._now_s()
        if self.core.timer_step_due(now_s):
            self._step(now_s, ball_driven=False)

    def _step(self, now_s: float, ball_driven: bool, received_wall_s: float | None = None) -> None:
        before = self.core.state
        result = self.core.step(now_s)
        if result.command is not None:
            self._publish(result.command)
            if result.policy:
                self.core.record_published(self._now_s(), ball_driven, received_wall_s, time.perf_counter())
        elif result.problem:
            self._warnings.warn('step', result.problem)
        if result.state != before:
            self.get_logger().info(f'{before.value} -> {result.state.value}')

    def _publish(self, command) -> None:
        self._command.data = command.tolist()
        self._command_pub.publish(self._command)

    def _publish_status(self) -> None:
        status = self.core.status(self._now_s())
        status['backend'] = self.backend
        self._status_pub.publish(String(data=json.dumps(status)))

    def close(self) -> None:
        s = self.core.status(self._now_s())
        self.get_logger().info(
            f'{s["counts"].get("commands", 0)} commands ({s["counts"].get("policy_steps", 0)} policy steps); '
            f'period {s["period_ms"]}; latency {s["latency_ms"]}; inference {s["inference_ms"]}; '
            f'rejected {s["rejected"]}'
        )


def main(args=None) -> int:
    """Entry point of the player executable."""
    return run_node('player', PlayerNode, args, config_errors=(ActorMismatchError,))


if __name__ == '__main__':
    sys.exit(main())
