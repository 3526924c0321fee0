"""Video of the PyBullet cell: its state drawn by the MuJoCo scene's renderer (rendering only, no physics).

The cell's video (video.VideoRecorder) renders MuJoCo's scene; the PyBullet cell has the same robot and
world, so its joint positions and ball are copied into an MjData of that scene and drawn from there,
with the same cameras and looks as ur5_sim's. Nothing of MuJoCo's dynamics runs.
    view = MirroredScene(); recorder = VideoRecorder(view.model, 'rally.mp4')
    recorder.capture(view.show(bullet_cell))
"""

from __future__ import annotations

import mujoco

from stylepong_sim.cells import scene


class MirroredScene:
    """The MuJoCo scene posed like a cell (any object with joint_positions_rad and ball_position_m)."""

    def __init__(self):
        self.model = scene.build_model()
        self.data = mujoco.MjData(self.model)
        self._ball_mocap = self.model.body_mocapid[self.model.body(scene.BALL_BODY).id]

    def show(self, cell) -> mujoco.MjData:
        """The scene's data posed as `cell` is now (arm joints first in qpos, as scene.build_model makes them)."""
        self.data.qpos[:6] = cell.joint_positions_rad
        ball = cell.ball_position_m
        self.data.mocap_pos[self._ball_mocap] = scene.BALL_PARKING_POSITION_M if ball is None else ball
        mujoco.mj_kinematics(self.model, self.data)
        return self.data
