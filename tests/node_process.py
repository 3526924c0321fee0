"""The old name of `stylepong_common.node_process`, for tests written before it moved; new code imports the package."""
from stylepong_common.node_process import *  # noqa: F401,F403
