"""recover_bag: bags left by a killed recorder become readable with everything flushed; healthy bags stay
untouched; clear errors. A crash is reproduced exactly by copying the bag directory while its writer is
still open: the copy holds what the OS had (a SIGKILL keeps that and loses the process's memory)."""

import os
import random
import shutil
import socket
import subprocess

import pytest
import yaml
from mcap.records import Chunk, Message
from mcap.stream_reader import StreamReader, breakup_chunk
from offline_clips import open_writer  # beside this file: conftest.py

from stylepong_recording.bag_check import (
    JOINT_STATES,
    WRENCH,
    joint_state_cdr,
    read_with_mcap_ros2,
    read_with_rosbags,
    read_with_sqlite3,
    storage_file,
)
from stylepong_recording.bag_layout import IN_PROGRESS_NAME, STORAGE_SUFFIX
from stylepong_recording.recover_bag import RecoveryError, main, recover_bag


def write_flushed(clip, clock, stamps, per_flush=50):
    """Write joint states, flushing after every `per_flush` of them (one mcap chunk each)."""
    for i, stamp in enumerate(stamps, 1):
        clip.write(JOINT_STATES, stamp, joint_state_cdr(stamp))
        if i % per_flush == 0:
            clock.now_s += 1.0
            clip.flush_if_due()


def dead_pid():
    child = subprocess.Popen(['true'])
    child.wait()
    return child.pid


def crash_copy(clip, destination):
    """What a SIGKILL right now would leave on disk, its recording note naming a process now gone."""
    shutil.copytree(clip.bag_dir, destination)
    note_path = destination / IN_PROGRESS_NAME
    note = yaml.safe_load(note_path.read_text())
    note['pid'] = dead_pid()
    note_path.write_text(yaml.safe_dump(note))
    return destination


def snapshot(bag_dir):
    return {p.name: (p.read_bytes(), p.stat().st_mtime_ns) for p in sorted(bag_dir.iterdir())}


@pytest.mark.parametrize('storage', ['mcap', 'sqlite3'])
def test_a_killed_clip_is_recovered_with_everything_flushed_and_its_label(tmp_path, storage):
    clip, clock = open_writer(tmp_path / 'forward_20250101_120000_000', storage)
    flushed = list(range(1, 1001))
    write_flushed(clip, clock, flushed)
    for stamp in range(1001, 1031):  # in memory only (mcap) / uncommitted (sqlite3)
        clip.write(JOINT_STATES, stamp, joint_state_cdr(stamp))
    crashed = crash_copy(clip, tmp_path / 'crashed')
    clip.abort()
    assert not (crashed / 'metadata.yaml').exists() and (crashed / IN_PROGRESS_NAME).exists()
    if storage == 'sqlite3':
        assert (crashed / f'{clip.bag_dir.name}.db3-wal').exists()

    report = recover_bag(crashed)

    assert report.outcome == 'recovered'
    assert report.message_counts == {JOINT_STATES: 1000, WRENCH: 0}
    assert any('not closed' in p for p in report.problems)
    assert not (crashed / IN_PROGRESS_NAME).exists()
    storage_name = f'{clip.bag_dir.name}{STORAGE_SUFFIX[storage]}'
    assert sorted(p.name for p in crashed.iterdir()) == sorted(['metadata.yaml', storage_name])
    content = read_with_rosbags(crashed)
    assert content.custom_data == {'label': 'forward'}
    assert content.stamps[JOINT_STATES] == flushed
    assert content.log_times[JOINT_STATES] == flushed
    assert content.metadata_counts == {JOINT_STATES: 1000, WRENCH: 0}
    if storage == 'mcap':
        assert read_with_mcap_ros2(storage_file(crashed, '.mcap')).stamps[JOINT_STATES] == flushed
    else:  # the .db3 file alone, through Python's sqlite3: the WAL was folded in, nothing uncommitted kept
        sql, joint_states = read_with_sqlite3(storage_file(crashed, '.db3'))
        assert sql.stamps[JOINT_STATES] == flushed
        assert [js.position[0] for js in joint_states] == [stamp * 1e-9 for stamp in flushed]


def mcap_chunk_ends(path):
    """(byte offset where each chunk record ends, messages in it) of a well-formed mcap file."""
    ends = []
    with open(path, 'rb') as stream:
        for record in StreamReader(stream, emit_chunks=True).records:
            if isinstance(record, Chunk):
                ends.append((stream.tell(), sum(isinstance(r, Message) for r in breakup_chunk(record))))
    return ends


def test_an_mcap_cut_anywhere_keeps_every_whole_chunk_before_the_cut(tmp_path):
    clip, clock = open_writer(tmp_path / 'whole')
    stamps = list(range(1, 501))
    write_flushed(clip, clock, stamps, per_flush=25)
    clip.close()
    whole = storage_file(clip.bag_dir, '.mcap')
    data = whole.read_bytes()
    ends = mcap_chunk_ends(whole)
    first_chunk_end = ends[0][0]  # schemas and channels only
    rng = random.Random(4)
    cuts = [first_chunk_end, ends[5][0], ends[5][0] + 1, ends[-1][0], len(data) - 1]
    cuts += rng.sample(range(first_chunk_end, len(data)), 10)
    for cut in cuts:
        bag = tmp_path / f'cut_{cut}'
        bag.mkdir()
        (bag / whole.name).write_bytes(data[:cut])
        report = recover_bag(bag)
        expected = sum(n for end, n in ends if end <= cut)
        recovered = read_with_rosbags(bag).stamps[JOINT_STATES]
        assert recovered == stamps[: len(recovered)], f'cut at {cut}: not a prefix of what was written'
        assert len(recovered) >= expected, f'cut at {cut}: {len(recovered)} < {expected} messages'
        assert report.custom_data == {}  # no metadata, no note, name not <label>_<time>


def test_a_healthy_bag_is_left_untouched_and_recovery_is_idempotent(tmp_path):
    clip, clock = open_writer(tmp_path / 'forward_20250101_120000_000')
    write_flushed(clip, clock, range(1, 201))
    clip.close()
    before = snapshot(clip.bag_dir)
    report = recover_bag(clip.bag_dir)
    assert report.outcome == 'healthy' and report.message_counts[JOINT_STATES] == 200
    assert report.custom_data == {'label': 'forward'}
    assert snapshot(clip.bag_dir) == before

    crashed_clip, clock = open_writer(tmp_path / 'leftward_20250101_120000_000', 'sqlite3', 'leftward')
    write_flushed(crashed_clip, clock, range(1, 201))
    crashed = crash_copy(crashed_clip, tmp_path / 'leftward_20250101_130000_000')
    crashed_clip.abort()
    assert recover_bag(crashed).outcome == 'recovered'
    after_first = snapshot(crashed)
    second = recover_bag(crashed)
    assert second.outcome == 'healthy' and second.custom_data == {'label': 'leftward'}
    assert snapshot(crashed) == after_first


def test_check_reports_without_changing_anything(tmp_path, capsys):
    clip, clock = open_writer(tmp_path / 'clip')
    write_flushed(clip, clock, range(1, 101))
    crashed = crash_copy(clip, tmp_path / 'crashed')
    clip.abort()
    before = snapshot(crashed)
    assert main(['--check', str(crashed)]) == 0
    assert 'needs recovery' in capsys.readouterr().out
    assert snapshot(crashed) == before


def test_a_clip_killed_before_its_first_message_becomes_an_empty_readable_bag(tmp_path):
    clip, _ = open_writer(tmp_path / 'clip')
    crashed = crash_copy(clip, tmp_path / 'crashed')
    clip.abort()
    report = recover_bag(crashed)
    assert report.message_counts == {JOINT_STATES: 0, WRENCH: 0}
    assert read_with_rosbags(crashed).metadata_counts == {JOINT_STATES: 0, WRENCH: 0}
    assert read_with_mcap_ros2(storage_file(crashed, '.mcap')).metadata_counts == {JOINT_STATES: 0, WRENCH: 0}


def test_the_label_comes_from_the_directory_name_when_nothing_else_has_it(tmp_path):
    clip, clock = open_writer(tmp_path / 'clip', label='ignored')
    write_flushed(clip, clock, range(1, 101))
    crashed = crash_copy(clip, tmp_path / 'rightward_20250101_120000_000')
    clip.abort()
    (crashed / IN_PROGRESS_NAME).unlink()
    report = recover_bag(crashed)
    assert report.custom_data == {'label': 'rightward'}
    assert any('directory name' in p for p in report.problems)
    assert read_with_rosbags(crashed).custom_data == {'label': 'rightward'}
    # The storage file keeps its own name (the directory was renamed after recording).
    assert (crashed / 'clip.mcap').is_file()


def test_a_bag_still_being_recorded_is_refused(tmp_path, capsys):
    clip, clock = open_writer(tmp_path / 'live')
    write_flushed(clip, clock, range(1, 101))
    note = yaml.safe_load((clip.bag_dir / IN_PROGRESS_NAME).read_text())
    assert note['pid'] == os.getpid() and note['host'] == socket.gethostname()
    with pytest.raises(RecoveryError, match='still being recorded by process'):
        recover_bag(clip.bag_dir)
    assert main([str(clip.bag_dir)]) == 1
    assert 'still being recorded' in capsys.readouterr().err
    clip.close()


def test_unrecoverable_input_gives_a_clear_error_and_exit_status_1(tmp_path, capsys):
    (tmp_path / 'empty').mkdir()
    (tmp_path / 'garbage').mkdir()
    (tmp_path / 'garbage' / 'garbage.mcap').write_bytes(b'definitely not an mcap file')
    (tmp_path / 'two').mkdir()
    (tmp_path / 'two' / 'a.mcap').write_bytes(b'')
    (tmp_path / 'two' / 'b.db3').write_bytes(b'')
    (tmp_path / 'notdb').mkdir()
    (tmp_path / 'notdb' / 'x.db3').write_bytes(b'not sqlite either, but long enough to be read as a header' * 4)
    (tmp_path / 'file').write_text('')
    cases = [
        ('missing', 'does not exist'),
        ('file', 'is not a directory'),
        ('empty', 'no .mcap or .db3'),
        ('garbage', 'not an MCAP file'),
        ('two', 'several storage files'),
        ('notdb', 'not a readable sqlite3 bag'),
    ]
    for name, reason in cases:
        with pytest.raises(RecoveryError, match=reason):
            recover_bag(tmp_path / name)
    assert main([str(tmp_path / 'missing'), str(tmp_path / 'garbage')]) == 1
    err = capsys.readouterr().err
    assert 'does not exist' in err and 'not an MCAP file' in err
    with pytest.raises(SystemExit) as usage:
        main([])
    assert usage.value.code == 2
