"""The old name of `stylepong_recording.bag_check`, for tests written before it moved; new code imports the package."""
from stylepong_recording.bag_check import *  # noqa: F401,F403
