"""`ros2 run stylepong_policy build_dataset ...` end to end, as a user runs it (the build_dataset checks
of docs/ACCEPTANCE.md).

Expected values come from the motions the test wrote or from rosbags' own reader, never from the tool.
"""

import math
import os
import pathlib
import subprocess

import numpy as np
import pytest

from stylepong_recording.joint_state_bags import (
    Swing,
    read_with_rosbags,
    truncate_file,
    write_driver_bag,
    write_recorder_bag,
)

ROOT = pathlib.Path(__file__).resolve().parent.parent
INTEROP_ARG = '../shared/interop-bags'  # as the README spells it, relative to the repository
INTEROP = (ROOT / INTEROP_ARG).resolve()
TOOLPATH = 'ur3e-hw-sqlite3-v5-toolpath'
needs_interop = pytest.mark.skipif(not INTEROP.is_dir(), reason=f'{INTEROP} is absent')


def build_dataset(*args, env=None) -> subprocess.CompletedProcess:
    result = subprocess.run(
        ['ros2', 'run', 'stylepong_policy', 'build_dataset', *map(str, args)],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert 'Traceback' not in result.stdout + result.stderr, result.stdout + result.stderr
    return result


def load(path):
    with np.load(path, allow_pickle=False) as data:
        return {k: data[k] for k in data.files}


def clip(data, c):
    frames = slice(int(data['clip_start'][c]), int(data['clip_start'][c] + data['clip_length'][c]))
    return data['t'][frames], data['q'][frames], data['qd'][frames]


def assert_augmented_exactly(data):
    originals = np.flatnonzero(data['speed_factor'] == 1)
    for c in range(len(data['clip_start'])):
        k = int(data['speed_factor'][c])
        source = [o for o in originals if data['source'][o] == data['source'][c] and o <= c][-1]
        _t, q, qd = clip(data, source)
        _t, q_k, qd_k = clip(data, c)
        assert len(q_k) == math.ceil(len(q) / k)
        assert np.array_equal(q_k, q[::k]) and np.array_equal(qd_k, k * qd[::k])


@needs_interop
def test_ur3e_toolpath_gives_an_original_and_x2_x3_x5_equal_to_the_recording(tmp_path, ros_env):
    out = tmp_path / 'x.npz'
    result = build_dataset(f'{INTEROP_ARG}/{TOOLPATH}', '-o', out, env=ros_env)
    assert result.returncode == 0, result.stdout + result.stderr
    data = load(out)
    assert data['speed_factor'].tolist() == [1, 2, 3, 5]
    assert float(data['rate_hz']) == 60.0 and data['joint_names'].tolist()[0] == 'shoulder_pan_joint'
    assert len(set(data['source'].tolist())) == 1 and TOOLPATH in data['source'][0]
    t, q, _qd = clip(data, 0)
    stamps, positions, _v = read_with_rosbags(INTEROP / TOOLPATH)
    assert np.allclose(np.diff(t), 1 / 60, rtol=0, atol=1e-5)
    assert stamps[0] / 1e9 - 1e-6 <= t[0] and t[-1] <= stamps[-1] / 1e9 + 1e-6
    t_rel, raw_rel = t - stamps[0] / 1e9, (stamps - stamps[0]) / 1e9
    expected = np.stack([np.interp(t_rel, raw_rel, positions[:, j]) for j in range(6)], axis=1)
    assert np.abs(q - expected).max() < 1e-3
    assert_augmented_exactly(data)


def test_a_driver_style_recording_from_another_writer_gives_the_true_motion(tmp_path, ros_env):
    swing = Swing()
    truth = write_driver_bag(tmp_path / 'ur_driver_take', swing, swing.total_s, label='rightward', seed=3)
    out = tmp_path / 'driver.npz'
    result = build_dataset(tmp_path / 'ur_driver_take', '-o', out, env=ros_env)
    assert result.returncode == 0, result.stdout + result.stderr
    data = load(out)
    assert data['label'].tolist() == ['rightward'] * 4
    t, q, qd = clip(data, 0)
    q_true, qd_true = swing(t - truth.stamps_ns[0] / 1e9)
    assert np.abs(np.diff(q, axis=0)).max() < 0.1  # continuous: no 2 pi jump in wrist_3
    assert q[:, 5].max() > math.pi + 0.5  # and it does turn past pi
    assert np.abs(q - q_true).max() < 1e-3
    assert np.abs(qd - qd_true).max() < 0.1
    assert_augmented_exactly(data)


def test_a_folder_with_good_bags_and_a_truncated_mcap(tmp_path, ros_env):
    swing = Swing()
    folder = tmp_path / 'bags'
    write_recorder_bag(folder / 'forward_20251121_101112_123', swing, swing.total_s, label='forward')
    write_recorder_bag(
        folder / 'leftward_20251121_101200_004', swing, swing.total_s, label='leftward', storage='sqlite3'
    )
    broken = folder / 'rightward_20251121_101300_000'
    write_recorder_bag(broken, swing, swing.total_s, label='rightward')
    (mcap,) = broken.glob('*.mcap')
    truncate_file(mcap)
    out, plot = tmp_path / 'd.npz', tmp_path / 'clips.png'
    result = build_dataset(folder, '-o', out, '--plot', plot, env=ros_env)
    assert result.returncode == 0, result.stdout + result.stderr
    assert str(broken) in result.stdout and 'truncated' in result.stdout
    data = load(out)
    assert sorted(set(data['label'].tolist())) == ['forward', 'leftward']
    assert data['speed_factor'].tolist() == [1, 2, 3, 5] * 2
    assert plot.stat().st_size > 10_000 and plot.read_bytes()[:4] == b'\x89PNG'

    # --strict: the broken bag is fatal and nothing is written.
    strict_out = tmp_path / 'strict.npz'
    result = build_dataset(folder, '-o', strict_out, '--strict', env=ros_env)
    assert result.returncode == 1 and not strict_out.exists()
    assert str(broken) in result.stdout

    # Nothing usable: exit 1, nothing written, the reason shown.
    none_out = tmp_path / 'none.npz'
    result = build_dataset(broken, '-o', none_out, env=ros_env)
    assert result.returncode == 1 and not none_out.exists()
    assert str(broken) in result.stdout


@needs_interop
def test_every_interop_bag_is_read_or_rejected_and_none_crashes_the_tool(tmp_path, ros_env):
    out = tmp_path / 'interop.npz'
    result = build_dataset(INTEROP_ARG, '-o', out, env=ros_env)
    assert result.returncode == 0, result.stdout + result.stderr
    lines = result.stdout.splitlines()
    for bag in sorted(p for p in INTEROP.iterdir() if p.is_dir()):
        entries = [line for line in lines if line.startswith(('[used]', '[skipped]')) and bag.name in line]
        assert len(entries) == 1, (bag.name, result.stdout)
    assert sum(line.startswith('[used]') for line in lines) == 2
    assert os.path.getsize(out) > 0
