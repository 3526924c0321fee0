"""Headless video of the cell: MuJoCo's offscreen renderer to an MP4 file or a folder of PNG frames.

Free of ROS. Rendering needs MUJOCO_GL=egl (or osmesa) before mujoco is first imported when there is no
display; importing stylepong_sim (its __init__) sets egl in that case.
A 640x480 frame costs about 15-20 ms of CPU.
    recorder = VideoRecorder(cell.model, 'rally.mp4', fps=30)   # or a folder path: frame_000000.png, ...
    if recorder.clock.due(cell.time_s): recorder.capture(cell.data)
    recorder.close()                                            # finishes the MP4 (needed to play it)
"""

from __future__ import annotations

import pathlib

import mujoco
import numpy as np

from stylepong_sim.cells import scene
from stylepong_sim.cells.sensing import SampleClock


class VideoRecorder:
    """Renders the cell from one camera at a fixed frame rate to an MP4 file or a folder of PNGs."""

    def __init__(
        self,
        model: mujoco.MjModel,
        path: str,
        fps: float = 30.0,
        width: int = 640,
        height: int = 480,
        camera: str = 'overview',
    ):
        if camera not in scene.CAMERAS:
            raise ValueError(f'unknown camera {camera!r}; the cell has {", ".join(scene.CAMERAS)}')
        if width % 16 or height % 16:
            raise ValueError(f'video size must be multiples of 16 pixels (H.264 macro blocks), got {width}x{height}')
        self.path = pathlib.Path(path)
        self.camera = camera
        self.clock = SampleClock(fps)
        self.frames = 0
        # An unwritable destination fails here, with its reason (OSError), not at the first frame inside ffmpeg.
        if self.path.suffix.lower() == '.mp4':
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self.path.open('wb').close()
        else:
            self.path.mkdir(parents=True, exist_ok=True)
        try:
            self._renderer = mujoco.Renderer(model, height, width)
        except mujoco.FatalError as error:
            raise RuntimeError(
                f'no OpenGL context ({error}); without a display set MUJOCO_GL=egl (or osmesa) '
                'before anything imports mujoco'
            ) from error
        self._writer = None
        if self.path.suffix.lower() == '.mp4':
            import imageio_ffmpeg

            self._writer = imageio_ffmpeg.write_frames(
                str(self.path), (width, height), fps=fps, codec='libx264', pix_fmt_out='yuv420p', quality=7
            )
            self._writer.send(None)  # starts ffmpeg

    def capture(self, data: mujoco.MjData) -> None:
        self._renderer.update_scene(data, camera=self.camera)
        frame = np.ascontiguousarray(self._renderer.render())
        if self._writer is not None:
            self._writer.send(frame)
        else:
            import imageio.v3 as iio

            iio.imwrite(self.path / f'frame_{self.frames:06d}.png', frame)
        self.frames += 1

    def close(self) -> None:
        if self._writer is not None:
            self._writer.close()
            self._writer = None
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
