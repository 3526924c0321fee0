"""virtual_teacher drags the simulated arm through a rightward stroke while the recorder records it:
ur5_sim + drag_teach + recorder + virtual_teacher through `ros2 run`, as tools/record_demos.sh runs them: the
cell at a quarter of real time, drag_teach and the teacher on its clock, so that a loaded machine stays in step
(at half of real time a loaded machine let the arm lag and catch up: a forward take peaked at 1.02 m/s, its
recording 0.55).
The recorded clip is checked against the take the teacher's seed gives (teacher.sample_variation)."""

import pathlib

import numpy as np
import pytest
from rosbags.highlevel import AnyReader

from stylepong_common.node_process import NodeProcess, wait_until
from stylepong_description import robot_model
from stylepong_sim import world_spec
from stylepong_sim.teaching.teacher import CellKinematics, StrokePath, TeacherConfig, sample_variation

KIN = CellKinematics()
CENTRE = KIN.frame_id(robot_model.PADDLE_CENTRE_FRAME)
TOOL = KIN.frame_id(robot_model.TOOL_FRAME)
HOME_CENTRE = KIN.pose(np.array(world_spec.HOME_JOINT_POSITIONS_RAD), CENTRE).translation
SEED = 0  # the node's default take
# The fastest take: the chain (teacher, drag_teach, cell, recorder) is the same for every swing, all three are
# dragged through the FDCC without ROS in stylepong_fdcc's test_teacher_drags_fdcc.py, and test_teacher.py
# tells them apart. Each take here costs the suite 18 s.
SWING = 'rightward'


def read_clip(bag: pathlib.Path):
    """Header times (s), positions and velocities (URDF order) of the clip's joint states."""
    with AnyReader([bag]) as reader:
        connections = [c for c in reader.connections if c.topic == '/joint_states']
        rows = []
        for connection, _, raw in reader.messages(connections=connections):
            msg = reader.deserialize(raw, connection.msgtype)
            index = [list(msg.name).index(n) for n in robot_model.JOINT_NAMES]
            rows.append(
                (
                    msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9,
                    np.asarray(msg.position)[index],
                    np.asarray(msg.velocity)[index],
                )
            )
    return np.array([r[0] for r in rows]), np.array([r[1] for r in rows]), np.array([r[2] for r in rows])


def tool_speeds(times_s: np.ndarray, q: np.ndarray, window_s: float = 0.02) -> np.ndarray:
    """tool0 speed (m/s) over windows of header time: the stroke's motion, not the servo's 500 Hz shake."""
    positions = np.array([KIN.pose(a, TOOL).translation for a in q])
    ahead = np.searchsorted(times_s, times_s + window_s)
    valid = ahead < len(times_s)
    return np.linalg.norm(positions[ahead[valid]] - positions[valid], axis=1) / (times_s[ahead[valid]] - times_s[valid])


@pytest.mark.slow  # over 20 s on the 2-core machine: .ci/run runs it, `make test` skips it
def test_the_teacher_drags_and_records_a_stroke(ros_env, tmp_path):
    sim = NodeProcess('stylepong_sim', 'ur5_sim', params={'real_time_factor': 0.25}).start()
    drag = NodeProcess('stylepong_fdcc', 'drag_teach', params={'use_sim_time': True}).start()
    recorder = NodeProcess('stylepong_recording', 'recorder', params={'output_dir': str(tmp_path)}).start()
    limits = robot_model.joint_limits()
    try:
        teacher = NodeProcess(
            'stylepong_sim', 'virtual_teacher', params={'swing': SWING, 'seed': SEED, 'use_sim_time': True}
        ).start()
        try:
            assert wait_until(lambda: not teacher.running(), 90.0), f'{SWING}: the teacher never finished'
        finally:
            code = teacher.stop()
        assert code == 0, f'{SWING} teacher failed:\n{teacher.output()[-3000:]}\n{recorder.output()[-2000:]}'
        bags = sorted(tmp_path.glob(f'{SWING}_*'))
        assert len(bags) == 1, f'{SWING}: bags {bags}'
        assert f'label: {SWING}' in (bags[0] / 'metadata.yaml').read_text()
        times, q, _ = read_clip(bags[0])
        duration_s = times[-1] - times[0]
        path = StrokePath(SWING, TeacherConfig(), HOME_CENTRE, sample_variation(SWING, SEED))
        assert path.stroke_s <= duration_s <= path.duration_s + 0.5, f'{SWING}: a {duration_s:.2f} s clip'
        assert np.all(q > limits.lower_rad) and np.all(q < limits.upper_rad)
        speeds = tool_speeds(times, q)
        assert 0.3 < speeds.max() < 1.0, f'{SWING}: peak tool speed {speeds.max():.2f} m/s'
        assert speeds[0] < 0.05 and speeds[-1] < 0.05, f'{SWING}: the clip does not start and end at rest'
        # The paddle went back, then forwards through the take's hitting point.
        centres = np.array([KIN.pose(a, CENTRE).translation for a in q])
        miss = np.min(np.linalg.norm(centres - path.hit, axis=1))
        assert miss < 0.04, f'{SWING}: the paddle passed {miss * 100:.1f} cm from the hitting point'
        assert np.min(np.linalg.norm(centres - path.back, axis=1)) < 0.04
        assert np.linalg.norm(centres[-1] - path.follow) < 0.04
    finally:
        recorder.stop()
        drag.stop()
        sim.stop()
