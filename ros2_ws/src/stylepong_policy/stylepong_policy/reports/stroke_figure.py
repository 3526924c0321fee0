"""The paper's Fig. 2: a PPO stroke, an AMP stroke and a demonstration, seven frames each, as a 3x7 grid.

The two policies are shown on the same ball: a seed serves the same balls whatever the actor, so the
ball (seed, environment) is the first one of the chosen direction that both returned (failing that,
the first of that direction). The reference row is the demonstration of that direction (an original
clip, speed factor 1) nearest to the AMP stroke by DTW. Frames are rendered with the cell's MuJoCo
scene (stylepong_sim.cells.scene; kinematics only: joint positions and the ball set each frame) from one
camera: a policy's seven frames are evenly spaced from SWING_LEAD_S before the paddle's first contact
to the stroke's end (0.3 s after it), the clip's over the whole clip. The default camera,
FIGURE_CAMERA, is a free camera close to the robot (three-quarter view from the robot's left front,
where the arm fills the frame); any of the scene's named cameras can be used instead.
"""

from __future__ import annotations

import os
import pathlib
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from stylepong_policy import png
from stylepong_policy.evaluation import strokes, style_metrics

FRAMES_PER_ROW = 7
SWING_LEAD_S = 0.45  # the back-swing starts about this long before a 5 m/s ball is met
FRAME_SIZE_PX = (320, 240)  # width, height of one rendered frame
FIGURE_CAMERA = 'figure'
# The free camera: looking at a point above the paddle's home pose, from 1.7 m away, 135 degrees of
# azimuth (from the robot's left front) and 12 degrees down.
FIGURE_CAMERA_LOOKAT_M = (-1.6, 0.05, 1.1)
FIGURE_CAMERA_DISTANCE_M = 1.7
FIGURE_CAMERA_AZIMUTH_DEG = 135.0
FIGURE_CAMERA_ELEVATION_DEG = -12.0
CAMERAS = (FIGURE_CAMERA, 'overview', 'robot_view')  # ours and the scene's


@dataclass
class FigureRow:
    """One row of the figure: a label, and the joint positions, ball and time of its seven frames."""

    label: str
    joint_positions_rad: np.ndarray  # [7, 6]
    ball_position_m: np.ndarray | None  # [7, 3]; None: no ball (a demonstration has none)
    times_s: np.ndarray  # [7] time of each frame relative to the paddle's contact (or the clip start)


def choose_ball(
    first: Sequence[strokes.Stroke], second: Sequence[strokes.Stroke], direction: str
) -> tuple[int, int] | None:
    """(seed, ball) of the first ball of `direction` that both actors returned, else the first of that
    direction; None when no ball has it. Both lists are strokes of the same seeds and balls."""
    first_by_key = {(s.seed, s.ball): s for s in first}
    second_by_key = {(s.seed, s.ball): s for s in second}
    candidates = [key for key, s in first_by_key.items() if s.direction == direction and key in second_by_key]
    both = [key for key in candidates if first_by_key[key].success and second_by_key[key].success]
    chosen = both or candidates
    return chosen[0] if chosen else None


def stroke_frames(stroke: strokes.Stroke, rate_hz: float, count: int = FRAMES_PER_ROW) -> np.ndarray:
    """Indices of `count` frames spread over the swing: SWING_LEAD_S before the first contact to the end."""
    last = len(stroke.joint_positions_rad) - 1
    contact = stroke.hit_frame if stroke.hit_frame != strokes.NO_FRAME else last
    first = max(0, contact - int(round(SWING_LEAD_S * rate_hz)))
    return np.round(np.linspace(first, last, count)).astype(int)


def policy_row(label: str, stroke: strokes.Stroke, rate_hz: float) -> FigureRow:
    """The figure row of a policy stroke, timed relative to the paddle's first contact."""
    frames = stroke_frames(stroke, rate_hz)
    contact = stroke.hit_frame if stroke.hit_frame != strokes.NO_FRAME else frames[-1]
    return FigureRow(
        label=label,
        joint_positions_rad=stroke.joint_positions_rad[frames],
        ball_position_m=stroke.ball_position_m[frames],
        times_s=(frames - contact) / rate_hz,
    )


def reference_row(label: str, dataset, direction: str, near: strokes.Stroke) -> FigureRow:
    """The original clip of `direction` nearest (DTW) to the stroke `near`, seven frames over its length."""
    originals = style_metrics.reference_clips(dataset, direction, speed_factors=[1])
    if not originals:
        raise ValueError(f'the reference dataset has no original clip labelled {direction!r}')
    match = style_metrics.nearest_reference(near.joint_positions_rad, originals)
    q = dataset.clip(match.clip).q
    frames = np.round(np.linspace(0, len(q) - 1, FRAMES_PER_ROW)).astype(int)
    return FigureRow(
        label=f'{label} (clip {match.clip}, x1)',
        joint_positions_rad=q[frames],
        ball_position_m=None,
        times_s=frames / dataset.rate_hz,
    )


def _camera(name: str):
    """The figure's free camera, or the name of one of the scene's cameras."""
    import mujoco

    if name != FIGURE_CAMERA:
        return name
    camera = mujoco.MjvCamera()
    camera.type = mujoco.mjtCamera.mjCAMERA_FREE
    camera.lookat[:] = FIGURE_CAMERA_LOOKAT_M
    camera.distance = FIGURE_CAMERA_DISTANCE_M
    camera.azimuth = FIGURE_CAMERA_AZIMUTH_DEG
    camera.elevation = FIGURE_CAMERA_ELEVATION_DEG
    return camera


def render_rows(rows: Sequence[FigureRow], camera: str = FIGURE_CAMERA) -> list[list[np.ndarray]]:
    """RGB images [row][frame] of the rows in the cell's scene, all from one camera."""
    import mujoco

    from stylepong_description.robot_model import JOINT_NAMES
    from stylepong_sim.cells import scene

    model = scene.build_model()
    data = mujoco.MjData(model)
    qpos_index = [model.jnt_qposadr[model.joint(name).id] for name in JOINT_NAMES]
    ball_mocap = model.body_mocapid[model.body(scene.BALL_BODY).id]
    width, height = FRAME_SIZE_PX
    renderer = mujoco.Renderer(model, height, width)
    view = _camera(camera)
    images = []
    try:
        for row in rows:
            row_images = []
            for k in range(len(row.joint_positions_rad)):
                data.qpos[qpos_index] = row.joint_positions_rad[k]
                data.mocap_pos[ball_mocap] = (
                    scene.BALL_PARKING_POSITION_M if row.ball_position_m is None else row.ball_position_m[k]
                )
                mujoco.mj_forward(model, data)
                renderer.update_scene(data, camera=view)
                row_images.append(np.array(renderer.render()))
            images.append(row_images)
    finally:
        renderer.close()
    return images


def save_grid(
    path: str | os.PathLike, rows: Sequence[FigureRow], images: Sequence[Sequence[np.ndarray]], title: str
) -> pathlib.Path:
    """Save the rendered frames as a grid, one row per FigureRow; returns the path."""
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    path = pathlib.Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    n_rows, n_cols = len(rows), FRAMES_PER_ROW
    figure, axes = plt.subplots(n_rows, n_cols, figsize=(2.3 * n_cols, 1.85 * n_rows + 0.7), squeeze=False)
    for r, (row, row_images) in enumerate(zip(rows, images)):
        for c, image in enumerate(row_images):
            ax = axes[r][c]
            ax.imshow(image)
            ax.set_xticks([])
            ax.set_yticks([])
            ax.set_xlabel(f'{row.times_s[c]:+.2f} s', fontsize=7, labelpad=1)
        axes[r][0].set_ylabel(row.label, fontsize=8)
    figure.suptitle(title, fontsize=9)
    figure.tight_layout()
    png.save_figure(figure, path, dpi=110)
    plt.close(figure)
    return path


def stroke_figure(
    path: str | os.PathLike,
    ppo: Sequence[strokes.Stroke],
    amp: Sequence[strokes.Stroke],
    dataset,
    rate_hz: float,
    direction: str = 'forward',
    camera: str = FIGURE_CAMERA,
    setting: str = '',
) -> dict | None:
    """Render the 3x7 grid to `path`; returns what was shown (None when no ball of that direction came)."""
    key = choose_ball(ppo, amp, direction)
    if key is None:
        return None
    ppo_stroke = next(s for s in ppo if (s.seed, s.ball) == key)
    amp_stroke = next(s for s in amp if (s.seed, s.ball) == key)
    rows = [
        policy_row(f'PPO ({ppo_stroke.outcome})', ppo_stroke, rate_hz),
        policy_row(f'AMP ({amp_stroke.outcome})', amp_stroke, rate_hz),
        reference_row(f'demonstration, {direction}', dataset, direction, amp_stroke),
    ]
    title = (
        f'Fig. 2: a {direction} ball (seed {key[0]}, ball {key[1]}, {ppo_stroke.launch_speed_m_s:.2f} m/s); '
        f"policy frames at times from the paddle's first contact, clip frames from its start; camera {camera}."
        f'\n{setting}'
    )
    save_grid(path, rows, render_rows(rows, camera), title)
    return {
        'direction': direction,
        'seed': key[0],
        'ball': key[1],
        'camera': camera,
        'launch_speed_m_s': round(ppo_stroke.launch_speed_m_s, 3),
        'outcomes': {'ppo': ppo_stroke.outcome, 'amp': amp_stroke.outcome},
        'reference_row': rows[2].label,
    }
