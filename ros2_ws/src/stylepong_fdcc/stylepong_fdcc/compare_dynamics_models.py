"""Developer tool: `python3 -m stylepong_fdcc.compare_dynamics_models` prints how the two dynamics models
answer a 10 N push (the figures in `fdcc_solver`'s docstring and docs/DESIGN.md, "FDCC: the virtual
dynamics model")."""

from __future__ import annotations

import time

import numpy as np
import pinocchio as pin

from stylepong_fdcc.fdcc_config import DYNAMICS_MODELS, FdccConfig
from stylepong_fdcc.fdcc_solver import FdccSolver


def simulate_push(
    config: FdccConfig, q0: np.ndarray, force_base_n: np.ndarray, push_s: float, total_s: float, rate_hz: float
) -> dict:
    """Drive the solver alone (a perfect servo) with a constant force at tool0, then nothing."""
    solver = FdccSolver(config)
    solver.reset(q0)
    start = solver.pose().translation.copy()
    dt = 1.0 / rate_hz
    wrench = np.concatenate([np.asarray(force_base_n, dtype=float), np.zeros(3)])
    steps = int(round(total_s * rate_hz))
    push_steps = int(round(push_s * rate_hz))
    positions, speeds, joint_speeds, rotations = [], [], [], []
    for k in range(steps):
        solver.step(wrench if k < push_steps else np.zeros(6), dt)
        pose = solver.pose()
        positions.append(pose.translation.copy())
        rotations.append(pose.rotation.copy())
        speeds.append(solver.twist()[:3].copy())
        joint_speeds.append(np.max(np.abs(solver.qdot)))
    positions, speeds = np.array(positions), np.array(speeds)
    direction = np.asarray(force_base_n) / np.linalg.norm(force_base_n)
    along = speeds @ direction
    steady = along[push_steps - 1]
    rise = int(np.argmax(along >= 0.9 * steady)) + 1
    push_disp = positions[push_steps - 1] - start
    rest = next((k for k in range(push_steps, steps) if joint_speeds[k] < 0.05), steps)
    return {
        'rise_s': rise * dt,
        'push_displacement_m': float(np.linalg.norm(push_disp)),
        'direction_cosine': float(push_disp @ direction / np.linalg.norm(push_disp)),
        'coast_m': float(np.linalg.norm(positions[-1] - positions[push_steps - 1])),
        'rest_after_s': (rest - push_steps + 1) * dt,
        'final_displacement_m': float(np.linalg.norm(positions[-1] - start)),
        'push_rotation_rad': float(np.linalg.norm(pin.log3(rotations[push_steps - 1] @ rotations[0].T))),
    }


def main() -> None:
    """Print the solver's response to a 10 N push at the home pose for each dynamics model."""
    from stylepong_sim.world_spec import HOME_JOINT_POSITIONS_RAD  # a developer tool: the cell's home pose

    home = np.array(HOME_JOINT_POSITIONS_RAD)
    print('10 N push along +x of base_link for 1 s at 500 Hz, solver alone, home pose')
    for kind in DYNAMICS_MODELS:
        config = FdccConfig(dynamics_model=kind)
        started = time.perf_counter()
        result = simulate_push(config, home, np.array([10.0, 0.0, 0.0]), 1.0, 4.0, 500.0)
        print(
            f'{kind:8s} '
            + ', '.join(f'{k} {v:.3f}' for k, v in result.items())
            + f'  ({time.perf_counter() - started:.1f} s)'
        )


if __name__ == '__main__':
    main()
