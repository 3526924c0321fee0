"""System tests of `ros2 run stylepong_sim ur5_sim` with non-default parameters: real_time_factor 0, video."""

import imageio_ffmpeg

from stylepong_common.node_process import NodeProcess
from stylepong_sim.testing.ur5_sim_probe import Ur5SimProbe


def test_real_time_factor_0_runs_faster_than_the_wall_clock(ros_env):
    with NodeProcess('stylepong_sim', 'ur5_sim', params={'real_time_factor': 0.0}) as node:
        probe = Ur5SimProbe()
        try:
            assert probe.wait_for_sim(60.0), node.output()
            probe.spin_for(0.5)
            first = probe.clock[-1]
            probe.spin_for(3.0)
            last = probe.clock[-1]
            speed_up = (last.stamp_s - first.stamp_s) / (last.received_s - first.received_s)
            print(f'real_time_factor 0: /clock advanced {speed_up:.2f}x wall time')
            assert speed_up >= 1.5, speed_up
            # Still a live node: services answer while it races.
            assert probe.launch(randomize=True, seed=3).success
        finally:
            probe.close()
        assert node.stop() == 0


def test_record_video_writes_a_playable_mp4(ros_env, tmp_path):
    path = tmp_path / 'cell.mp4'
    params = {
        'real_time_factor': 0.0,
        'record_video': str(path),
        'video_fps': 25.0,
        'video_width': 320,
        'video_height': 240,
    }
    with NodeProcess('stylepong_sim', 'ur5_sim', params=params) as node:
        probe = Ur5SimProbe()
        try:
            assert probe.wait_for_sim(60.0), node.output()
            assert probe.launch(randomize=True, seed=7).success
            assert probe.spin_until(lambda: probe.clock and probe.clock[-1].stamp_s > 3.0, 60.0)
        finally:
            probe.close()
        assert node.stop(timeout_s=20.0) == 0  # Ctrl-C finishes the file
    reader = imageio_ffmpeg.read_frames(str(path))
    meta = next(reader)
    assert meta['size'] == (320, 240)
    assert sum(1 for _ in reader) >= 25 * 3 - 1
