"""The one JointLimits type: the URDF's limits, and the narrower ones a controller commands within."""

import numpy as np
import pytest

from stylepong_description import robot_model


def test_the_urdf_states_no_acceleration_limit():
    limits = robot_model.joint_limits()
    assert limits.acceleration_rad_s2 is None
    assert all(
        len(v) == robot_model.NUM_JOINTS
        for v in (limits.lower_rad, limits.upper_rad, limits.velocity_rad_s, limits.effort_nm)
    )


def test_command_limits_narrow_the_urdfs_and_leave_them_alone():
    urdf = robot_model.joint_limits()
    before = urdf.lower_rad.copy()
    narrowed = robot_model.JointLimits.for_commands(0.05, 0.5, [8.0, 8.0, 8.0, 12.0, 12.0, 12.0])
    np.testing.assert_allclose(narrowed.lower_rad, urdf.lower_rad + 0.05)
    np.testing.assert_allclose(narrowed.upper_rad, urdf.upper_rad - 0.05)
    np.testing.assert_allclose(narrowed.velocity_rad_s, urdf.velocity_rad_s * 0.5)
    np.testing.assert_array_equal(narrowed.effort_nm, urdf.effort_nm)
    np.testing.assert_array_equal(narrowed.acceleration_rad_s2, [8.0, 8.0, 8.0, 12.0, 12.0, 12.0])
    np.testing.assert_array_equal(urdf.lower_rad, before)  # the cached URDF limits are not changed


def test_command_limits_need_an_acceleration_per_joint():
    with pytest.raises(ValueError, match='6 values'):
        robot_model.JointLimits.for_commands(0.0, 1.0, [8.0, 8.0])
