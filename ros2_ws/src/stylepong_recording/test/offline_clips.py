"""Test helper: clips written without a ROS graph, on a clock the test moves by hand (for the ClipWriter and
recover_bag tests)."""

from pathlib import Path

from stylepong_recording.bag_check import JOINT_STATE_TYPE, JOINT_STATES, WRENCH, WRENCH_TYPE
from stylepong_recording.clip_writer import ClipWriter, TopicSpec
from stylepong_recording.msg_definitions import MessageDefinitions

# Only the standard types are needed, which MessageDefinitions knows without msg files.
DEFINITIONS = MessageDefinitions(find_msg_file=lambda msgtype: None)
JOINT_STATES_AND_WRENCH = ((JOINT_STATES, JOINT_STATE_TYPE), (WRENCH, WRENCH_TYPE))
FLUSH_PERIOD_S = 0.1


class FakeClock:
    """A monotonic clock that stands still until the test sets now_s."""

    def __init__(self):
        self.now_s = 0.0

    def __call__(self) -> float:
        return self.now_s


def topic_spec(topic: str, msgtype: str) -> TopicSpec:
    """The topic as the recorder would add it (definition and type hash, no QoS)."""
    return TopicSpec(topic, msgtype, *DEFINITIONS.definition(msgtype))


def open_writer(
    bag_dir: Path, storage: str = 'mcap', label: str = 'forward', topics=JOINT_STATES_AND_WRENCH
) -> tuple[ClipWriter, FakeClock]:
    """An open ClipWriter on a FakeClock at 0, its topics added and flushed to disk (a copy of the bag
    directory now holds them, as a crash would leave it)."""
    clock = FakeClock()
    clip = ClipWriter(bag_dir, storage, {'label': label}, flush_period_s=FLUSH_PERIOD_S, monotonic_s=clock)
    clip.open()
    for topic, msgtype in topics:
        clip.add_topic(topic_spec(topic, msgtype))
    clip.flush()
    return clip, clock
