"""The names a rosbag2 bag and a StylePong clip are laid out with, spelled once (no ROS imports).

A rosbag2 bag is a directory holding its storage file(s) and, once closed, `metadata.yaml`, whose
`rosbag2_bagfile_information` mapping lists the storage, the files, the topics with their message
counts and free-form `custom_data`. The recorder writes bags in this layout (clip_writer), recover_bag
rebuilds it after a crash and stylepong_policy's bag reader reads it, so all three take the names from
here and cannot drift apart.
"""

from __future__ import annotations

# --- metadata.yaml ----------------------------------------------------------------------------------
METADATA_NAME = 'metadata.yaml'
METADATA_ROOT_KEY = 'rosbag2_bagfile_information'
STORAGE_IDENTIFIER_KEY = 'storage_identifier'
RELATIVE_FILE_PATHS_KEY = 'relative_file_paths'
TOPICS_WITH_MESSAGE_COUNT_KEY = 'topics_with_message_count'
TOPIC_METADATA_KEY = 'topic_metadata'  # inside each entry of topics_with_message_count
TOPIC_NAME_KEY = 'name'  # inside topic_metadata
MESSAGE_COUNT_KEY = 'message_count'  # beside topic_metadata
CUSTOM_DATA_KEY = 'custom_data'
# The clip's label inside custom_data: the key `ros2 bag record --custom-data label=...` writes too, so
# bags recorded with rosbag2 itself carry their labels the same way.
LABEL_KEY = 'label'
# The metadata version the recorder writes: rosbag2's on ROS 2 Jazzy.
ROSBAG2_VERSION = 9

# --- storage files ----------------------------------------------------------------------------------
# Storage identifiers as metadata.yaml names them (rosbag2's storage plugins), each with its file suffix.
MCAP_STORAGE = 'mcap'
SQLITE3_STORAGE = 'sqlite3'
MCAP_SUFFIX = '.mcap'
SQLITE3_SUFFIX = '.db3'
STORAGE_SUFFIX = {MCAP_STORAGE: MCAP_SUFFIX, SQLITE3_STORAGE: SQLITE3_SUFFIX}
STORAGES = tuple(STORAGE_SUFFIX)
STORAGE_SUFFIXES = tuple(STORAGE_SUFFIX.values())
# rosbag2's per-file compression appends this to the storage file's name.
COMPRESSED_STORAGE_SUFFIXES = tuple(f'{suffix}.zstd' for suffix in STORAGE_SUFFIXES)

# --- a clip being recorded --------------------------------------------------------------------------
# Present while the recorder has the clip open (label, storage, start time, process): a bag holding it
# and no metadata.yaml is a recording that was never closed, which recover_bag can make whole.
IN_PROGRESS_NAME = 'recording_in_progress.yaml'
