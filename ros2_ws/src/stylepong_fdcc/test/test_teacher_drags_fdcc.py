"""The virtual teacher dragging drag_teach's FDCC controller on a perfect servo (no ROS, no MuJoCo)."""

import numpy as np
import pinocchio as pin
import pytest

from stylepong_description import robot_model
from stylepong_fdcc.drag_teach_controller import DragTeachController
from stylepong_fdcc.fdcc_config import FdccConfig
from stylepong_fdcc.wrench_conditioning import gravity_wrench_on_tool, tool_load_from_model
from stylepong_sim import world_spec
from stylepong_sim.teaching.teacher import CellKinematics, TeacherConfig, VirtualTeacher

HOME = np.array(world_spec.HOME_JOINT_POSITIONS_RAD)
KIN = CellKinematics()


def singularity_margins(q: np.ndarray) -> tuple[float, float]:
    """Smallest singular value of tool0's Jacobian, and wrist_1's distance (m) from the base's axis."""
    model, data = KIN.model, KIN.data
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    jacobian = pin.getFrameJacobian(model, data, KIN.frame_id(robot_model.TOOL_FRAME), pin.LOCAL_WORLD_ALIGNED)
    wrist = data.oMf[KIN.frame_id('wrist_1_link')].translation
    return float(np.linalg.svd(jacobian, compute_uv=False)[-1]), float(np.hypot(wrist[0], wrist[1]))


class DragLoop:
    """drag_teach's controller on an arm that follows its commands exactly; the hand acts at tool0."""

    def __init__(self, dt_s: float = 0.002):
        self.kin = KIN
        self.tool = KIN.frame_id(robot_model.TOOL_FRAME)
        self.load = tool_load_from_model(KIN.model)
        self.controller = DragTeachController(FdccConfig(nominal_period_s=dt_s))
        self.q, self.qdot, self.t, self.dt = HOME.copy(), np.zeros(6), 0.0, dt_s
        for _ in range(100):  # drag_teach runs (and tares) before the teacher takes the paddle
            self.step(np.zeros(6))

    def step(self, hand_world: np.ndarray) -> None:
        tool = self.kin.pose(self.q, self.tool)
        rotation_base = self.kin.base.rotation.T @ tool.rotation
        sensor = np.concatenate([tool.rotation.T @ hand_world[:3], tool.rotation.T @ hand_world[3:]])
        sensor += gravity_wrench_on_tool(self.load, rotation_base, np.array(KIN.model.gravity.linear))
        self.controller.on_joint_positions(self.q, self.t)
        self.controller.on_wrench(sensor, self.t)
        command = self.controller.tick(self.t).command
        if command is not None:
            self.qdot, self.q = (command - self.q) / self.dt, command
        self.t += self.dt

    def teach(self, swing: str, config: TeacherConfig):
        teacher = VirtualTeacher(swing, config)
        record, start = [], None
        while self.t < 20.0:
            wrench = teacher.update(self.t, self.q, self.qdot)
            if teacher.phase == 'ready':
                teacher.begin_stroke(self.t)
                start = self.t
            if teacher.phase == 'finished':
                teacher.release()
                assert np.all(teacher.update(self.t, self.q, self.qdot) == 0.0)
                return teacher, record, self.t - start
            self.step(wrench)
            if teacher.phase == 'stroke':
                record.append(
                    (
                        self.q.copy(),
                        teacher.via_point(self.t),
                        np.linalg.norm(self.kin.twist(self.q, self.qdot, self.tool)[:3]),
                    )
                )
        raise AssertionError(f'the {swing} stroke did not finish (phase {teacher.phase})')


# Per blade pitch: how far the paddle centre may lag its via-point, and the wrist's least distance from the
# base's axis, where the shoulder is singular. The upright strokes keep 0.1 m from the axis and lag under
# 0.03 m. The opened blade (the default, the shipped clips) brings the wrist back towards the base: the
# forward and leftward strokes pass within 0.016 m of the axis and the leftward one lags up to 0.037 m
# there (docs/DESIGN.md, Known limits). Tracked without a flip, as the other checks show, but with little
# to spare.
@pytest.mark.parametrize('blade_pitch_rad, tracking_m, wrist_clearance_m', [(0.0, 0.03, 0.1), (0.6, 0.045, 0.01)])
def test_the_teacher_drags_the_fdcc_arm_through_each_stroke_within_limits(
    blade_pitch_rad, tracking_m, wrist_clearance_m
):
    loop = DragLoop()
    config = TeacherConfig(blade_pitch_rad=blade_pitch_rad)
    centre_id = KIN.frame_id(robot_model.PADDLE_CENTRE_FRAME)
    limits = robot_model.joint_limits()
    for swing in ('forward', 'leftward', 'rightward', 'forward'):  # each starts where the last one ended
        teacher, record, duration_s = loop.teach(swing, config)
        assert 1.5 <= duration_s <= 3.5
        errors = [np.linalg.norm(KIN.pose(q, centre_id).translation - via.position_m) for q, via, _ in record]
        assert max(errors) < tracking_m, swing
        assert max(speed for _, _, speed in record) < 1.0
        joints = np.array([q for q, _, _ in record])
        assert np.all(joints > limits.lower_rad + 0.05) and np.all(joints < limits.upper_rad - 0.05)
        # Clear of the singularities where a dragged arm flips: elbow bent, wrist away from the base axis.
        assert np.min(np.abs(joints[:, 2])) > 1.0, swing
        assert min(singularity_margins(q)[1] for q in joints[::10]) > wrist_clearance_m, swing
        # The paddle ends the stroke where the follow-through is.
        assert np.linalg.norm(KIN.pose(loop.q, centre_id).translation - teacher.path.follow) < 0.03
