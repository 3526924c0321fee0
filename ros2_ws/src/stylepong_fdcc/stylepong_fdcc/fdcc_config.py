"""The settings of the FDCC solver and its safety layer (`FdccConfig`), checked in one place.

`drag_teach_node` fills one from its parameters; `fdcc_solver` explains the gains and the dynamics
models, `wrench_conditioning`, `joint_limits` and `drag_teach_controller` the safety settings.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from stylepong_common.settings import at_least, check_ranges, non_negative, positive

DYNAMICS_MODELS = ('virtual', 'urdf')


# ---------------------------------------------------------------------------------------------------
# Configuration
# ---------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class FdccConfig:
    """All settings of the solver and its safety layer; the node fills it from its parameters. A number's
    range is declared with its default (stylepong_common.settings); validate checks those and the rest."""

    # Gains: (x, y, z) in N s/m resp. N/m, then (rx, ry, rz) in N m s/rad resp. N m/rad, base_link axes.
    damping: tuple[float, ...] = (30.0, 30.0, 30.0, 3.0, 3.0, 3.0)
    stiffness: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    joint_damping_nms_per_rad: float = non_negative(0.05)  # keeps motions J cannot see (singularities) damped
    dynamics_model: str = 'virtual'
    virtual_link_mass_kg: float = positive(0.1)
    virtual_link_inertia_kg_m2: float = positive(1e-6)
    virtual_end_mass_kg: float = positive(1.0)
    virtual_end_inertia_kg_m2: float = positive(0.01)
    nominal_period_s: float = positive(0.002)  # 1 / control rate
    # A gap between cycles longer than this many nominal periods (a stalled process, not a skipped tick)
    # is integrated as this many: after a stall the arm carries on instead of jumping to catch up.
    max_late_periods: float = at_least(2.0, 1.0)
    # Wrench conditioning.
    gravity_compensation: bool = True
    lowpass_cutoff_hz: float = positive(20.0)
    force_deadband_n: float = non_negative(1.0)
    torque_deadband_nm: float = non_negative(0.1)
    max_force_n: float = positive(40.0)
    max_torque_nm: float = positive(4.0)
    reject_force_n: float = positive(500.0)
    reject_torque_nm: float = positive(50.0)
    tare_window_s: float = positive(0.2)
    # Joint limits.
    position_margin_rad: float = non_negative(0.05)
    # x the URDF's velocity limits, in (0, 1]: settings has no range open at one end only, so validate checks it.
    velocity_limit_scale: float = 1.0
    acceleration_limit_rad_s2: tuple[float, ...] = (8.0, 8.0, 8.0, 12.0, 12.0, 12.0)
    # Watchdog.
    watchdog_timeout_s: float = positive(0.05)
    resume_ramp_s: float = positive(0.2)  # after a hold the wrench fades back in over this time

    def validate(self) -> None:
        """Raise ValueError naming the first bad setting."""

        # The vectors and the choice are checked here: settings' fields hold single numbers.
        def vec(name, n=6, above_zero=False):
            v = np.asarray(getattr(self, name), dtype=float)
            if v.shape != (n,) or not np.all(np.isfinite(v)) or np.any(v < 0) or (above_zero and np.any(v == 0)):
                raise ValueError(
                    f'{name} must be {n} finite {"positive" if above_zero else "non-negative"} '
                    f'numbers, got {getattr(self, name)!r}'
                )

        vec('damping', above_zero=True)
        vec('stiffness')
        vec('acceleration_limit_rad_s2', above_zero=True)
        if self.dynamics_model not in DYNAMICS_MODELS:
            raise ValueError(f'dynamics_model must be one of {DYNAMICS_MODELS}, got {self.dynamics_model!r}')
        check_ranges(self)
        if not 0 < self.velocity_limit_scale <= 1.0:
            raise ValueError(f'velocity_limit_scale must be in (0, 1], got {self.velocity_limit_scale!r}')
        if self.max_force_n >= self.reject_force_n or self.max_torque_nm >= self.reject_torque_nm:
            raise ValueError('the clamp (max_force_n, max_torque_nm) must lie below the rejection thresholds')
