"""`ros2 run stylepong_sim ur5_sim`: the simulated UR5 table-tennis cell, driven like a real UR5.

Thin ROS wiring around a cell (physics, servo, ball, referee) and sensing.py (sensor models). The cell is
engine:=mujoco, stylepong_sim.cells.cell.Cell (analytic ball contacts, as the batched training world), or
engine:=pybullet, stylepong_sim.cells.bullet_cell.BulletCell (Bullet's own dynamics and contacts; also
`ros2 run stylepong_sim ur5_bullet`); both behind the same topics, services and parameters. actuator:=ideal
(world_spec's servo reference) or ur_servoj (the UR controller's servoj: servo_rate_hz, lookahead_s, gain;
stylepong_sim.cells.ur_servoj states its law).
Time: the cell's simulated time, from 0 at start. It is published on /clock and stamps every message; nodes
that run with use_sim_time follow it. real_time_factor 1.0 paces the simulation by the wall clock (a
schedule: after a stall it catches up, by up to max_lag_s, then gives the backlog up with a warning);
0.0 runs as fast as the machine allows.

Publishes (QoS reliable, depth 10, as ros2_control's broadcasters; events depth 100):
  /joint_states                            sensor_msgs/JointState     joint_state_rate_hz (500): URDF names,
                                                                      position, velocity, effort (servo + gravity)
  /force_torque_sensor_broadcaster/wrench  geometry_msgs/WrenchStamped wrench_rate_hz (500), frame tool0: the
                                                                      wrench the environment applies on the tool
                                                                      (paddle weight, hand, contacts) about tool0;
                                                                      ft_include_inertia adds the tool's inertia
  /ball/detection                          geometry_msgs/PointStamped ball_detection_rate_hz (150): what a
                                                                      ball tracker reports (tracker.py): the
                                                                      centre in frame ball_camera, stamp =
                                                                      exposure; noise, latency, lost frames
                                                                      and false detections are parameters
  /sim/ball/ground_truth                   stylepong_msgs/BallState   ball_state_rate_hz (120), frame world: the
                                                                      true state, for tests and evaluation only
                                                                      (nothing on the robot side reads it)
  /ball/state                              stylepong_msgs/BallState   only with publish_ball_state: the ball with
                                                                      camera noise on position and velocity
                                                                      (the path before the estimator, kept for
                                                                      comparison); else ball_estimator's topic
  /rally/events                            stylepong_msgs/RallyEvent  on event, stamp = when it happened
  /clock                                   rosgraph_msgs/Clock        clock_rate_hz (1000: every physics step)
  /robot_description, /tf_static          std_msgs/String, tf2_msgs/TFMessage: once, transient local (as
                                                                      robot_state_publisher: the URDF, fixed joints,
                                                                      world -> base_link; world -> ball_camera)
  /tf                                      tf2_msgs/TFMessage         tf_rate_hz (100): the six joint transforms
  /cell/markers                            visualization_msgs/MarkerArray marker_rate_hz (30), transient local:
                                                                      table, net, ball (DELETE when none), frame world
Subscribes (reliable, depth 10):
  /forward_position_controller/commands    std_msgs/Float64MultiArray 6 joint positions (URDF order); wrong
                                                                      length, NaN/inf or outside the joint limits:
                                                                      throttled warning, last good target held
  /sim/hand_wrench                         geometry_msgs/WrenchStamped a hand on the tool, acting at tool0's
                                                                      origin, axes of header.frame_id (world or
                                                                      tool0); dropped hand_wrench_timeout_s (0.1)
                                                                      of sim time after it arrived
Services:
  /sim/launch_ball   stylepong_msgs/LaunchBall   explicit state, or randomize: world_spec.incoming_ball_for_seed
                                                 (seed, [speed_min, speed_max]; both 0: default 4.0-6.6 m/s)
  /sim/reset         std_srvs/Trigger            robot to home at rest, ball removed (its rally ends 'aborted')
Parameters: PARAMETERS below, all of them with their defaults in config/ur5_sim.yaml (read at start-up; a bad
one stops the node with one line on stderr and exit code 2, stylepong_common.node_support); sensing levels for
robustness tests: config/tracker_sensing.yaml (a 150 Hz stereo tracker, for ball_estimator) and
config/realistic_sensing.yaml (the older path: /ball/state with noisy velocities, publish_ball_state).
record_video: '' (off), a path ending in .mp4, or a folder for PNG frames. real_time_factor alone can be
changed at run time.
"""

from __future__ import annotations

import dataclasses
import math
import sys
import time

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import PointStamped, WrenchStamped
from rcl_interfaces.msg import SetParametersResult
from rclpy._rclpy_pybind11 import RCLError
from rclpy.node import Node
from rclpy.qos import QoSProfile
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from std_srvs.srv import Trigger
from visualization_msgs.msg import MarkerArray

from stylepong_common.node_support import Param, ParameterError, ThrottledLog, declare_parameters, run_node, typed_value
from stylepong_description import robot_model
from stylepong_description.robot_state import LinkTransform
from stylepong_msgs.msg import BallState, RallyEvent
from stylepong_msgs.srv import LaunchBall
from stylepong_sim import world_spec
from stylepong_sim.cells import ur_servoj
from stylepong_sim.cells.cell_inputs import FRAME_WORLD, MAX_LAUNCH_SPEED_M_S, InputError
from stylepong_sim.cells.cell_markers import cell_markers
from stylepong_sim.cells.sensing import BallCamera, ForceTorqueSensor, SampleClock, SensingConfig
from stylepong_sim.cells.tracker import FRAME_CAMERA, BallTracker, TrackerConfig
from stylepong_sim.nodes.robot_state_publisher_node import LATCHED_QOS, RobotStateOutputs

PROGRAM = 'ur5_sim'
MUJOCO, PYBULLET = 'mujoco', 'pybullet'
ENGINES = (MUJOCO, PYBULLET)
TIMER_PERIOD_S = 0.002
# real_time_factor 0: wall time a timer callback may spend stepping before inputs are served again.
FAST_BATCH_WALL_S = 0.004
MAX_RATE_HZ = 1.0 / world_spec.PHYSICS_DT_S  # a stream can sample at most every physics step
_SENSING_FLOATS = (
    'ball_position_noise_std_m',
    'ball_velocity_noise_std_m_s',
    'ball_latency_s',
    'ball_dropout_probability',
    'ft_force_noise_std_n',
    'ft_torque_noise_std_nm',
)


def _servoj_param(name: str, description: str) -> Param:
    """The ServojSettings field `name` as a parameter: its default, bounded by ur_servoj.SETTING_RANGES."""
    low, high = ur_servoj.SETTING_RANGES[name]
    return Param(name, getattr(ur_servoj.ServojSettings, name), description, low=low, high=high)


# The tracker's scalar parameters, one per TrackerConfig field in the dataclass's order (the camera pose
# follows them): name, description, low, high. Their defaults are TrackerConfig's.
_TRACKER_SCALARS = (
    ('ball_detection_rate_hz', '/ball/detection rate (tracker frames)', 1.0, MAX_RATE_HZ),
    ('ball_detection_latency_s', 'Tracker: exposure to message', 0.0, 1.0),
    ('ball_detection_latency_jitter_s', 'Tracker: latency varies uniformly by this much either way', 0.0, 1.0),
    ('ball_detection_noise_std_m', 'Tracker: position noise (std, per axis)', 0.0, 1.0),
    ('ball_detection_dropout_probability', 'Tracker: probability a frame shows no ball', 0.0, 0.99),
    ('ball_detection_outlier_probability', 'Tracker: probability a frame adds a false detection', 0.0, 0.99),
)


def _tracker_scalar_params() -> tuple[Param, ...]:
    """The rows of _TRACKER_SCALARS as parameters, each with the default of its TrackerConfig field."""
    fields = dataclasses.fields(TrackerConfig)[: len(_TRACKER_SCALARS)]
    return tuple(
        Param(name, field.default, description, low=low, high=high)
        for field, (name, description, low, high) in zip(fields, _TRACKER_SCALARS, strict=True)
    )


REAL_TIME_FACTOR = Param(
    'real_time_factor',
    1.0,
    'Simulated seconds per wall-clock second; 0 = as fast as possible',
    low=0.0,
    high=100.0,
    read_only=False,
)
ENGINE = Param(
    'engine',
    MUJOCO,
    'Physics of the cell: mujoco (analytic ball contacts) or pybullet (Bullet contacts)',
    choices=ENGINES,
)
PARAMETERS = (
    REAL_TIME_FACTOR,
    ENGINE,
    Param(
        'actuator',
        ur_servoj.IDEAL,
        "Command -> joint reference: ideal (world_spec's servo) or ur_servoj (UR)",
        choices=ur_servoj.ACTUATORS,
    ),
    _servoj_param('servo_rate_hz', 'ur_servoj: controller rate (CB3 125, e-Series 500)'),
    _servoj_param('lookahead_s', 'ur_servoj: servoj look-ahead time'),
    _servoj_param('gain', 'ur_servoj: servoj proportional gain'),
    Param('max_lag_s', 0.25, 'Largest backlog (sim s) caught up after a stall', low=0.001, high=10.0),
    Param(
        'home_joint_positions_rad',
        list(world_spec.HOME_JOINT_POSITIONS_RAD),
        'Start and reset pose, 6 joint positions (rad) in URDF order',
        length=robot_model.NUM_JOINTS,
    ),
    Param('joint_state_rate_hz', 500.0, '/joint_states rate', low=1.0, high=MAX_RATE_HZ),
    Param('wrench_rate_hz', 500.0, 'F/T wrench rate', low=1.0, high=MAX_RATE_HZ),
    Param('ball_state_rate_hz', 120.0, '/sim/ball/ground_truth (and /ball/state) rate', low=1.0, high=MAX_RATE_HZ),
    Param('clock_rate_hz', MAX_RATE_HZ, '/clock rate', low=1.0, high=MAX_RATE_HZ),
    Param('tf_rate_hz', 100.0, '/tf rate (the joint transforms, as robot_state_publisher)', low=1.0, high=MAX_RATE_HZ),
    Param('marker_rate_hz', 30.0, '/cell/markers rate (table, net, ball)', low=1.0, high=MAX_RATE_HZ),
    Param('hand_wrench_timeout_s', 0.1, 'A hand wrench is dropped this long after it arrived', low=0.001, high=10.0),
    *_tracker_scalar_params(),
    Param('ball_camera_xyz_m', list(TrackerConfig.camera_xyz_m), 'ball_camera frame: origin in world', length=3),
    Param(
        'ball_camera_rpy_rad',
        list(TrackerConfig.camera_rpy_rad),
        'ball_camera frame: roll, pitch, yaw in world',
        length=3,
    ),
    Param(
        'publish_ball_state',
        False,
        '/ball/state from the cell (noisy position and velocity, the path before '
        'ball_estimator); false: /ball/state is left to ball_estimator',
    ),
    Param('ball_position_noise_std_m', 0.0, 'Camera: position noise (std, per axis)', low=0.0, high=1.0),
    Param('ball_velocity_noise_std_m_s', 0.0, 'Camera: velocity noise (std, per axis)', low=0.0, high=10.0),
    Param('ball_latency_s', 0.0, 'Camera: delay from observation to publication', low=0.0, high=1.0),
    Param('ball_dropout_probability', 0.0, 'Camera: probability a sample is lost', low=0.0, high=0.99),
    Param('ft_force_noise_std_n', 0.0, 'F/T: force noise (std, per axis)', low=0.0, high=100.0),
    Param('ft_torque_noise_std_nm', 0.0, 'F/T: torque noise (std, per axis)', low=0.0, high=10.0),
    Param('ft_force_bias_n', [0.0, 0.0, 0.0], 'F/T: constant force bias, tool0 axes', length=3),
    Param('ft_torque_bias_nm', [0.0, 0.0, 0.0], 'F/T: constant torque bias, tool0 axes', length=3),
    Param(
        'ft_include_inertia',
        False,
        "F/T: also feel the tool's own inertia (a physical sensor does); false: the environment's wrench only",
    ),
    Param('sensing_seed', 0, 'Seed of the sensor noise', low=0, high=2**31 - 1),
    Param('record_video', '', "'' = off; a path ending in .mp4, or a folder for PNG frames"),
    Param('video_fps', 30.0, 'Video frames per simulated second', low=1.0, high=240.0),
    Param('video_width', 640, 'Video width (pixels, multiple of 16)', low=16, high=1920),
    Param('video_height', 480, 'Video height (pixels, multiple of 16)', low=16, high=1072),
    Param('video_camera', 'overview', 'overview (side view) or robot_view (from the opponent)'),
)


def _stamp(time_s: float) -> Time:
    nanoseconds = round(time_s * 1e9)
    return Time(sec=nanoseconds // 1_000_000_000, nanosec=nanoseconds % 1_000_000_000)


def build_cell(engine: str, home_joint_positions_rad, actuator: str, servoj: ur_servoj.ServojSettings):
    """The cell of `engine` (one of ENGINES); ValueError for a bad home pose."""
    if engine == PYBULLET:
        from stylepong_sim.cells.bullet_cell import BulletCell  # pybullet is loaded only when asked for

        return BulletCell(home_joint_positions_rad, actuator=actuator, servoj=servoj)
    from stylepong_sim.cells.cell import Cell  # with it the analytic ball contacts, which the Bullet cell must not load

    return Cell(home_joint_positions_rad=home_joint_positions_rad, actuator=actuator, servoj=servoj)


class Ur5SimNode(Node):
    """The ur5_sim node: the cell behind the UR driver's and ros2_control's topics, with ball and sim services."""

    def __init__(self, default_engine: str = MUJOCO, **node_kwargs):
        super().__init__(PROGRAM, **node_kwargs)
        table = tuple(
            Param(ENGINE.name, default_engine, ENGINE.description, choices=ENGINES) if row is ENGINE else row
            for row in PARAMETERS
        )
        value = declare_parameters(self, table)
        self.engine = value['engine']
        servoj = ur_servoj.ServojSettings(value['servo_rate_hz'], value['lookahead_s'], value['gain'])
        try:
            self._cell = build_cell(self.engine, value['home_joint_positions_rad'], value['actuator'], servoj)
        except ValueError as error:
            raise ParameterError(f'parameter home_joint_positions_rad: {error}') from error
        try:
            sensing = SensingConfig(
                **{name: value[name] for name in _SENSING_FLOATS},
                ft_force_bias_n=tuple(value['ft_force_bias_n']),
                ft_torque_bias_nm=tuple(value['ft_torque_bias_nm']),
                seed=value['sensing_seed'],
            )
        except ValueError as error:  # its messages name the field, and the fields are the parameters
            raise ParameterError(str(error)) from error
        try:
            tracker = TrackerConfig(
                *(value[name] for name, *_ in _TRACKER_SCALARS),
                tuple(value['ball_camera_xyz_m']),
                tuple(value['ball_camera_rpy_rad']),
            )
        except ValueError as error:
            raise ParameterError(str(error)) from error
        rng = np.random.default_rng(sensing.seed)
        self._camera = BallCamera(sensing, rng) if value['publish_ball_state'] else None
        self._tracker = BallTracker(tracker, np.random.default_rng([sensing.seed, 1]))
        self._detection_clock = SampleClock(tracker.rate_hz)
        self._ft_sensor = ForceTorqueSensor(sensing, rng)
        self._joint_clock = SampleClock(value['joint_state_rate_hz'])
        self._wrench_clock = SampleClock(value['wrench_rate_hz'])
        self._ball_clock = SampleClock(value['ball_state_rate_hz'])
        self._clock_clock = SampleClock(value['clock_rate_hz'])
        self._tf_clock = SampleClock(value['tf_rate_hz'])
        self._marker_clock = SampleClock(value['marker_rate_hz'])
        self._hand_timeout_s = value['hand_wrench_timeout_s']
        self._ft_include_inertia = value['ft_include_inertia']
        self._max_lag_s = value['max_lag_s']
        self._warnings = ThrottledLog(self.get_logger())
        self._video = None
        self._video_view = None
        video_path = value['record_video']
        if video_path:
            from stylepong_sim.cells.video import VideoRecorder

            try:
                if self.engine == PYBULLET:  # Bullet's state drawn by the MuJoCo scene's renderer
                    from stylepong_sim.cells.bullet_video import MirroredScene

                    self._video_view = MirroredScene()
                model = self._cell.model if self._video_view is None else self._video_view.model
                self._video = VideoRecorder(
                    model,
                    video_path,
                    fps=value['video_fps'],
                    width=value['video_width'],
                    height=value['video_height'],
                    camera=value['video_camera'],
                )
            except Exception as error:  # noqa: BLE001 - any renderer/encoder failure is a configuration problem
                reason = f'parameter record_video: cannot record video to {video_path!r}: {error}'
                raise ParameterError(reason) from error
            self.get_logger().info(f'recording video to {video_path} (rendering slows the simulation)')

        qos = QoSProfile(depth=10)
        self._joint_pub = self.create_publisher(JointState, '/joint_states', qos)
        self._wrench_pub = self.create_publisher(WrenchStamped, '/force_torque_sensor_broadcaster/wrench', qos)
        self._ball_pub = self.create_publisher(BallState, '/ball/state', qos) if self._camera else None
        self._truth_pub = self.create_publisher(BallState, '/sim/ball/ground_truth', qos)
        self._detection_pub = self.create_publisher(PointStamped, '/ball/detection', qos)
        self._event_pub = self.create_publisher(RallyEvent, '/rally/events', QoSProfile(depth=100))
        self._clock_pub = self.create_publisher(Clock, '/clock', qos)
        # What robot_state_publisher would publish for this arm, so that RViz and Foxglove show the cell.
        self._robot_state = RobotStateOutputs(self)
        camera = LinkTransform(FRAME_WORLD, FRAME_CAMERA, np.array(tracker.camera_xyz_m), tracker.camera_rotation_xyzw)
        self._robot_state.publish_description_and_static(_stamp(self._cell.time_s), extra=(camera,))
        self._marker_pub = self.create_publisher(MarkerArray, '/cell/markers', LATCHED_QOS)
        self.create_subscription(Float64MultiArray, '/forward_position_controller/commands', self._on_command, qos)
        self.create_subscription(WrenchStamped, '/sim/hand_wrench', self._on_hand_wrench, qos)
        self.create_service(LaunchBall, '/sim/launch_ball', self._on_launch_ball)
        self.create_service(Trigger, '/sim/reset', self._on_reset)

        # Messages are reused: filling fields is cheaper than building new ones at 500 Hz.
        self._joint_msg = JointState(name=list(robot_model.JOINT_NAMES))
        self._wrench_msg = WrenchStamped()
        self._wrench_msg.header.frame_id = robot_model.TOOL_FRAME
        self._ball_msg = BallState()
        self._ball_msg.header.frame_id = FRAME_WORLD
        if self._camera is not None:  # the camera model's noise, as a tracker's estimate would state it
            position_var = sensing.ball_position_noise_std_m**2
            velocity_var = sensing.ball_velocity_noise_std_m_s**2
            self._ball_msg.position_covariance = [
                position_var,
                0.0,
                0.0,
                0.0,
                position_var,
                0.0,
                0.0,
                0.0,
                position_var,
            ]
            self._ball_msg.velocity_covariance = [
                velocity_var,
                0.0,
                0.0,
                0.0,
                velocity_var,
                0.0,
                0.0,
                0.0,
                velocity_var,
            ]
        self._truth_msg = BallState()
        self._truth_msg.header.frame_id = FRAME_WORLD
        self._detection_msg = PointStamped()
        self._detection_msg.header.frame_id = FRAME_CAMERA
        self._clock_msg = Clock()

        self._real_time_factor = value['real_time_factor']
        self._anchored = False  # the wall-clock schedule starts at the first timer callback
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self._timer = self.create_timer(TIMER_PERIOD_S, self._on_timer)
        self._publish_due(self._cell.time_s)
        self.get_logger().info(
            f'UR5 cell ready ({self.engine}, actuator {value["actuator"]}): '
            f'physics step {self._cell.dt_s * 1e3:.1f} ms, real_time_factor {self._real_time_factor}'
        )

    # --- simulation loop ---------------------------------------------------------------------------
    def _reanchor(self) -> None:
        self._anchor_wall_s = time.monotonic()
        self._anchor_sim_s = self._cell.time_s

    def _on_timer(self) -> None:
        try:
            self._advance()
        except RCLError:
            if self.context.ok():
                raise
            # Shut down (Ctrl-C, SIGTERM) while publishing: the executor loop ends next.

    def _advance(self) -> None:
        """Step the physics up to where the schedule says sim time should be, publishing on the way."""
        cell = self._cell
        if not self._anchored:
            self._reanchor()
            self._anchored = True
        if self._real_time_factor > 0.0:
            target_s = self._anchor_sim_s + (time.monotonic() - self._anchor_wall_s) * self._real_time_factor
            if target_s - cell.time_s > self._max_lag_s:
                self._warnings.warn(
                    'backlog',
                    f'simulation {target_s - cell.time_s:.3f} s behind real_time_factor '
                    f'{self._real_time_factor}: dropping the backlog',
                )
                # Keep max_lag_s of it to catch up now; the rest of the schedule moves later.
                self._anchor_wall_s = time.monotonic()
                self._anchor_sim_s = cell.time_s + self._max_lag_s
                target_s = self._anchor_sim_s
            half_step_s = 0.5 * cell.dt_s
            while cell.time_s + half_step_s < target_s:
                cell.step(1)
                self._publish_due(cell.time_s)
        else:
            deadline_s = time.monotonic() + FAST_BATCH_WALL_S
            while time.monotonic() < deadline_s:
                cell.step(1)
                self._publish_due(cell.time_s)
        self._publish_events()

    def _publish_due(self, time_s: float) -> None:
        cell = self._cell
        stamp = None  # built once per step, only if something is published (publishing copies it)
        if self._joint_clock.due(time_s):
            stamp = _stamp(time_s)
            msg = self._joint_msg
            msg.header.stamp = stamp
            msg.position = cell.joint_positions_rad.tolist()
            msg.velocity = cell.joint_velocities_rad_s.tolist()
            msg.effort = cell.joint_efforts_nm.tolist()
            self._joint_pub.publish(msg)
        if self._wrench_clock.due(time_s):
            stamp = stamp or _stamp(time_s)
            force, torque = self._ft_sensor.measure(*cell.tool_wrench(self._ft_include_inertia))
            msg = self._wrench_msg
            msg.header.stamp = stamp
            wrench = msg.wrench
            wrench.force.x, wrench.force.y, wrench.force.z = force.tolist()
            wrench.torque.x, wrench.torque.y, wrench.torque.z = torque.tolist()
            self._wrench_pub.publish(msg)
        if self._clock_clock.due(time_s):
            self._clock_msg.clock = stamp or _stamp(time_s)
            self._clock_pub.publish(self._clock_msg)
        if self._tf_clock.due(time_s):
            self._robot_state.publish_joint_positions(cell.joint_positions_rad, stamp or _stamp(time_s))
        if self._marker_clock.due(time_s):
            ball = cell.ball_position_m if cell.ball_in_play else None
            self._marker_pub.publish(cell_markers(ball, stamp or _stamp(time_s)))
        if self._ball_clock.due(time_s) and cell.ball_in_play:  # the camera's frames keep their grid
            stamp = stamp or _stamp(time_s)
            self._publish_ball_state(
                self._truth_pub, self._truth_msg, stamp, cell.ball_position_m, cell.ball_velocity_m_s
            )
            if self._camera is not None:
                self._camera.observe(time_s, cell.ball_position_m, cell.ball_velocity_m_s)
        if self._camera is not None:
            for observation in self._camera.delivered(time_s):
                self._publish_ball_state(
                    self._ball_pub,
                    self._ball_msg,
                    _stamp(observation.stamp_s),
                    observation.position_m,
                    observation.velocity_m_s,
                )
        if self._detection_clock.due(time_s):  # a tracker runs whether or not a ball is in play
            self._tracker.expose(time_s, cell.ball_position_m if cell.ball_in_play else None)
        for detection in self._tracker.delivered(time_s):
            msg = self._detection_msg
            msg.header.stamp = _stamp(detection.stamp_s)
            msg.point.x, msg.point.y, msg.point.z = detection.position_camera_m.tolist()
            self._detection_pub.publish(msg)
        if self._video is not None and self._video.clock.due(time_s):
            self._video.capture(cell.data if self._video_view is None else self._video_view.show(cell))

    @staticmethod
    def _publish_ball_state(
        publisher, msg: BallState, stamp: Time, position_m: np.ndarray, velocity_m_s: np.ndarray
    ) -> None:
        msg.header.stamp = stamp
        msg.position.x, msg.position.y, msg.position.z = position_m.tolist()
        msg.velocity.x, msg.velocity.y, msg.velocity.z = velocity_m_s.tolist()
        publisher.publish(msg)

    def _publish_events(self) -> None:
        for event in self._cell.pop_events():
            msg = RallyEvent(ball_id=event.ball_id, type=event.type, success=event.success, reason=event.reason)
            msg.header.stamp = _stamp(event.time_s)
            msg.header.frame_id = FRAME_WORLD
            msg.position.x, msg.position.y, msg.position.z = event.position_m
            self._event_pub.publish(msg)
            self.get_logger().info(str(event))

    # --- inputs ------------------------------------------------------------------------------------
    def _on_command(self, msg: Float64MultiArray) -> None:
        try:
            self._cell.set_joint_targets(msg.data)
        except InputError as error:
            self._warnings.warn('command_' + error.kind, f'command rejected, holding the last good target: {error}')

    def _on_hand_wrench(self, msg: WrenchStamped) -> None:
        frame = msg.header.frame_id.lstrip('/')
        w = msg.wrench
        try:
            self._cell.set_hand_wrench(
                (w.force.x, w.force.y, w.force.z),
                (w.torque.x, w.torque.y, w.torque.z),
                frame=frame,
                duration_s=self._hand_timeout_s,
            )
        except InputError as error:
            self._warnings.warn('hand_' + error.kind, f'/sim/hand_wrench rejected: {error}')

    def _on_launch_ball(self, request: LaunchBall.Request, response: LaunchBall.Response) -> LaunchBall.Response:
        try:
            if request.randomize:
                speed_range = self._checked_speed_range(request.speed_min, request.speed_max)
                launch = world_spec.incoming_ball_for_seed(request.seed, speed_range)
                position, velocity = launch.position_m, launch.velocity_m_s
            else:
                position = (request.position.x, request.position.y, request.position.z)
                velocity = (request.velocity.x, request.velocity.y, request.velocity.z)
            response.ball_id = self._cell.launch_ball(position, velocity)
        except (ValueError, RuntimeError) as error:
            response.success = False
            response.message = f'no ball launched: {error}'
            self.get_logger().warn(response.message)
            return response
        p, v = self._cell.ball_position_m, self._cell.ball_velocity_m_s
        response.position.x, response.position.y, response.position.z = p.tolist()
        response.velocity.x, response.velocity.y, response.velocity.z = v.tolist()
        response.success = True
        response.message = f'ball {response.ball_id} launched at {float(np.linalg.norm(v)):.2f} m/s'
        self._publish_events()
        return response

    @staticmethod
    def _checked_speed_range(speed_min: float, speed_max: float) -> tuple[float, float] | None:
        if speed_min == 0.0 and speed_max == 0.0:
            return None
        if not (
            math.isfinite(speed_min)
            and math.isfinite(speed_max)
            and 0.0 < speed_min <= speed_max <= MAX_LAUNCH_SPEED_M_S
        ):
            raise ValueError(
                f'speed range must satisfy 0 < speed_min <= speed_max <= {MAX_LAUNCH_SPEED_M_S} m/s '
                f'(or both 0 for the default), got [{speed_min}, {speed_max}]'
            )
        return (speed_min, speed_max)

    def _on_reset(self, _request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        self._cell.reset()
        self._publish_events()
        response.success = True
        response.message = 'robot at home, ball removed'
        return response

    def _on_set_parameters(self, parameters) -> SetParametersResult:
        """Run-time changes: only real_time_factor is writable, checked by the same row as at start-up."""
        for parameter in parameters:
            if parameter.name == REAL_TIME_FACTOR.name:
                try:
                    self._real_time_factor = typed_value(REAL_TIME_FACTOR, parameter.value)
                except ParameterError as error:
                    return SetParametersResult(successful=False, reason=str(error))
                self._reanchor()
        return SetParametersResult(successful=True)

    def close(self) -> None:
        if self._video is not None:
            self._video.close()
            self.get_logger().info(f'video: {self._video.frames} frames in {self._video.path}')
            self._video = None
        close_cell = getattr(self._cell, 'close', None)
        if close_cell is not None:
            close_cell()


def main(args: list[str] | None = None) -> int:
    """Entry point of the ur5_sim executable; Ctrl-C and SIGTERM stop it between steps."""
    # run_node's events executor costs a fraction of the Python one per wake-up (at the 500 Hz timer about
    # 11 % of a core instead of 26 %).
    return run_node(PROGRAM, Ur5SimNode, args)


def main_bullet(args: list[str] | None = None) -> int:
    """Entry point of ur5_bullet: ur5_sim with engine pybullet by default (same node name and parameters)."""
    return run_node('ur5_bullet', lambda: Ur5SimNode(default_engine=PYBULLET), args)


if __name__ == '__main__':
    sys.exit(main())
