"""The old name of `stylepong_recording.joint_state_bags`, for tests written before it moved."""
from stylepong_recording.joint_state_bags import *  # noqa: F401,F403
