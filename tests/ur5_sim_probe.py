"""The old name of `stylepong_sim.ur5_sim_probe`, for tests written before it moved; new code imports the package."""
from stylepong_sim.ur5_sim_probe import *  # noqa: F401,F403
