"""The skill library: networks that already return balls, each in a style it learned, to start a new style from.

A style learned in an hour of a 2-core CPU keeps the contact and the rhythm of the skill it starts from
(docs/DESIGN.md, "Learning a style"), so the start matters: learn_style validates every skill offered here
against the new demonstrations and starts from the one whose strokes are nearest them.

The library is the shipped style actor's network (models/amp_actor_checkpoint.pt, named SHIPPED) and every
training checkpoint in models/skills/ (named by its file's stem). A learned skill records the demonstrations
behind it, its own and its start's (LINEAGE_KEY: their fingerprints, demonstrations_fingerprint), so that a
skill that has already seen a set is not offered as the start for learning that set: a run then measures
learning those demonstrations, not continuing them (continue a run with learn_style --from). The shipped
skill records none and is always offered.
"""

from __future__ import annotations

import hashlib
import pathlib
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

SHIPPED = 'shipped'
SHIPPED_FILE = 'amp_actor_checkpoint.pt'
LIBRARY_DIR = 'skills'
LINEAGE_KEY = 'learned_on'
# Positions are hashed at this resolution: the same bags built twice give the same fingerprint even where
# float arithmetic differs in the last bits.
FINGERPRINT_RESOLUTION_RAD = 1e-4


@dataclass(frozen=True)
class Skill:
    """A network to start from: its name, its training checkpoint and the fingerprints it learned on."""

    name: str
    path: pathlib.Path
    learned_on: tuple[str, ...]


def demonstrations_fingerprint(dataset) -> str:
    """A short hash of a stylepong_policy.training.dataset.ReferenceDataset's original clips (labels and positions),
    in the dataset's order: the same demonstrations give the same fingerprint whatever their speed-ups."""
    digest = hashlib.sha256()
    for clip in dataset.select(speed_factors=[1]):
        q = dataset.clip(int(clip)).q
        digest.update(str(dataset.label[clip]).encode())
        digest.update(np.round(np.asarray(q, dtype=np.float64) / FINGERPRINT_RESOLUTION_RAD).astype(np.int64).tobytes())
    return digest.hexdigest()[:16]


def lineage_of(checkpoint: dict) -> tuple[str, ...]:
    """The fingerprints of the demonstrations a training checkpoint has learned on (none recorded: ())."""
    return tuple(str(f) for f in checkpoint.get(LINEAGE_KEY) or ())


def lineage_after(start: dict, fingerprint: str) -> list[str]:
    """The lineage of a network learned on `fingerprint` from the checkpoint `start`."""
    before = list(lineage_of(start))
    return before if fingerprint in before else before + [fingerprint]


def read_skill(name: str, path: pathlib.Path) -> Skill:
    """The skill in a training checkpoint file."""
    import torch

    checkpoint = torch.load(path, map_location='cpu', weights_only=False)
    return Skill(name, path, lineage_of(checkpoint))


def library(models_dir: pathlib.Path) -> list[Skill]:
    """The shipped skill first, then models/skills/*.pt by name."""
    shipped = Skill(SHIPPED, models_dir / SHIPPED_FILE, ())
    learned = sorted((models_dir / LIBRARY_DIR).glob('*.pt'))
    return [shipped] + [read_skill(path.stem, path) for path in learned]


def offered(skills: Sequence[Skill], fingerprint: str) -> list[Skill]:
    """The skills that have not learned on the demonstrations with this fingerprint."""
    return [skill for skill in skills if fingerprint not in skill.learned_on]
