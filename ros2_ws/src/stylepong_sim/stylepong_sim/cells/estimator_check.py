"""The ball estimator against the cell's truth, without ROS: the tracker sees the MuJoCo cell's ball, the
estimator (stylepong_player.ball_estimator) turns its detections into states, and each published state is
compared with the true one at its stamp.

Used by the estimator's accuracy test and by `make bench`. The arm stays at home (it may touch the ball;
only the flight up to the first paddle contact is compared).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from stylepong_player.ball_estimator import BallEstimator, EstimatorConfig, Outcome
from stylepong_sim import referee, world_spec
from stylepong_sim.cells.cell import Cell
from stylepong_sim.cells.sensing import SampleClock
from stylepong_sim.cells.tracker import BallTracker, TrackerConfig, camera_to_world


@dataclass(frozen=True)
class EstimateError:
    """One published estimate: when, and how far from the truth at its stamp."""

    seed: int
    since_appeared_s: float  # stamp - the ball's launch
    since_bounce_s: float  # stamp - the first bounce on the robot's half (nan before it)
    position_error_m: float
    velocity_error_m_s: float
    velocity_std_m_s: float  # what the estimator said of its velocity


def estimator_errors(
    seeds, tracker_config: TrackerConfig, estimator_config: EstimatorConfig | None = None, cell=None
) -> list[EstimateError]:
    """Every published estimate's error over one ball per seed (evaluate's incoming balls), in `cell` (a
    MuJoCo Cell by default; a BulletCell works alike)."""
    cell = cell or Cell()
    out: list[EstimateError] = []
    for seed in seeds:
        out += _one_ball(cell, int(seed), tracker_config, estimator_config)
    return out


def _one_ball(
    cell, seed: int, tracker_config: TrackerConfig, estimator_config: EstimatorConfig | None
) -> list[EstimateError]:
    cell.reset()
    rng = np.random.default_rng(seed)
    tracker = BallTracker(tracker_config, rng)
    estimator = BallEstimator(estimator_config)
    clock = SampleClock(tracker_config.rate_hz, start_s=cell.time_s)
    launch = world_spec.incoming_ball_for_seed(seed)
    launch_s = cell.time_s
    cell.launch_ball(launch.position_m, launch.velocity_m_s)
    truth: dict[float, tuple[np.ndarray, np.ndarray]] = {}
    bounce_s, hit = np.nan, False
    errors = []
    while cell.ball_in_play and not hit:
        cell.step(1)
        t = cell.time_s
        for event in cell.pop_events():
            if event.type == referee.BOUNCE_OWN_SIDE and np.isnan(bounce_s):
                bounce_s = event.time_s
            hit = hit or event.type == referee.PADDLE_HIT
        if clock.due(t) and cell.ball_in_play:
            truth[round(t, 6)] = (cell.ball_position_m, cell.ball_velocity_m_s)
            tracker.expose(t, cell.ball_position_m)
        for detection in tracker.delivered(t):
            result = estimator.update(detection.stamp_s, camera_to_world(tracker_config, detection.position_camera_m))
            true = truth.get(round(detection.stamp_s, 6))
            if result.outcome != Outcome.PUBLISHED or true is None:
                continue
            e = result.estimate
            errors.append(
                EstimateError(
                    seed,
                    e.stamp_s - launch_s,
                    e.stamp_s - bounce_s,
                    float(np.linalg.norm(e.position_m - true[0])),
                    float(np.linalg.norm(e.velocity_m_s - true[1])),
                    e.velocity_std_m_s,
                )
            )
    return errors
