"""What the viewer draws, from plain values (no ROS here): the cell in 3D and the time plots, in rerun.

One CellView is fed by the live node (viewer_node.py) and by a bag (bag_view.py) alike. Every sample carries
its message time (header stamps: the cell's simulated time with ur5_sim), which is the `time` timeline, so a
live session and a recorded clip look the same and can be scrubbed. High-rate streams are decimated by
message time (decimate.py) and plotted in batches at each flush(): the viewer costs the graph little and
never falls behind 500 Hz joint states.

Entities
  /robot/...            the UR5 + paddle URDF (rerun's URDF loader: meshes and fixed joints), its frames
                        named after the links; /tf the moving joints, /tf_static world -> base_link
  /cell/table, /cell/net, /cell/ball, /cell/ball_trail, /cell/paddle_path, /cell/hand_force  (frame world)
  /plots/position/<joint>/{measured,commanded}, /plots/speed/<joint>/{speed,limit}, /plots/player/*,
  /events (rally events, player state changes)
"""
from __future__ import annotations

import math
import pathlib
import tempfile

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from stylepong_description import robot_model as rm
from stylepong_description.robot_state import RobotState, quaternion_from_matrix, rotate
from stylepong_sim import world_spec as ws
from stylepong_viz.decimate import ColumnBuffer, Decimator, Trail

FRAME_WORLD = 'world'
TIMELINE = 'time'
ARM_RATE_HZ = 30.0         # 3D arm updates: a browser shows ~30-60 frames a second
PLOT_RATE_HZ = 100.0       # plot points per second per series: a 500 Hz stream decimated 5x
TRAIL_S = 1.5              # ball trail and paddle path length (message time)
FORCE_SCALE_M_PER_N = 0.02   # the hand force arrow: 10 N draws 0.2 m
TABLE_RGB = (20, 70, 150)
NET_RGB = (225, 210, 140)   # cream: told apart from the grey arm in screenshots
BALL_RGB = (255, 140, 0)
PADDLE_PATH_RGB = (200, 40, 40)
FORCE_RGB = (230, 30, 200)
BACKGROUND_RGB = (28, 30, 34)
PLAYER_SERIES = (('period_ms', 'jitter_p99'), ('latency_ms', 'p99'), ('inference_ms', 'p50'))
# The 3D view's camera: behind the robot on the table's long axis, looking down the table. The robot's base
# is then on the view's vertical centre line: world +y to the left of it, -y to the right.
EYE_POSITION_M = (ws.ROBOT_BASE_POSITION_M[0] - 1.3, 0.0, ws.TABLE_HEIGHT_M + 0.75)
EYE_TARGET_M = (ws.ROBOT_BASE_POSITION_M[0] + 0.8, 0.0, ws.TABLE_HEIGHT_M + 0.05)
PLOT_WINDOW_S = 10.0       # the plots show the last 10 s before the time cursor


def blueprint() -> rrb.Blueprint:
    """The page: the cell in 3D across the top, the time plots below it, panels collapsed."""
    cell = rrb.Spatial3DView(
        name='cell', origin='/', contents=['/robot/**', '/cell/**'],
        spatial_information=rrb.SpatialInformation(target_frame=FRAME_WORLD),
        background=BACKGROUND_RGB, line_grid=False,
        eye_controls=rrb.EyeControls3D(kind=rrb.Eye3DKind.Orbital, position=EYE_POSITION_M,
                                       look_target=EYE_TARGET_M, eye_up=(0.0, 0.0, 1.0)))
    window = rrb.TimeRange(start=rrb.TimeRangeBoundary.cursor_relative(seconds=-PLOT_WINDOW_S),
                           end=rrb.TimeRangeBoundary.cursor_relative())

    def plot(name: str, origin: str) -> rrb.TimeSeriesView:
        return rrb.TimeSeriesView(name=name, origin=origin,
                                  time_ranges=rrb.VisibleTimeRange(TIMELINE, start=window.start, end=window.end))

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
    """Logs the cell into a rerun recording: static scene once, then samples as they come."""

    def __init__(self, recording: rr.RecordingStream, arm_rate_hz: float = ARM_RATE_HZ,
                 plot_rate_hz: float = PLOT_RATE_HZ):
        self.rec = recording
        urdf = rm.urdf_xml_for_display()
        self.robot_state = RobotState(urdf)
        self.joint_names = self.robot_state.moving_joint_names
        self._index = {n: k for k, n in enumerate(self.joint_names)}
        self._arm = Decimator(arm_rate_hz)
        self._plot_joint = Decimator(plot_rate_hz)
        self._plot_force = Decimator(arm_rate_hz)
        self._measured = ColumnBuffer(len(self.joint_names))
        self._speed = ColumnBuffer(len(self.joint_names))
        self._commanded = ColumnBuffer(len(self.joint_names))
        self._ball_trail = Trail(TRAIL_S)
        self._paddle_path = Trail(TRAIL_S)
        self._player_state = None
        self.latest_time_s = 0.0
        self.counts = {'joint_states': 0, 'arm_frames': 0}
        rotation, position = ws.robot_base_pose()
        self._base_rotation_xyzw = quaternion_from_matrix(rotation)
        self._base_position_m = np.asarray(position, dtype=float)
        self._log_static(urdf)

    # --- the scene that does not move -----------------------------------------------------------------
    def _log_static(self, urdf: str) -> None:
        rec = self.rec
        # rerun's URDF loader reads a file: the same XML the cell publishes on /robot_description.
        with tempfile.TemporaryDirectory(prefix='stylepong_viz_') as folder:
            path = pathlib.Path(folder) / 'ur5_paddle.urdf'
            path.write_text(urdf.replace('file://', ''))
            rr.urdf.UrdfTree.from_file_path(path, entity_path_prefix='robot').log_urdf_to_recording(rec)
        rr.log('tf_static/world_base', rr.Transform3D(
            translation=self._base_position_m, quaternion=self._base_rotation_xyzw,
            parent_frame=FRAME_WORLD, child_frame=rm.BASE_FRAME), static=True, recording=rec)
        world = rr.CoordinateFrame(FRAME_WORLD)
        table_half = (ws.HALF_LENGTH_M, ws.HALF_WIDTH_M, ws.TABLE_THICKNESS_M / 2.0)
        rr.log('cell/table', rr.Boxes3D(centers=[(0.0, 0.0, ws.TABLE_HEIGHT_M - ws.TABLE_THICKNESS_M / 2.0)],
                                        half_sizes=[table_half], colors=[TABLE_RGB], fill_mode='solid'),
               world, static=True, recording=rec)
        low, high = np.array(ws.NET_BOX_LOW_M), np.array(ws.NET_BOX_HIGH_M)
        rr.log('cell/net', rr.Boxes3D(centers=[(low + high) / 2.0], half_sizes=[(high - low) / 2.0], colors=[NET_RGB],
                                      fill_mode='solid'), world, static=True, recording=rec)
        for name in ('ball', 'ball_trail', 'paddle_path', 'hand_force'):
            rr.log(f'cell/{name}', world, static=True, recording=rec)
        limits = [j.velocity_limit for j in self.robot_state.moving_joints]
        for name, limit in zip(self.joint_names, limits):
            rr.log(f'plots/speed/{name}/limit', rr.SeriesLines(colors=[(150, 150, 150)], names=[f'{name} limit']),
                   static=True, recording=rec)
            rr.log(f'plots/position/{name}/commanded', rr.SeriesLines(names=[f'{name} commanded']),
                   static=True, recording=rec)
        self._velocity_limits = np.array(limits)

    # --- samples ----------------------------------------------------------------------------------------
    def _set_time(self, time_s: float) -> None:
        self.latest_time_s = max(self.latest_time_s, time_s) if time_s >= self.latest_time_s - 1.0 else time_s
        rr.set_time(TIMELINE, duration=time_s, recording=self.rec)

    def urdf_order(self, names, values) -> np.ndarray | None:
        """values (named by names) in URDF joint order; None unless all six are there and finite."""
        out = np.full(len(self.joint_names), np.nan)
        for name, value in zip(names, values):
            k = self._index.get(name)
            if k is not None:
                out[k] = value
        return out if np.all(np.isfinite(out)) else None

    def on_joint_state(self, time_s: float, names, positions, velocities) -> None:
        """A /joint_states sample: the arm (decimated to arm_rate_hz) and the position/speed plots."""
        self.counts['joint_states'] += 1
        q = self.urdf_order(names, positions)
        if q is None:
            return
        if self._plot_joint.due(time_s):
            self._measured.add(time_s, q)
            qd = self.urdf_order(names, velocities) if len(velocities) == len(names) else None
            if qd is not None:
                self._speed.add(time_s, np.abs(qd))
        if self._arm.due(time_s):
            self.counts['arm_frames'] += 1
            self._set_time(time_s)
            transforms = self.robot_state.moving_transforms(q)
            # One entity per joint: an entity holds one transform between two frames.
            for name, t in zip(self.joint_names, transforms):
                rr.log(f'tf/{name}', rr.Transform3D(translation=t.translation_m, quaternion=t.rotation_xyzw,
                                                    parent_frame=t.parent, child_frame=t.child), recording=self.rec)
            centre, _ = self.robot_state.link_pose_in_base(rm.PADDLE_CENTRE_FRAME, q)
            self._paddle_path.add(time_s, self._to_world(centre))
            rr.log('cell/paddle_path', rr.LineStrips3D([self._paddle_path.points()], colors=[PADDLE_PATH_RGB],
                                                       radii=0.004), recording=self.rec)

    def _to_world(self, point_in_base_m: np.ndarray) -> np.ndarray:
        return self._base_position_m + rotate(self._base_rotation_xyzw, point_in_base_m)

    def on_command(self, time_s: float, positions) -> None:
        """A /forward_position_controller/commands sample (URDF order); wrong length or NaN: not drawn."""
        if len(positions) == len(self.joint_names) and all(map(math.isfinite, positions)):
            self._commanded.add(time_s, positions)

    def on_ball(self, time_s: float, position_m) -> None:
        """A /ball/state sample: the ball and its trail."""
        self._set_time(time_s)
        self._ball_trail.add(time_s, position_m)
        rr.log('cell/ball', rr.Points3D([position_m], radii=ws.BALL_RADIUS_M, colors=[BALL_RGB]), recording=self.rec)
        rr.log('cell/ball_trail', rr.LineStrips3D([self._ball_trail.points()], colors=[BALL_RGB], radii=0.003),
               recording=self.rec)

    def on_wrench(self, time_s: float, frame: str, force_n) -> None:
        """A wrench on the tool (the F/T sensor while teaching): its force as an arrow from the frame's origin."""
        if not self._plot_force.due(time_s) or not all(map(math.isfinite, force_n)):
            return
        self._set_time(time_s)
        vector = np.asarray(force_n, dtype=float) * FORCE_SCALE_M_PER_N
        rr.log('cell/hand_force', rr.Arrows3D(origins=[(0.0, 0.0, 0.0)], vectors=[vector], colors=[FORCE_RGB],
                                              radii=0.006), rr.CoordinateFrame(frame or rm.TOOL_FRAME),
               recording=self.rec)

    def on_rally_event(self, time_s: float, name: str, reason: str, success: bool, position_m) -> None:
        self._set_time(time_s)
        text = f'{name} at ({position_m[0]:.2f}, {position_m[1]:.2f}, {position_m[2]:.2f}) m'
        if name == 'RALLY_END':
            text += f': {"returned" if success else "missed"} ({reason})'
            self._ball_trail.clear()
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

    def flush(self) -> None:
        """Send the plot points gathered since the last flush, one batch per series."""
        for buffer, kind in ((self._measured, 'position/{}/measured'), (self._commanded, 'position/{}/commanded'),
                             (self._speed, 'speed/{}/speed')):
            if not len(buffer):
                continue
            times, values = buffer.take()
            for k, name in enumerate(self.joint_names):
                rr.send_columns(f'plots/{kind.format(name)}', indexes=[rr.TimeColumn(TIMELINE, duration=times)],
                                columns=rr.Scalars.columns(scalars=values[:, k]), recording=self.rec)
            if buffer is self._speed:
                limits = np.broadcast_to(self._velocity_limits, values.shape)
                for k, name in enumerate(self.joint_names):
                    rr.send_columns(f'plots/speed/{name}/limit', indexes=[rr.TimeColumn(TIMELINE, duration=times)],
                                    columns=rr.Scalars.columns(scalars=limits[:, k]), recording=self.rec)


def stamp_seconds(header) -> float:
    """A std_msgs/Header's stamp in seconds."""
    return _stamp_s(header.stamp.sec, header.stamp.nanosec)
