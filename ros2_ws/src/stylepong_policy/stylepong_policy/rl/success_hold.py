"""The motion terms' scale, lowered while the returns fall below the skill's own: style as far as returns allow.

    hold = SuccessHold(warmup_iterations=10, margin=0.03, gain=0.15, smoothing=0.1)
    scale = hold.observe(success_rate, episodes)     # after every iteration; r = w_task r_task + scale * motion

Why. Moving a skill to a new style trades returns for style along the whole run: with fixed weights the
motion terms (up to 66 an episode in pose) outweigh a return (about 11), the strokes keep coming closer and
the returns keep falling, so the best checkpoint is an early one that has moved little (docs/DESIGN.md,
"Learning a style"). Held, the problem is a constrained one: the closest style whose returns stay within
`margin` of the skill's. A dual-ascent step on the scale does that without a weight tuned to a set:

    floor = (training success over the warm-up iterations' episodes, the skill's own here) - margin
    s     = S / E,  S <- (1 - smoothing) S + smoothing * successes,  E <- (1 - smoothing) E + smoothing * episodes
    scale <- clip(scale + gain (s - floor), 0, 1)

so the scale falls while the returns are below the floor and climbs back to 1 once they recover. s is the
training success smoothed over iterations, each weighed by the episodes that ended in it: the first
iterations of a run end few episodes, all started together, and their rates swing from 0 to 0.95. The
warm-up iterations are those the runner steps the critic alone (runner.critic_warmup_iterations): the actor
is still the skill there. Without warm-up iterations the floor is the first iteration's success.
An iteration in which no episode ended changes nothing.

The gain. In the learn_style runs, training success answered the scale about 30 iterations late and fell
about 0.09 from scale 0 to 1 (least squares on 20-iteration means of their progress.csv). An integral step
with that delay in its loop swings whenever the gain is large: at 0.5 the scale went between 0 and 1 with a
period of some 250 iterations, success with it, and which phase a checkpoint caught decided much of the
choice. At 0.15 the loop settles within a few hundred iterations for delays up to 40 (test_success_hold).
"""

from __future__ import annotations

import math
from typing import Any


class SuccessHold:
    """The scale of the motion terms, held to keep training success above the skill's own less a margin."""

    def __init__(self, warmup_iterations: int, margin: float, gain: float, smoothing: float):
        self.warmup_iterations = max(int(warmup_iterations), 1)
        self.margin = float(margin)
        self.gain = float(gain)
        self.smoothing = float(smoothing)
        self.scale = 1.0
        self.floor: float | None = None
        self._iterations = 0
        self._successes = 0.0  # the warm-up's sums, then their smoothed values (S and E above)
        self._episodes = 0.0

    @property
    def smoothed(self) -> float | None:
        """The smoothed training success s (None before any episode ended)."""
        return self._successes / self._episodes if self._episodes > 0.0 else None

    def observe(self, success_rate: float | None, episodes: float | None) -> float:
        """The scale for the next iteration, given this iteration's training success rate over its episodes."""
        if not episodes or success_rate is None or not math.isfinite(success_rate):
            return self.scale
        successes = float(success_rate) * float(episodes)
        if self.floor is None:
            self._iterations += 1
            self._successes += successes
            self._episodes += float(episodes)
            if self._iterations >= self.warmup_iterations:
                self.floor = self.smoothed - self.margin
                # Continue from one mean warm-up iteration's worth: the smoothing's memory starts full.
                self._successes /= self._iterations
                self._episodes /= self._iterations
            return self.scale
        keep = 1.0 - self.smoothing
        self._successes = keep * self._successes + self.smoothing * successes
        self._episodes = keep * self._episodes + self.smoothing * float(episodes)
        self.scale = min(1.0, max(0.0, self.scale + self.gain * (self.smoothed - self.floor)))
        return self.scale

    def state_dict(self) -> dict[str, Any]:
        return {
            'scale': self.scale,
            'floor': self.floor,
            'iterations': self._iterations,
            'successes': self._successes,
            'episodes': self._episodes,
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Continue a resumed run where it was (its floor and scale, not a new warm-up)."""
        self.scale = float(state['scale'])
        self.floor = None if state['floor'] is None else float(state['floor'])
        self._iterations = int(state['iterations'])
        self._successes = float(state['successes'])
        self._episodes = float(state['episodes'])
