"""Headless recording of the cell to MP4 and to PNG frames."""

import imageio.v3 as iio
import imageio_ffmpeg
import numpy as np
import pytest

from stylepong_sim import world_spec
from stylepong_sim.cells.cell import Cell
from stylepong_sim.cells.video import VideoRecorder


def _record(cell: Cell, recorder: VideoRecorder, duration_s: float) -> None:
    launch = world_spec.incoming_ball_for_seed(7)
    cell.launch_ball(launch.position_m, launch.velocity_m_s)
    for _ in range(round(duration_s / cell.dt_s)):
        cell.step(1)
        if recorder.clock.due(cell.time_s):
            recorder.capture(cell.data)
    recorder.close()


def test_an_mp4_of_a_ball_plays_back(tmp_path):
    cell = Cell()
    path = tmp_path / 'rally.mp4'
    _record(cell, VideoRecorder(cell.model, str(path), fps=20.0, width=320, height=240), 0.3)
    reader = imageio_ffmpeg.read_frames(str(path))
    meta = reader.__next__()
    frames = list(reader)
    assert meta['size'] == (320, 240)
    assert len(frames) == 7  # instants 0, 0.05, ..., 0.3 s


def test_png_frames_show_the_ball_moving(tmp_path):
    cell = Cell()
    _record(
        cell,
        VideoRecorder(cell.model, str(tmp_path / 'frames'), fps=10.0, width=320, height=240, camera='robot_view'),
        0.3,
    )
    images = [iio.imread(p) for p in sorted((tmp_path / 'frames').glob('frame_*.png'))]
    assert len(images) == 4 and images[0].shape == (240, 320, 3)  # instants 0, 0.1, 0.2, 0.3 s
    assert images[0].std() > 10.0  # a scene, not a blank frame
    assert np.abs(images[3].astype(int) - images[0].astype(int)).sum() > 0  # the ball moved


def test_bad_video_settings_are_rejected(tmp_path):
    cell = Cell()
    with pytest.raises(ValueError):
        VideoRecorder(cell.model, str(tmp_path / 'x.mp4'), camera='nowhere')
    with pytest.raises(ValueError):
        VideoRecorder(cell.model, str(tmp_path / 'x.mp4'), width=330)


def test_an_unwritable_destination_fails_at_once_with_its_reason(tmp_path):
    cell = Cell()
    taken = tmp_path / 'clip.mp4'
    taken.mkdir()  # a folder where the file should go: ffmpeg would only
    with pytest.raises(OSError):  # fail at the first frame
        VideoRecorder(cell.model, str(taken))
    blocker = tmp_path / 'a_file'
    blocker.write_text('')
    with pytest.raises(OSError):  # a file where the frames' folder should go
        VideoRecorder(cell.model, str(blocker / 'frames'))
