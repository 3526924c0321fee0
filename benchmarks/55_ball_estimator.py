#!/usr/bin/env python3
"""ball_estimator: its error against the simulated cell's truth, and its cost per detection.

1. Accuracy, no ROS (stylepong_sim.cells.estimator_check): the MuJoCo cell and the PyBullet cell serve
   `evaluate`'s incoming balls of SEEDS (the arm parked at home), the tracker of config/tracker_sensing.yaml
   (150 Hz, 20 +- 5 ms, 3 mm, 3 % lost, 1 % false) sees them, BallEstimator with its defaults turns the
   detections into states, and each published state is compared with the cell's true ball at its stamp,
   up to the first paddle contact. Figures: p50 and p95 of the position and velocity errors by the time
   since the ball appeared (before its bounce) and since its bounce on the robot's half.
2. Cost: BallEstimator.update per detection on this machine (the node adds ROS's deserialisation).
Prints one Markdown section for BENCHMARKS.md (`make bench`).
"""

import time

import numpy as np
import yaml

from stylepong_player.ball_estimator import BallEstimator
from stylepong_player.ball_prediction import predict_ball
from stylepong_sim.cells.estimator_check import estimator_errors
from stylepong_sim.cells.tracker import TrackerConfig

SEEDS = range(900, 960)  # validation seeds: one ball each
APPEARED_BINS_S = (0.0, 0.05, 0.1, 0.2, 0.4, 1.0)
BOUNCE_BINS_S = (0.0, 0.02, 0.05, 0.1, 0.2)
COST_DETECTIONS = 5000


def tracker_preset() -> TrackerConfig:
    from ament_index_python.packages import get_package_share_directory

    path = f'{get_package_share_directory("stylepong_sim")}/config/tracker_sensing.yaml'
    with open(path) as file:
        p = yaml.safe_load(file)['ur5_sim']['ros__parameters']
    return TrackerConfig(
        p['ball_detection_rate_hz'],
        p['ball_detection_latency_s'],
        p['ball_detection_latency_jitter_s'],
        p['ball_detection_noise_std_m'],
        p['ball_detection_dropout_probability'],
        p['ball_detection_outlier_probability'],
    )


def table(errors, key: str, bins) -> list[str]:
    rows = []
    for low, high in zip(bins, bins[1:]):
        chosen = [
            e
            for e in errors
            if low <= getattr(e, key) < high and (key == 'since_bounce_s' or not e.since_bounce_s >= 0.0)
        ]
        if not chosen:
            continue
        p = np.array([e.position_error_m for e in chosen]) * 1e3
        v = np.array([e.velocity_error_m_s for e in chosen])
        rows.append(
            f'| {low * 1e3:.0f}-{high * 1e3:.0f} ms | {len(chosen)} | {np.median(p):.1f} | '
            f'{np.percentile(p, 95):.1f} | {np.median(v):.3f} | {np.percentile(v, 95):.3f} |'
        )
    return rows


def cost_per_detection_s() -> float:
    estimator, rng = BallEstimator(), np.random.default_rng(0)
    p, v, stamp = np.zeros(3), np.zeros(3), 0.0
    started = time.perf_counter()
    for k in range(COST_DETECTIONS):
        if k % 100 == 0:  # a new ball every 100 frames, so tracks start, confirm and bounce
            p, v, stamp = np.array([1.2, 0.1, 1.0]), np.array([-5.5, -0.2, 0.3]), stamp + 0.5
        stamp += 1.0 / 150.0
        p, v = predict_ball(p, v, 1.0 / 150.0)
        estimator.update(stamp, p + rng.normal(0.0, 0.003, 3))
    return (time.perf_counter() - started) / COST_DETECTIONS


def main() -> None:
    from stylepong_sim.cells.bullet_cell import BulletCell
    from stylepong_sim.cells.cell import Cell

    config = tracker_preset()
    lines = [
        "## ball_estimator: error against the cells' truth, cost per detection",
        '',
        f'`benchmarks/55_ball_estimator.py`: no ROS; one ball per validation seed {SEEDS[0]}-{SEEDS[-1]} '
        f"(`evaluate`'s incoming balls, the arm at home), the tracker of `config/tracker_sensing.yaml` "
        f'({config.rate_hz:g} Hz, {config.latency_s * 1e3:g} +- {config.latency_jitter_s * 1e3:g} ms, '
        f'{config.position_noise_std_m * 1e3:g} mm, {config.dropout_probability:.0%} lost, '
        f"{config.outlier_probability:.0%} false), the estimator's defaults; every published state "
        'against the true ball at its stamp, up to the first paddle contact. Errors are Euclidean.',
    ]
    for name, cell in (('MuJoCo cell', Cell()), ('PyBullet cell', BulletCell())):
        errors = estimator_errors(SEEDS, config, cell=cell)
        header = [
            '| window | states | position p50 (mm) | p95 | velocity p50 (m/s) | p95 |',
            '|---|---|---|---|---|---|',
        ]
        lines += ['', f'{name}, before the bounce, by the time since the ball appeared:', ''] + header
        lines += table(errors, 'since_appeared_s', APPEARED_BINS_S)
        lines += ['', f"{name}, after the bounce on the robot's half, by the time since it:", ''] + header
        lines += table(errors, 'since_bounce_s', BOUNCE_BINS_S)
    lines += [
        '',
        f'Cost: {cost_per_detection_s() * 1e3:.3f} ms per detection (`BallEstimator.update`, '
        f'{COST_DETECTIONS} detections, this machine).',
    ]
    print('\n'.join(lines))


if __name__ == '__main__':
    main()
