"""A demonstration recorded on the PyBullet cell: ur5_bullet + drag_teach + recorder + virtual_teacher through
`ros2 run`, as tools/record_demos.sh runs them on ur5_sim. The teacher's hand wrench reaches Bullet's arm
through /sim/hand_wrench, drag_teach reads it from the cell's F/T topic and moves the arm, and the recorder
writes the clip: it starts and ends at rest and the paddle passes the take's hitting point."""

import numpy as np
import pytest

from stylepong_common.node_process import NodeProcess, wait_until
from stylepong_description import robot_model
from stylepong_sim.teaching.teacher import StrokePath, TeacherConfig, sample_variation
from tests.test_virtual_teacher import CENTRE, HOME_CENTRE, KIN, SEED, read_clip, tool_speeds


@pytest.mark.slow  # 21 s on the 2-core machine: .ci/run runs it, `make test` skips it
def test_the_teacher_records_a_stroke_on_the_pybullet_cell(ros_env, tmp_path):
    swing = 'forward'
    sim = NodeProcess('stylepong_sim', 'ur5_bullet', params={'real_time_factor': 0.25}).start()
    drag = NodeProcess('stylepong_fdcc', 'drag_teach', params={'use_sim_time': True}).start()
    recorder = NodeProcess('stylepong_recording', 'recorder', params={'output_dir': str(tmp_path)}).start()
    try:
        teacher = NodeProcess(
            'stylepong_sim', 'virtual_teacher', params={'swing': swing, 'seed': SEED, 'use_sim_time': True}
        ).start()
        try:
            assert wait_until(lambda: not teacher.running(), 120.0), 'the teacher never finished'
        finally:
            code = teacher.stop()
        assert code == 0, f'teacher failed:\n{teacher.output()[-3000:]}\n{sim.output()[-2000:]}'
    finally:
        recorder.stop()
        drag.stop()
        sim.stop()
    assert 'UR5 cell ready (pybullet' in sim.output()
    bags = sorted(tmp_path.glob(f'{swing}_*'))
    assert len(bags) == 1, bags
    times, q, _ = read_clip(bags[0])
    path = StrokePath(swing, TeacherConfig(), HOME_CENTRE, sample_variation(swing, SEED))
    assert path.stroke_s <= times[-1] - times[0] <= path.duration_s + 0.5
    limits = robot_model.joint_limits()
    assert np.all(q > limits.lower_rad) and np.all(q < limits.upper_rad)
    speeds = tool_speeds(times, q)
    assert 0.3 < speeds.max() < 1.0 and speeds[0] < 0.05 and speeds[-1] < 0.05
    centres = np.array([KIN.pose(a, CENTRE).translation for a in q])
    assert np.min(np.linalg.norm(centres - path.hit, axis=1)) < 0.04
