"""A synthetic reference dataset for tests that measure DTW (evaluate, select_checkpoint)."""

import pathlib

import numpy as np

from stylepong_policy.evaluation import strokes
from stylepong_policy.training.dataset import Clip, SourceClip, assemble_dataset


def write_reference(path: pathlib.Path, labels=strokes.DIRECTIONS) -> pathlib.Path:
    """A small reference dataset in the robot's joint order: one swing per label (each a different joint),
    x1 and x2."""
    from stylepong_description.robot_model import JOINT_NAMES
    from stylepong_sim.world_spec import HOME_JOINT_POSITIONS_RAD

    t = np.arange(90) / 60.0
    home = np.array(HOME_JOINT_POSITIONS_RAD)
    sources = []
    for k, label in enumerate(labels):
        swing = 0.4 * np.sin(np.pi * t / t[-1])[:, None] * np.eye(6)[k]
        q = home + swing
        sources.append(SourceClip(Clip(t=t, q=q, qd=np.gradient(q, t, axis=0)), label, f'synthetic:{label}:{k}'))
    assemble_dataset(sources, (2,), JOINT_NAMES, 60.0).save(path)
    return path
