"""The figures the paper reports ("Stylized Table Tennis Robots Skill Learning with Incomplete Human
Demonstrations", Experiments), as printed, for `paper_tables` to set beside ours.

Method names: the paper's "PPO" is our `ppo` actor, its "AMP" (the motion prior without the sped-up
reference clips) our `amp-noaug`, its "Our Method" (with them) our `amp`. Every table counts 200
balls per seed over 10 seeds; "Mean Success" is the mean number of successes per seed.
"""

from __future__ import annotations

from dataclasses import dataclass

PAPER_NAMES = {'ppo': 'PPO', 'amp-noaug': 'AMP', 'amp': 'Our Method'}
ATTEMPTS_PER_SEED = 200


@dataclass(frozen=True)
class SuccessFigure:
    """A success row of the paper: attempts, mean successes and success rate."""

    attempts: int
    mean_success: float
    success_rate: float


# Table I: success rate, all incoming speeds.
TABLE_I = {
    'ppo': SuccessFigure(200, 192.53, 0.9627),
    'amp-noaug': SuccessFigure(200, 163.22, 0.8161),
    'amp': SuccessFigure(200, 180.64, 0.9032),
}

# Table II: DTW distance of joint-position sequences to the reference motion (lower is better).
TABLE_II = {
    'ppo': {'forward': 148.23, 'leftward': 263.77, 'rightward': 403.85},
    'amp': {'forward': 62.73, 'leftward': 133.22, 'rightward': 243.56},
}

# Table III: low (4.0-4.8 m/s) and high (5.8-6.6 m/s) incoming speeds.
TABLE_III = {
    ('amp-noaug', 'low'): SuccessFigure(200, 184.29, 0.9215),
    ('amp', 'low'): SuccessFigure(200, 183.89, 0.9195),
    ('amp-noaug', 'high'): SuccessFigure(200, 138.00, 0.6900),
    ('amp', 'high'): SuccessFigure(200, 171.00, 0.8591),
}

# Table IV: the trained policy in its training simulator and in another one.
TABLE_IV = {
    'IsaacGym (training simulator)': SuccessFigure(200, 142.78, 0.7139),
    'PyBullet (other simulator)': SuccessFigure(200, 78.64, 0.3932),
}

# Where the paper's own numbers disagree with each other (worth knowing before comparing with them).
INCONSISTENCIES = (
    'Table I gives Our Method 90.32 % while the text says 93 %.',
    "Table III's high-speed Our Method row has a mean of 171.00 of 200 (85.50 %) but a rate of 85.91 %.",
    "Table IV's IsaacGym row (71.39 %) is not Table I's 90.32 % for the same method; the paper does not "
    'say which setting (randomisation, seeds) each used.',
)
