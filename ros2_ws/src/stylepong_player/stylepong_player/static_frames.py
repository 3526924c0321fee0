"""Fixed frames from /tf_static, without tf2: a point in a sensor's frame expressed in `world`.

tf2_ros is not published as a wheel, and the estimator needs only fixed transforms (a tracker's camera
is bolted to the cell): each is kept as its parent's rotation and translation of the child, and a point
is carried up the chain of parents until `world`. A chain that does not reach `world` (a frame nobody
has published yet, or a loop) gives None.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from stylepong_description.robot_state import rotate

MAX_CHAIN = 32  # more links than any real tree has: a loop


@dataclass(frozen=True)
class _Link:
    parent: str
    translation_m: np.ndarray
    rotation_xyzw: np.ndarray


class StaticFrames:
    """The fixed transforms seen so far; `to_frame` carries a point up to a root frame."""

    def __init__(self):
        self._links: dict[str, _Link] = {}

    def add(self, parent: str, child: str, translation_m, rotation_xyzw) -> None:
        """parent -> child: the child's origin (m) and orientation (unit quaternion x y z w) in parent."""
        q = np.asarray(rotation_xyzw, dtype=float)
        t = np.asarray(translation_m, dtype=float)
        norm = float(np.linalg.norm(q))
        if q.shape != (4,) or t.shape != (3,) or not (np.isfinite(q).all() and np.isfinite(t).all()) or norm < 1e-6:
            raise ValueError(f'transform {parent} -> {child} is not a finite pose with a unit quaternion')
        self._links[child.lstrip('/')] = _Link(parent.lstrip('/'), t, q / norm)

    def to_frame(self, source: str, target: str, point_m) -> np.ndarray | None:
        """`point_m` given in `source`, expressed in `target` (an ancestor of source), or None."""
        frame, point = source.lstrip('/'), np.asarray(point_m, dtype=float)
        for _ in range(MAX_CHAIN):
            if frame == target:
                return point
            link = self._links.get(frame)
            if link is None:
                return None
            point = rotate(link.rotation_xyzw, point) + link.translation_m
            frame = link.parent
        return None
