"""Synthetic reference datasets: one for tests that measure DTW (evaluate, select_checkpoint), one toy clip
for tests of the motion prior (test_amp)."""

import pathlib

import numpy as np

from stylepong_policy.evaluation import strokes
from stylepong_policy.training.dataset import Clip, ReferenceDataset, SourceClip, assemble_dataset


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


def one_clip_dataset(q: np.ndarray, qd: np.ndarray, label: str) -> ReferenceDataset:
    """All the frames as one original clip labelled `label`, at 60 Hz, of joints named a, b, ... (the
    fields a ReferenceDataset needs, with toy provenance: no bag was read)."""
    frames = len(q)
    return ReferenceDataset(
        t=np.arange(frames) / 60.0,
        q=q,
        qd=qd,
        clip_start=np.array([0]),
        clip_length=np.array([frames]),
        label=np.array([label]),
        speed_factor=np.array([1]),
        source=np.array(['toy']),
        original=np.array([0]),
        time_source=np.array(['header']),
        velocity_source=np.array(['bag']),
        rate_hz=60.0,
        joint_names=np.array([chr(ord('a') + j) for j in range(q.shape[1])]),
    )
