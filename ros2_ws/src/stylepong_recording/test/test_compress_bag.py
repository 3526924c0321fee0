"""compress_bag: a finished mcap clip rewritten with zstd chunks holds exactly what it held (read back by
rosbags and, independently, by the mcap library); nothing else is touched; recover_bag keeps chunks
compressed; a bag that is not whole, or not mcap, is refused with the reason."""

import pytest
from mcap.records import Chunk
from mcap.stream_reader import StreamReader

from stylepong_recording import compress_bag as compression
from stylepong_recording.bag_check import (
    JOINT_STATE_TYPE,
    JOINT_STATES,
    joint_state_cdr,
    read_with_mcap_ros2,
    read_with_rosbags,
    storage_file,
)
from stylepong_recording.clip_writer import ClipWriter, TopicSpec
from stylepong_recording.msg_definitions import MessageDefinitions
from stylepong_recording.recover_bag import recover_bag

JOINT_STATE_DEFINITION = MessageDefinitions(find_msg_file=lambda msgtype: None).definition(JOINT_STATE_TYPE)
STAMPS = list(range(1_000, 1_600))


def recorded_clip(bag_dir, storage='mcap', stamps=STAMPS):
    """A closed clip as the recorder leaves it: a chunk (or commit) every 0.1 s."""
    clock_s = [0.0]
    clip = ClipWriter(bag_dir, storage, {'label': 'forward'}, flush_period_s=0.1, monotonic_s=lambda: clock_s[0])
    clip.open()
    clip.add_topic(TopicSpec(JOINT_STATES, JOINT_STATE_TYPE, *JOINT_STATE_DEFINITION))
    for stamp in stamps:
        clock_s[0] += 0.008
        clip.write(JOINT_STATES, stamp, joint_state_cdr(stamp))
    clip.close()
    return clip


def chunk_compressions(mcap_path):
    with open(mcap_path, 'rb') as stream:
        return [r.compression for r in StreamReader(stream, emit_chunks=True).records if isinstance(r, Chunk)]


def files_of(bag_dir):
    return {p.name: p.read_bytes() for p in sorted(bag_dir.iterdir())}


def test_a_clip_is_compressed_with_its_content_and_metadata_unchanged(tmp_path):
    clip = recorded_clip(tmp_path / 'forward_20250101_120000_000')
    mcap = storage_file(clip.bag_dir, '.mcap')
    before = compression.bag_content(clip.bag_dir)
    metadata_before = (clip.bag_dir / 'metadata.yaml').read_text()
    assert set(chunk_compressions(mcap)) == {''}

    report = compression.compress_bag(clip.bag_dir)

    assert report.outcome == 'compressed' and report.size_after_bytes < report.size_before_bytes / 2
    assert report.size_before_bytes > report.size_after_bytes == mcap.stat().st_size
    assert set(chunk_compressions(mcap)) == {'zstd'}
    assert sorted(p.name for p in clip.bag_dir.iterdir()) == ['forward_20250101_120000_000.mcap', 'metadata.yaml']
    assert (clip.bag_dir / 'metadata.yaml').read_text() == metadata_before
    assert compression.bag_content(clip.bag_dir) == before
    assert read_with_rosbags(clip.bag_dir).stamps[JOINT_STATES] == STAMPS
    assert read_with_mcap_ros2(mcap).stamps[JOINT_STATES] == STAMPS  # the mcap library, through the index


def test_a_compressed_bag_is_left_untouched_and_recover_bag_keeps_it_compressed(tmp_path, capsys):
    clip = recorded_clip(tmp_path / 'clip')
    assert compression.main([str(clip.bag_dir)]) == 0
    once = files_of(clip.bag_dir)
    assert compression.main([str(clip.bag_dir)]) == 0
    assert 'already compressed (zstd), left unchanged' in capsys.readouterr().out
    assert files_of(clip.bag_dir) == once

    # A compressed bag that lost its summary and metadata.yaml comes back from recover_bag compressed.
    mcap = storage_file(clip.bag_dir, '.mcap')
    (clip.bag_dir / 'metadata.yaml').unlink()
    mcap.write_bytes(once[mcap.name][:-200])
    assert recover_bag(clip.bag_dir).outcome == 'recovered'
    assert set(chunk_compressions(mcap)) == {'zstd'}
    assert read_with_rosbags(clip.bag_dir).stamps[JOINT_STATES] == STAMPS


def test_a_copy_that_reads_back_differently_never_replaces_the_bag(tmp_path, monkeypatch):
    clip = recorded_clip(tmp_path / 'clip')
    before = files_of(clip.bag_dir)
    read = compression.bag_content
    reads = []

    def second_read_loses_a_message(bag_dir):
        content = read(bag_dir)
        reads.append(bag_dir)
        return (
            content
            if len(reads) == 1
            else compression.BagContent(content.custom_data, content.connections, content.messages[:-1])
        )

    monkeypatch.setattr(compression, 'bag_content', second_read_loses_a_message)
    with pytest.raises(compression.CompressionError, match='reads back differently; the bag is unchanged'):
        compression.compress_bag(clip.bag_dir)
    assert files_of(clip.bag_dir) == before


@pytest.mark.parametrize(
    'case, reason',
    [
        ('no_metadata', 'is not a whole bag (no readable metadata.yaml): make it readable with recover_bag first'),
        ('sqlite3', 'is a sqlite3 bag: only mcap bags have compressed chunks'),
        ('missing', 'does not exist'),
    ],
)
def test_what_cannot_be_compressed_is_refused_with_the_reason(tmp_path, capsys, case, reason):
    bag_dir = tmp_path / case
    if case != 'missing':
        recorded_clip(bag_dir, 'sqlite3' if case == 'sqlite3' else 'mcap')
    if case == 'no_metadata':
        (bag_dir / 'metadata.yaml').unlink()
    before = files_of(bag_dir) if bag_dir.exists() else None
    assert compression.main([str(bag_dir)]) == 1
    error = capsys.readouterr().err
    assert error.startswith('compress_bag: error: ') and reason in error and error.count('\n') == 1
    if before is not None:
        assert files_of(bag_dir) == before
