"""The viewer's options and its CellView, without a ROS graph or a browser."""

import os
import subprocess
import sys

import numpy as np
import pytest
import rerun as rr

from stylepong_viz import viewer_node
from stylepong_viz.cell_view import HAND_FORCE_SHOWN_N, CellView


@pytest.mark.parametrize(
    'argv, why',
    [
        (['--web-port', '0'], 'web-port'),
        (['--grpc-port', 'x'], 'grpc-port'),
        (['--nice', '20'], 'nice'),
        (['--nonsense'], 'unrecognized'),
    ],
)
def test_bad_options_give_one_line_and_exit_code_2(argv, why, capsys):
    with pytest.raises(SystemExit) as stopped:
        viewer_node.parse_args(argv)
    assert stopped.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith('viewer: ') and why in err[0]


def test_ros_args_are_left_to_rclpy():
    args = viewer_node.parse_args(['--web-port', '9191', '--ros-args', '-p', 'use_sim_time:=true'])
    assert args.web_port == 9191 and args.bag is None and args.nice == viewer_node.DEFAULT_NICE


def test_lower_priority_makes_every_thread_nicer():
    # In a child: the test process keeps its priority.
    script = (
        'import os, threading, time\n'
        'from stylepong_viz.viewer_node import lower_priority\n'
        'stop = threading.Event()\n'
        'threading.Thread(target=stop.wait, daemon=True).start()\n'
        'lower_priority(3)\n'
        'late = threading.Thread(target=lambda: print(os.getpriority(os.PRIO_PROCESS, threading.get_native_id())))\n'
        'late.start(); late.join()\n'
        'def nice(tid):\n'
        '    try:\n'
        '        return [os.getpriority(os.PRIO_PROCESS, tid)]\n'
        '    except OSError:\n'
        '        return []          # a thread that ended since the listing\n'
        'print(*[n for t in os.listdir("/proc/self/task") for n in nice(int(t))])\n'
        'stop.set()\n'
    )
    before = os.getpriority(os.PRIO_PROCESS, 0)
    if before > 16:
        pytest.skip(f'this process runs at nice {before}: no room to see 3 more')
    out = subprocess.run(
        [sys.executable, '-c', script], capture_output=True, text=True, check=True, timeout=60
    ).stdout.split()
    assert len(out) >= 3 and set(out) == {str(before + 3)}


def _view(**rates) -> CellView:
    recording = rr.RecordingStream('stylepong_test')
    recording.memory_recording()  # keeps the data in memory: no server, no file
    return CellView(recording, **rates)


def test_cell_view_decodes_only_the_joint_states_it_keeps():
    view = _view(arm_rate_hz=30.0, plot_rate_hz=50.0)
    names = list(view.joint_names)
    reads = []

    def read():
        reads.append(1)
        return names, [0.1 * j for j in range(6)], [0.0] * 6

    for k in range(1000):  # 2 s at 500 Hz
        view.on_joint_state(k * 0.002, read)
    view.flush()
    assert view.counts['joint_states'] == 1000 and view.counts['arm_frames'] == 60
    # A message is read when the plots (50 Hz) or the arm (30 Hz) keep it: at most 80 a second, not 500.
    assert 100 <= len(reads) <= 160


def test_cell_view_ignores_joint_states_missing_a_joint_or_not_finite():
    view = _view()
    names = list(view.joint_names)
    view.on_joint_state(0.0, lambda: (names[:5], [0.0] * 5, []))
    view.on_joint_state(0.1, lambda: (names, [float('nan')] + [0.0] * 5, []))
    assert view.counts['arm_frames'] == 0 and view.latest_q is None
    view.on_player_status(0.2, ['not', 'a', 'dict'])  # a malformed status is not drawn
    view.on_wrench(0.3, lambda: [float('nan')] * 6)  # nor a wrench before any joint state
    view.flush()


def _weight_reading(view: CellView, q: np.ndarray, hand_tool: np.ndarray) -> np.ndarray:
    """What the sensor reads with the paddle hanging at q and a hand pushing with hand_tool (tool axes)."""
    from stylepong_description.robot_state import rotate

    _, tool = view.robot_state.link_pose_in_base('tool0', q)  # base <- tool; its conjugate: tool <- base
    weight = rotate(tool * np.array([-1.0, -1.0, -1.0, 1.0]), view.tool_load.mass_kg * view._gravity_base_m_s2)
    return np.concatenate([weight, np.cross(view.tool_load.com_m, weight)]) + hand_tool


def test_the_hand_arrow_shows_a_push_and_not_the_paddles_weight():
    view = _view()
    names = list(view.joint_names)
    q = np.array([-1.5, -1.2, 1.2, -1.57, -1.57, -1.57])

    def second(first_step: int, hand_tool: np.ndarray) -> None:
        for k in range(first_step, first_step + 500):  # 1 s at 500 Hz, a flush each 0.1 s
            view.on_joint_state(k * 0.002, lambda: (names, q, [0.0] * 6))
            view.on_wrench(k * 0.002, lambda: _weight_reading(view, q, hand_tool))
            if k % 50 == 49:
                view.flush()

    second(0, np.zeros(6))  # the paddle alone
    assert view.counts['hand_shown'] == 0
    second(500, np.array([0.0, 3.0 * HAND_FORCE_SHOWN_N, 0.0, 0.05, 0.0, 0.0]))  # a hand pushes
    assert view.counts['hand_shown'] == 10 and view.counts['wrenches'] == 1000


def test_the_latest_command_is_plotted_beside_the_next_plotted_joint_state_and_decoded_once():
    view = _view(plot_rate_hz=50.0)
    names = list(view.joint_names)
    decoded = []

    def command(k: int):
        def read():
            decoded.append(k)
            return [0.01 * k] * 6

        return read

    for k in range(500):  # 1 s at 500 Hz, a command after each joint state
        view.on_joint_state(k * 0.002, lambda: (names, [0.0] * 6, [0.0] * 6))
        view.on_command(command(k))
    # The first plotted joint state came before any command; each of the 49 others has the one just before it.
    assert len(view._commanded) == 49 and len(decoded) == 49  # one in ten decoded
    times, values = view._commanded.take()
    assert decoded == [round(t / 0.002) - 1 for t in times]
    assert np.allclose(values[:, 0], 0.01 * np.array(decoded))
    view.on_command(lambda: [0.0] * 5)  # a wrong-length command is not plotted
    view.on_joint_state(2.0, lambda: (names, [0.0] * 6, [0.0] * 6))
    assert len(view._commanded) == 0
