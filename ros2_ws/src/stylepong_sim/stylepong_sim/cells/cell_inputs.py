"""What every cell (MuJoCo `cell.Cell`, PyBullet `bullet_cell.BulletCell`) accepts: frames, launch speed, the
error it raises for a rejected input. Its own module so that the PyBullet cell needs nothing of the MuJoCo
cell (whose module brings the analytic ball contacts with it)."""

from __future__ import annotations

from stylepong_description import robot_model
from stylepong_description.robot_cell import FRAME_WORLD  # noqa: F401  (the cells' API names its frames here)

MAX_LAUNCH_SPEED_M_S = 30.0
FRAME_TOOL = robot_model.TOOL_FRAME


class InputError(ValueError):
    """A rejected command or input; `kind` names the problem (for throttling warnings per kind)."""

    def __init__(self, kind: str, message: str):
        super().__init__(message)
        self.kind = kind
