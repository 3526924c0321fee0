"""What the viewer draws, from plain values (no ROS here): the cell in 3D and the time plots, in rerun.

One CellView is fed by the live node (viewer_node.py) and by a bag (bag_view.py) alike. Every sample carries
its message time (header stamps: the cell's simulated time with ur5_sim), which is the `time` timeline, so a
live session and a recorded clip look the same and can be scrubbed. High-rate streams are decimated by
message time before anything is decoded (decimate.py; the caller passes a function that reads the values),
and what is kept is sent at each flush() as one batch per entity: the viewer's work does not grow with the
graph's 500 Hz streams.

Entities
  /robot/...            the UR5 + paddle URDF (rerun's URDF loader: meshes and fixed joints), its frames
                        named after the links; /tf the moving joints, /tf_static world -> base_link
  /cell/table, /cell/net, /cell/ball, /cell/ball_trail, /cell/paddle_path (frame world)
  /cell/hand_wrench     the hand's force and torque (hand_wrench.py) as two arrows from tool0, while it pushes
  /plots/position/{measured,commanded}, /plots/speed/joints (a series per joint; speeds and limits),
  /plots/player/*,
  /events (rally events, player state changes)
"""

from __future__ import annotations

import math
import pathlib
import tempfile
from collections.abc import Callable, Sequence

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from stylepong_description import robot_model
from stylepong_description.robot_cell import FRAME_WORLD
from stylepong_description.robot_state import RobotState, quaternion_from_matrix, rotate
from stylepong_sim import world_spec
from stylepong_viz.batch_transforms import LinkPoses, joint_rotations
from stylepong_viz.decimate import ColumnBuffer, Decimator, Trail
from stylepong_viz.hand_wrench import STANDARD_GRAVITY_M_S2, hand_wrench_in_tool, tool_load_from_urdf

TIMELINE = 'time'
ARM_RATE_HZ = 30.0  # arm frames a second in the recording (scrubbing); the page shows them as they come
PLOT_RATE_HZ = 50.0  # plot points a second per series: 500 in a 10 s window, a swing's 0.4 s in 20
BALL_RATE_HZ = 60.0  # ball positions a second: a 6 m/s ball moves 10 cm between two
TRAIL_S = 1.5  # ball trail and paddle path length (message time)
FORCE_SCALE_M_PER_N = 0.02  # the hand's force arrow: 10 N draws 0.2 m
TORQUE_SCALE_M_PER_NM = 0.5  # the hand's torque arrow (right-hand rule): 0.4 N m draws 0.2 m
# Below this the sensor's noise and the paddle's model error, not a hand: no arrow (drag_teach ignores the
# same amount, its force_deadband_n in config/drag_teach.yaml).
HAND_FORCE_SHOWN_N = 1.0
TABLE_RGB = (20, 70, 150)
NET_RGB = (225, 210, 140)  # cream: told apart from the grey arm in screenshots
BALL_RGB = (255, 140, 0)
PADDLE_PATH_RGB = (200, 40, 40)
FORCE_RGB = (230, 30, 200)
TORQUE_RGB = (40, 200, 230)
JOINT_RGB = ((31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40), (148, 103, 189), (140, 86, 75))
LIMIT_RGB = (150, 150, 150)
BACKGROUND_RGB = (28, 30, 34)
PLAYER_SERIES = (('period_ms', 'jitter_p99'), ('latency_ms', 'p99'), ('inference_ms', 'p50'))
# The 3D view's camera: behind the robot on the table's long axis, looking down the table. The robot's base
# is then on the view's vertical centre line: world +y to the left of it, -y to the right.
EYE_POSITION_M = (world_spec.ROBOT_BASE_POSITION_M[0] - 1.3, 0.0, world_spec.TABLE_HEIGHT_M + 0.75)
EYE_TARGET_M = (world_spec.ROBOT_BASE_POSITION_M[0] + 0.8, 0.0, world_spec.TABLE_HEIGHT_M + 0.05)
PLOT_WINDOW_S = 10.0  # the plots show the last 10 s before the time cursor


def blueprint() -> rrb.Blueprint:
    """The page: the cell in 3D across the top, the time plots below it, panels collapsed."""
    cell = rrb.Spatial3DView(
        name='cell',
        origin='/',
        contents=['/robot/**', '/cell/**'],
        spatial_information=rrb.SpatialInformation(target_frame=FRAME_WORLD),
        background=BACKGROUND_RGB,
        line_grid=False,
        eye_controls=rrb.EyeControls3D(
            kind=rrb.Eye3DKind.Orbital, position=EYE_POSITION_M, look_target=EYE_TARGET_M, eye_up=(0.0, 0.0, 1.0)
        ),
    )
    window = rrb.TimeRange(
        start=rrb.TimeRangeBoundary.cursor_relative(seconds=-PLOT_WINDOW_S), end=rrb.TimeRangeBoundary.cursor_relative()
    )

    def plot(name: str, origin: str) -> rrb.TimeSeriesView:
        return rrb.TimeSeriesView(
            name=name, origin=origin, time_ranges=rrb.VisibleTimeRange(TIMELINE, start=window.start, end=window.end)
        )

    plots = rrb.Horizontal(
        plot('joint position: measured vs commanded (rad)', '/plots/position'),
        plot('joint speed vs limit (rad/s)', '/plots/speed'),
        plot('player: jitter, latency, inference (ms)', '/plots/player'),
        rrb.TextLogView(name='rally events, player state', origin='/events'),
    )
    return rrb.Blueprint(rrb.Vertical(cell, plots, row_shares=[3, 2]), collapse_panels=True)


def _stamp_s(sec: int, nanosec: int) -> float:
    return sec + nanosec * 1e-9


class CellView:
    """Logs the cell into a rerun recording: the static scene once, then samples as they come.

    Every on_* call takes the sample's time and a `read` function that returns its values: the values
    are read (a message decoded) only when the sample is kept, so a dropped sample costs a stamp
    comparison. Kept samples are buffered and sent at flush(), one batch per entity.
    """

    def __init__(
        self,
        recording: rr.RecordingStream,
        arm_rate_hz: float = ARM_RATE_HZ,
        plot_rate_hz: float = PLOT_RATE_HZ,
        ball_rate_hz: float = BALL_RATE_HZ,
    ):
        self.rec = recording
        urdf = robot_model.urdf_xml_for_display()
        self.robot_state = RobotState(urdf)
        self.joint_names = self.robot_state.moving_joint_names
        self._index = {n: k for k, n in enumerate(self.joint_names)}
        width = len(self.joint_names)
        self._arm, self._plot_joint = Decimator(arm_rate_hz), Decimator(plot_rate_hz)
        self._ball = Decimator(ball_rate_hz)
        self._arm_frames, self._measured = ColumnBuffer(width), ColumnBuffer(width)
        self._speed, self._commanded = ColumnBuffer(2 * width), ColumnBuffer(width)
        self._command_read: Callable[[], Sequence[float]] | None = None  # the latest command, not yet plotted
        self._wrench: tuple[float, Callable[[], Sequence[float]]] | None = None  # the latest, not yet drawn
        self._balls = ColumnBuffer(3)
        self._ball_trail = Trail(TRAIL_S)
        self._paddle_path = Trail(TRAIL_S)
        self._player_state = None
        self._hand_shown = False
        self.latest_time_s = 0.0
        self.latest_q: np.ndarray | None = None
        self.counts = {'joint_states': 0, 'arm_frames': 0, 'wrenches': 0, 'hand_shown': 0}
        rotation, position = world_spec.robot_base_pose()
        self._base_rotation_xyzw = quaternion_from_matrix(rotation)
        self._base_position_m = np.asarray(position, dtype=float)
        # Gravity in the base's axes (the base may be turned about world z): the tool's weight is removed there.
        self._gravity_base_m_s2 = rotate(
            self._base_rotation_xyzw * np.array([-1.0, -1.0, -1.0, 1.0]), np.array([0.0, 0.0, -STANDARD_GRAVITY_M_S2])
        )
        self.tool_load = tool_load_from_urdf(urdf, robot_model.TOOL_FRAME)
        self._tool_poses = LinkPoses(self.robot_state, robot_model.TOOL_FRAME)
        self._paddle_centre_poses = LinkPoses(self.robot_state, robot_model.PADDLE_CENTRE_FRAME)
        self._velocity_limits = np.array([j.velocity_limit for j in self.robot_state.moving_joints])
        self._log_static(urdf)

    # --- the scene that does not move -----------------------------------------------------------------
    def _log_static(self, urdf: str) -> None:
        rec = self.rec
        # rerun's URDF loader reads a file: the same XML the cell publishes on /robot_description.
        with tempfile.TemporaryDirectory(prefix='stylepong_viz_') as folder:
            path = pathlib.Path(folder) / 'ur5_paddle.urdf'
            path.write_text(urdf.replace('file://', ''))
            rr.urdf.UrdfTree.from_file_path(path, entity_path_prefix='robot').log_urdf_to_recording(rec)
        rr.log(
            'tf_static/world_base',
            rr.Transform3D(
                translation=self._base_position_m,
                quaternion=self._base_rotation_xyzw,
                parent_frame=FRAME_WORLD,
                child_frame=robot_model.BASE_FRAME,
            ),
            static=True,
            recording=rec,
        )
        world = rr.CoordinateFrame(FRAME_WORLD)
        table_half = (world_spec.HALF_LENGTH_M, world_spec.HALF_WIDTH_M, world_spec.TABLE_THICKNESS_M / 2.0)
        rr.log(
            'cell/table',
            rr.Boxes3D(
                centers=[(0.0, 0.0, world_spec.TABLE_HEIGHT_M - table_half[2])],
                half_sizes=[table_half],
                colors=[TABLE_RGB],
                fill_mode='solid',
            ),
            world,
            static=True,
            recording=rec,
        )
        low, high = np.array(world_spec.NET_BOX_LOW_M), np.array(world_spec.NET_BOX_HIGH_M)
        rr.log(
            'cell/net',
            rr.Boxes3D(
                centers=[(low + high) / 2.0], half_sizes=[(high - low) / 2.0], colors=[NET_RGB], fill_mode='solid'
            ),
            world,
            static=True,
            recording=rec,
        )
        for name in ('ball', 'ball_trail', 'paddle_path'):
            rr.log(f'cell/{name}', world, static=True, recording=rec)
        # The hand's wrench is drawn where the sensor reads it: at tool0's origin, in tool0's axes.
        rr.log('cell/hand_wrench', rr.CoordinateFrame(robot_model.TOOL_FRAME), static=True, recording=rec)
        colours = [JOINT_RGB[k % len(JOINT_RGB)] for k in range(len(self.joint_names))]
        short = [n.replace('_joint', '') for n in self.joint_names]
        # One entity per plot layer, a series per joint: a flush sends each layer as one batch.
        rr.log(
            'plots/position/measured',
            rr.SeriesLines(colors=colours, names=[f'{n} measured' for n in short]),
            static=True,
            recording=rec,
        )
        rr.log(
            'plots/position/commanded',
            rr.SeriesPoints(colors=colours, names=[f'{n} commanded' for n in short], marker_sizes=[1.5] * len(short)),
            static=True,
            recording=rec,
        )
        rr.log(
            'plots/speed/joints',
            rr.SeriesLines(
                colors=colours + [LIMIT_RGB] * len(short),
                names=[f'{n} |speed|' for n in short] + [f'{n} limit' for n in short],
            ),
            static=True,
            recording=rec,
        )

    # --- samples ----------------------------------------------------------------------------------------
    def _note_time(self, time_s: float) -> None:
        """The latest message time (a jump back of more than a second: a restarted cell or a new clip)."""
        self.latest_time_s = max(self.latest_time_s, time_s) if time_s >= self.latest_time_s - 1.0 else time_s

    def _set_time(self, time_s: float) -> None:
        rr.set_time(TIMELINE, duration=time_s, recording=self.rec)

    def urdf_order(self, names, values) -> np.ndarray | None:
        """values (named by names) in URDF joint order; None unless all six are there and finite."""
        out = np.full(len(self.joint_names), np.nan)
        for name, value in zip(names, values):
            k = self._index.get(name)
            if k is not None:
                out[k] = value
        return out if np.all(np.isfinite(out)) else None

    def on_joint_state(self, time_s: float, read: Callable[[], tuple]) -> None:
        """A /joint_states sample at time_s; read() -> (names, positions, velocities), called only when the
        sample is kept: for the arm (arm_rate_hz) or the plots (plot_rate_hz), where the latest command
        since the last plotted sample is plotted beside it."""
        self.counts['joint_states'] += 1
        plot, arm = self._plot_joint.due(time_s), self._arm.due(time_s)
        if not (plot or arm):
            return
        names, positions, velocities = read()
        q = self.urdf_order(names, positions)
        if q is None:
            return
        self._note_time(time_s)
        self.latest_q = q
        if plot:
            self._measured.add(time_s, q)
            qd = self.urdf_order(names, velocities) if len(velocities) == len(names) else None
            if qd is not None:
                self._speed.add(time_s, np.concatenate([np.abs(qd), self._velocity_limits]))
            if self._command_read is not None:
                command = self._command_read()
                self._command_read = None
                if len(command) == len(self.joint_names) and all(map(math.isfinite, command)):
                    self._commanded.add(time_s, command)
        if arm:
            self.counts['arm_frames'] += 1
            self._arm_frames.add(time_s, q)

    def on_command(self, read: Callable[[], Sequence[float]]) -> None:
        """A /forward_position_controller/commands sample: read() -> positions (URDF order). It has no stamp:
        the latest one is plotted at the next plotted joint state; wrong length or NaN: not drawn."""
        self._command_read = read

    def on_ball(self, time_s: float, read: Callable[[], Sequence[float]]) -> None:
        """A /ball/state sample: read() -> position (m, world); drawn at ball_rate_hz with its trail."""
        if not self._ball.due(time_s):
            return
        position_m = read()
        if len(position_m) == 3 and all(map(math.isfinite, position_m)):
            self._note_time(time_s)
            self._balls.add(time_s, position_m)

    def on_wrench(self, time_s: float, read: Callable[[], Sequence[float]]) -> None:
        """An F/T sample: read() -> (force N, torque N m) in tool0 axes about its origin (the sensor's
        convention). The latest one at each flush is drawn (_send_hand)."""
        self.counts['wrenches'] += 1
        self._wrench = (time_s, read)

    def on_rally_event(self, time_s: float, name: str, reason: str, success: bool, position_m) -> None:
        self._note_time(time_s)
        self._set_time(time_s)
        text = f'{name} at ({position_m[0]:.2f}, {position_m[1]:.2f}, {position_m[2]:.2f}) m'
        if name == 'RALLY_END':
            text += f': {"returned" if success else "missed"} ({reason})'
            self._send_balls()  # the ball's last samples before it goes
            self._ball_trail.clear()
            self._set_time(time_s)
            rr.log('cell/ball', rr.Points3D(np.zeros((0, 3))), recording=self.rec)
            rr.log('cell/ball_trail', rr.LineStrips3D([]), recording=self.rec)
        level = rr.TextLogLevel.INFO if success or name != 'RALLY_END' else rr.TextLogLevel.WARN
        rr.log('events/rally', rr.TextLog(text, level=level), recording=self.rec)

    def on_player_status(self, time_s: float, status: dict) -> None:
        """A /player/status sample: state changes as events, jitter/latency/inference p99s as plots."""
        if not isinstance(status, dict):
            return
        self._set_time(time_s)
        state = status.get('state')
        if state != self._player_state:
            self._player_state = state
            rr.log('events/player', rr.TextLog(f'player state: {state}'), recording=self.rec)
        for group, key in PLAYER_SERIES:
            value = status.get(group, {}).get(key) if isinstance(status.get(group), dict) else None
            if isinstance(value, (int, float)) and math.isfinite(value):
                rr.log(f'plots/player/{group}_{key}', rr.Scalars(float(value)), recording=self.rec)

    # --- sending -----------------------------------------------------------------------------------------
    def flush(self) -> None:
        """Send what was kept since the last flush: the arm's frames, the ball, the hand's wrench, the plots
        (one batch per entity)."""
        self._send_arm()
        self._send_balls()
        self._send_hand()
        for buffer, entity in (
            (self._measured, 'position/measured'),
            (self._commanded, 'position/commanded'),
            (self._speed, 'speed/joints'),
        ):
            if len(buffer):
                times, values = buffer.take()
                rr.send_columns(
                    f'plots/{entity}',
                    indexes=[rr.TimeColumn(TIMELINE, duration=times)],
                    columns=rr.Scalars.columns(scalars=values),
                    recording=self.rec,
                )

    def _send_hand(self) -> None:
        """The hand's wrench (the reading less the paddle's weight, hand_wrench.py) as two arrows from tool0
        while a hand pushes (HAND_FORCE_SHOWN_N or more); none otherwise."""
        if self._wrench is None or self.latest_q is None:
            return
        (time_s, read), self._wrench = self._wrench, None
        reading = np.asarray(read(), dtype=float)
        if reading.shape != (6,) or not np.all(np.isfinite(reading)):
            return
        _, tool_rotation = self._tool_poses.poses(self.latest_q)
        hand = hand_wrench_in_tool(reading, self.tool_load, tool_rotation[0], self._gravity_base_m_s2)
        force_n, torque_nm = float(np.linalg.norm(hand[:3])), float(np.linalg.norm(hand[3:]))
        shown = force_n >= HAND_FORCE_SHOWN_N
        if not shown and not self._hand_shown:
            return
        self._set_time(time_s)
        self._hand_shown = shown
        if not shown:  # the hand let go: the arrows go
            rr.log('cell/hand_wrench', rr.Arrows3D(vectors=np.zeros((0, 3))), recording=self.rec)
            return
        self.counts['hand_shown'] += 1
        rr.log(
            'cell/hand_wrench',
            rr.Arrows3D(
                vectors=[hand[:3] * FORCE_SCALE_M_PER_N, hand[3:] * TORQUE_SCALE_M_PER_NM],
                origins=[(0, 0, 0)] * 2,
                colors=[FORCE_RGB, TORQUE_RGB],
                radii=[0.006, 0.004],
                labels=[f'hand {force_n:.1f} N', f'{torque_nm:.2f} N m'],
            ),
            recording=self.rec,
        )

    def _send_arm(self) -> None:
        """The arm's frames as columns, a batch per joint; the paddle's path through them."""
        if not len(self._arm_frames):
            return
        times, qs = self._arm_frames.take()
        index = [rr.TimeColumn(TIMELINE, duration=times)]
        n = len(times)
        # One entity per joint: an entity holds one transform between two frames. Every row carries the whole
        # transform: rerun resolves a Transform3D from its last row alone (a row of rotations only would drop
        # the translation and the frames).
        for joint, rotations in zip(self.robot_state.moving_joints, joint_rotations(self.robot_state, qs)):
            rr.send_columns(
                f'tf/{joint.name}',
                indexes=index,
                columns=rr.Transform3D.columns(
                    translation=np.broadcast_to(joint.origin_xyz_m, (n, 3)),
                    quaternion=rotations,
                    parent_frame=[joint.parent] * n,
                    child_frame=[joint.child] * n,
                ),
                recording=self.rec,
            )
        centres, _ = self._paddle_centre_poses.poses(qs)
        for time_s, centre in zip(times, centres):
            self._paddle_path.add(time_s, self._to_world(centre))
        # The path as it stands at the batch's last frame (a strip per frame would cost a log call each).
        self._set_time(float(times[-1]))
        rr.log(
            'cell/paddle_path',
            rr.LineStrips3D([self._paddle_path.points()], colors=[PADDLE_PATH_RGB], radii=0.004),
            recording=self.rec,
        )

    def _send_balls(self) -> None:
        """The ball's kept positions as one column; its trail as it stands at the last of them."""
        if not len(self._balls):
            return
        times, positions = self._balls.take()
        rr.send_columns(
            'cell/ball',
            indexes=[rr.TimeColumn(TIMELINE, duration=times)],
            columns=rr.Points3D.columns(
                positions=positions, radii=[world_spec.BALL_RADIUS_M] * len(times), colors=[BALL_RGB] * len(times)
            ),
            recording=self.rec,
        )
        for time_s, position in zip(times, positions):
            self._ball_trail.add(time_s, position)
        self._set_time(float(times[-1]))
        rr.log(
            'cell/ball_trail',
            rr.LineStrips3D([self._ball_trail.points()], colors=[BALL_RGB], radii=0.003),
            recording=self.rec,
        )

    def _to_world(self, point_in_base_m: np.ndarray) -> np.ndarray:
        return self._base_position_m + rotate(self._base_rotation_xyzw, point_in_base_m)


def stamp_seconds(header) -> float:
    """A std_msgs/Header's stamp in seconds."""
    return _stamp_s(header.stamp.sec, header.stamp.nanosec)
