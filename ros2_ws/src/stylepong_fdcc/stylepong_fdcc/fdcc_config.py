"""The settings of the FDCC solver and its safety layer (`FdccConfig`), checked in one place.

`drag_teach_node` fills one from its parameters; `fdcc_solver` explains the gains and the dynamics
models, `wrench_conditioning`, `joint_limits` and `drag_teach_controller` the safety settings.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

DYNAMICS_MODELS = ('virtual', 'urdf')


# ---------------------------------------------------------------------------------------------------
# Configuration
# ---------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class FdccConfig:
    """All settings of the solver and its safety layer; the node fills it from its parameters."""
    # Gains: (x, y, z) in N s/m resp. N/m, then (rx, ry, rz) in N m s/rad resp. N m/rad, base_link axes.
    damping: tuple[float, ...] = (30.0, 30.0, 30.0, 3.0, 3.0, 3.0)
    stiffness: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    joint_damping_nms_per_rad: float = 0.05   # keeps motions J cannot see (singularities) damped
    dynamics_model: str = 'virtual'
    virtual_link_mass_kg: float = 0.1
    virtual_link_inertia_kg_m2: float = 1e-6
    virtual_end_mass_kg: float = 1.0
    virtual_end_inertia_kg_m2: float = 0.01
    nominal_period_s: float = 0.002           # 1 / control rate
    # A gap between cycles longer than this many nominal periods (a stalled process, not a skipped tick)
    # is integrated as this many: after a stall the arm carries on instead of jumping to catch up.
    max_late_periods: float = 2.0
    # Wrench conditioning.
    gravity_compensation: bool = True
    lowpass_cutoff_hz: float = 20.0
    force_deadband_n: float = 1.0
    torque_deadband_nm: float = 0.1
    max_force_n: float = 40.0
    max_torque_nm: float = 4.0
    reject_force_n: float = 500.0
    reject_torque_nm: float = 50.0
    tare_window_s: float = 0.2
    # Joint limits.
    position_margin_rad: float = 0.05
    velocity_limit_scale: float = 1.0         # x the URDF's velocity limits
    acceleration_limit_rad_s2: tuple[float, ...] = (8.0, 8.0, 8.0, 12.0, 12.0, 12.0)
    # Watchdog.
    watchdog_timeout_s: float = 0.05
    resume_ramp_s: float = 0.2                # after a hold the wrench fades back in over this time

    def validate(self) -> None:
        """Raise ValueError naming the first bad setting."""
        def vec(name, n=6, positive=False):
            v = np.asarray(getattr(self, name), dtype=float)
            if v.shape != (n,) or not np.all(np.isfinite(v)) or np.any(v < 0) or (positive and np.any(v == 0)):
                raise ValueError(f'{name} must be {n} finite {"positive" if positive else "non-negative"} numbers, '
                                 f'got {getattr(self, name)!r}')
        vec('damping', positive=True)
        vec('stiffness')
        vec('acceleration_limit_rad_s2', positive=True)
        if self.dynamics_model not in DYNAMICS_MODELS:
            raise ValueError(f'dynamics_model must be one of {DYNAMICS_MODELS}, got {self.dynamics_model!r}')
        positive = ('virtual_link_mass_kg', 'virtual_link_inertia_kg_m2', 'virtual_end_mass_kg',
                    'virtual_end_inertia_kg_m2', 'nominal_period_s', 'lowpass_cutoff_hz',
                    'max_force_n', 'max_torque_nm', 'reject_force_n', 'reject_torque_nm', 'tare_window_s',
                    'watchdog_timeout_s', 'resume_ramp_s')
        for name in positive:
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f'{name} must be a positive number, got {value!r}')
        for name in ('joint_damping_nms_per_rad', 'force_deadband_n', 'torque_deadband_nm', 'position_margin_rad'):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f'{name} must be a non-negative number, got {value!r}')
        if not 0 < self.velocity_limit_scale <= 1.0:
            raise ValueError(f'velocity_limit_scale must be in (0, 1], got {self.velocity_limit_scale!r}')
        if not (math.isfinite(self.max_late_periods) and self.max_late_periods >= 1.0):
            raise ValueError(f'max_late_periods must be at least 1, got {self.max_late_periods!r}')
        if self.max_force_n >= self.reject_force_n or self.max_torque_nm >= self.reject_torque_nm:
            raise ValueError('the clamp (max_force_n, max_torque_nm) must lie below the rejection thresholds')

