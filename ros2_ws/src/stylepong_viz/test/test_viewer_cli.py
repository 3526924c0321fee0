"""The viewer's options and its CellView, without a ROS graph or a browser."""
import pytest
import rerun as rr

from stylepong_viz import viewer_node
from stylepong_viz.cell_view import CellView


@pytest.mark.parametrize('argv, why', [(['--web-port', '0'], 'web-port'), (['--grpc-port', 'x'], 'grpc-port'),
                                       (['--nonsense'], 'unrecognized')])
def test_bad_options_give_one_line_and_exit_code_2(argv, why, capsys):
    with pytest.raises(SystemExit) as stopped:
        viewer_node.parse_args(argv)
    assert stopped.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith('viewer: ') and why in err[0]


def test_ros_args_are_left_to_rclpy():
    args = viewer_node.parse_args(['--web-port', '9191', '--ros-args', '-p', 'use_sim_time:=true'])
    assert args.web_port == 9191 and args.bag is None


def test_cell_view_decimates_500_hz_joint_states_to_its_arm_rate():
    recording = rr.RecordingStream('stylepong_test')
    recording.memory_recording()          # keeps the data in memory: no server, no file
    view = CellView(recording, arm_rate_hz=30.0, plot_rate_hz=100.0)
    names = list(view.joint_names)
    for k in range(1000):                   # 2 s at 500 Hz
        view.on_joint_state(k * 0.002, names, [0.1 * j for j in range(6)], [0.0] * 6)
    view.flush()
    assert view.counts == {'joint_states': 1000, 'arm_frames': 60}


def test_cell_view_ignores_joint_states_missing_a_joint_or_not_finite():
    recording = rr.RecordingStream('stylepong_test')
    recording.memory_recording()
    view = CellView(recording)
    names = list(view.joint_names)
    view.on_joint_state(0.0, names[:5], [0.0] * 5, [])
    view.on_joint_state(0.1, names, [float('nan')] + [0.0] * 5, [])
    assert view.counts['arm_frames'] == 0
    view.on_player_status(0.2, ['not', 'a', 'dict'])     # a malformed status is not drawn
    view.on_command(0.3, [0.0] * 5)                      # a wrong-length command is not drawn
