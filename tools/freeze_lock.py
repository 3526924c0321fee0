#!/usr/bin/env python3
"""Write requirements.lock from the current virtual environment (run with the venv's python).

`pip freeze` is not reinstallable here: the ROS wheels (e.g. ros-action-msgs) also carry an
egg-info of the inner package (action_msgs), which freeze lists as a second distribution that no
index serves. Only real installed distributions (.dist-info) are pinned; the torch local version
suffix (+cpu) is dropped so `torch==2.13.0` picks the local CPU build.
"""

import importlib.metadata
import pathlib
import sys

HEADER = """# Pinned Python environment of StylePong, as tested (Debian 12, CPython 3.11).
# Direct needs: ROS 2 Jazzy wheels (rclpy, common interfaces, rosidl/ament build tools), colcon,
# pin, example-robot-data, mujoco, rosbags, torch (CPU build), numpy, pytest, matplotlib, tensorboard,
# mcap + mcap-ros2-support, imageio + imageio-ffmpeg (MP4 videos), tqdm, pyyaml, rerun-sdk (the browser viewer),
# pybullet (the second cell, ur5_bullet), filterpy (the ball estimator's Kalman filter; brings scipy).
# Regenerate after a tested change: .venv/bin/python tools/freeze_lock.py > requirements.lock
"""


def main() -> int:
    """Print the lock file of the running environment."""
    pins = {}
    for dist in importlib.metadata.distributions():
        path = getattr(dist, '_path', None)
        if path is None or pathlib.Path(path).suffix != '.dist-info':
            continue
        name = dist.metadata['Name']
        pins[name.lower()] = f'{name}=={dist.version.split("+")[0]}'
    sys.stdout.write(HEADER + ''.join(line + '\n' for _, line in sorted(pins.items())))
    return 0


if __name__ == '__main__':
    sys.exit(main())
