"""The observation/action contract under the name the training task imports it by (`from stylepong_policy
import spec`); the contract itself is `stylepong_player.spec`, the module the player runs on the robot."""
from stylepong_player.spec import *  # noqa: F401,F403
