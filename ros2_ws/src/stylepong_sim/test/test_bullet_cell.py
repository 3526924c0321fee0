"""The PyBullet cell: Bullet's own contacts with world_spec's coefficients, the referee on its contact points,
the arm on Bullet's motors within the URDF efforts, and nothing loaded of the analytic contacts."""

import subprocess
import sys

import numpy as np
import pytest

from stylepong_description import robot_model
from stylepong_sim import referee, world_spec
from stylepong_sim.cells import ur_servoj
from stylepong_sim.cells.bullet_cell import BulletCell, InputError, coulomb_friction

HOME = np.array(world_spec.HOME_JOINT_POSITIONS_RAD)


@pytest.fixture(scope='module')
def cell():
    cell = BulletCell()
    yield cell
    cell.close()


def _bounce(cell: BulletCell, velocity_m_s, height_m: float = 0.003) -> tuple[np.ndarray, np.ndarray]:
    """Velocities just before and just after the ball's first bounce on the table (robot's half)."""
    cell.reset()
    cell.launch_ball([-0.8, 0.3, world_spec.TABLE_CONTACT_HEIGHT_M + height_m], velocity_m_s)
    for _ in range(100):
        before = cell.ball_velocity_m_s
        cell.step(1)
        after = cell.ball_velocity_m_s
        if after[2] > 0.0:
            return before, after
    raise AssertionError('no bounce')


def _types(events) -> list[str]:
    return [referee.EVENT_NAMES[e.type] for e in events]


def test_the_bullet_cell_loads_nothing_of_the_analytic_contacts():
    code = (
        'import sys, rclpy\n'
        'from stylepong_sim.nodes.ur5_sim_node import Ur5SimNode\n'
        'rclpy.init()\n'
        'node = Ur5SimNode(default_engine="pybullet")\n'
        'node._cell.step(5)\n'
        'print(sorted(m for m in sys.modules if m.startswith("stylepong_sim")))\n'
        'node.close(); node.destroy_node(); rclpy.shutdown()\n'
    )
    result = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, timeout=60, check=True)
    loaded = result.stdout.strip().splitlines()[-1]
    assert 'stylepong_sim.cells.bullet_cell' in loaded
    for module in ('ball_contacts', 'batched_world', "stylepong_sim.cells.cell'"):
        assert module not in loaded, loaded


def test_the_analytic_contact_law_is_never_called(cell, monkeypatch):
    def refuse(*_args, **_kwargs):
        raise AssertionError('world_spec.contact_response called')

    launch = world_spec.incoming_ball_for_seed(1000)
    monkeypatch.setattr(world_spec, 'contact_response', refuse)
    cell.reset()
    cell.pop_events()
    cell.launch_ball(launch.position_m, launch.velocity_m_s)
    cell.step_for(1.5)
    assert 'BOUNCE_OWN_SIDE' in _types(cell.pop_events())


def test_the_arm_holds_home_and_follows_a_step_within_the_efforts():
    for actuator in ur_servoj.ACTUATORS:
        cell = BulletCell(actuator=actuator)
        cell.step_for(0.5)
        assert cell.joint_positions_rad == pytest.approx(HOME, abs=1e-3)
        target = HOME + np.array([0.2, -0.1, 0.1, 0.1, -0.1, 0.2])
        cell.set_joint_targets(target)
        peak_effort = np.zeros(6)
        for _ in range(700):
            cell.step(1)
            peak_effort = np.maximum(peak_effort, np.abs(cell.joint_efforts_nm))
        assert cell.joint_positions_rad == pytest.approx(target, abs=0.01), actuator
        assert (peak_effort <= robot_model.joint_limits().effort_nm + 1e-6).all()
        cell.close()


def test_table_bounce_has_world_specs_restitution_and_tangential_factor(cell):
    for vertical in (-1.5, -3.0, -6.0):
        before, after = _bounce(cell, [0.0, 0.0, vertical])
        assert -after[2] / before[2] == pytest.approx(world_spec.TABLE_RESTITUTION, abs=0.005)
    # at the reference impact ratio the sliding ball keeps world_spec's tangential factor
    before, after = _bounce(cell, [1.67 * 3.0, 0.0, -3.0])
    assert after[0] / before[0] == pytest.approx(world_spec.TABLE_TANGENTIAL_FACTOR, abs=0.02)
    assert coulomb_friction(0.7, 0.89, 1.67) == pytest.approx(0.3 * 1.67 / 1.89)


def test_a_seeded_ball_bounces_where_world_spec_aims_it(cell):
    launch = world_spec.incoming_ball_for_seed(1001)
    cell.reset()
    cell.pop_events()
    cell.launch_ball(launch.position_m, launch.velocity_m_s)
    cell.step_for(3.2)
    events = cell.pop_events()
    bounce = next(e for e in events if e.type == referee.BOUNCE_OWN_SIDE)
    assert (
        np.hypot(bounce.position_m[0] - launch.bounce_point_m[0], bounce.position_m[1] - launch.bounce_point_m[1])
        < 0.03
    )
    ends = [e for e in events if e.type == referee.RALLY_END]
    assert len(ends) == 1 and not ends[0].success


def test_a_ball_thrown_at_the_resting_blade_is_hit_and_bounces_back(cell):
    cell.reset()
    cell.pop_events()
    centre, rotation = cell.paddle_pose()
    normal = rotation[:, 2]
    start = centre + 0.25 * normal + np.array([0.0, 0.0, 0.017])  # gravity drops it 17 mm on the way
    speed = 3.0
    cell.launch_ball(start, -speed * normal)
    incoming = None
    for _ in range(200):
        velocity = cell.ball_velocity_m_s
        cell.step(1)
        if np.dot(cell.ball_velocity_m_s, normal) > 0.0:
            incoming = velocity
            break
    assert incoming is not None
    outgoing = cell.ball_velocity_m_s
    restitution = -np.dot(outgoing, normal) / np.dot(incoming, normal)
    assert restitution == pytest.approx(world_spec.PADDLE_RESTITUTION, abs=0.03)
    assert 'PADDLE_HIT' in _types(cell.pop_events())


def test_the_wrench_reads_the_paddles_weight_and_the_hand_which_the_joints_carry():
    cell = BulletCell()
    cell.step_for(0.2)
    weight = robot_model.PADDLE.mass_kg * world_spec.GRAVITY_M_S2
    force, _ = cell.tool_wrench()
    _, rotation = cell.tool_pose()
    assert rotation @ force == pytest.approx([0.0, 0.0, -weight], abs=1e-3)
    efforts_before = cell.joint_efforts_nm
    cell.set_hand_wrench([0.0, 0.0, 60.0], duration_s=0.05)
    cell.step_for(0.03)
    force, _ = cell.tool_wrench()
    assert rotation @ force == pytest.approx([0.0, 0.0, 60.0 - weight], abs=1e-2)
    # Bullet's motors hold the arm against the hand: the lift and elbow joints take tens of N m more
    assert np.abs(cell.joint_efforts_nm - efforts_before)[1:3].max() > 20.0
    cell.step_for(0.05)  # released after its duration
    force, _ = cell.tool_wrench()
    assert np.linalg.norm(force) == pytest.approx(weight, abs=1e-3)
    cell.close()


def test_bad_inputs_are_refused(cell):
    with pytest.raises(InputError, match='6 joint positions'):
        cell.set_joint_targets([0.0] * 5)
    with pytest.raises(InputError, match='outside the cell'):
        cell.launch_ball([0.0, 0.0, -1.0], [0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match='actuator'):
        BulletCell(actuator='servo')


def test_the_video_view_poses_the_mujoco_scene_like_the_bullet_cell(cell):
    from stylepong_sim.cells.bullet_video import MirroredScene

    view = MirroredScene()
    cell.reset()
    cell.set_joint_targets(HOME + 0.1)
    cell.step_for(0.2)
    cell.launch_ball([-0.5, 0.2, 1.0], [-3.0, 0.0, 0.0])
    data = view.show(cell)
    assert data.qpos[:6] == pytest.approx(cell.joint_positions_rad)
    assert data.mocap_pos[0] == pytest.approx(cell.ball_position_m)
    # the two engines agree on where the blade is for the same joint positions (same URDF)
    centre, _ = cell.paddle_pose()
    assert data.xpos[view.model.body(robot_model.PADDLE_CENTRE_FRAME).id] == pytest.approx(centre, abs=1e-5)


def test_the_pd_joint_drive_follows_a_step_with_world_specs_servo():
    cell = BulletCell(joint_drive='pd')
    target = HOME + 0.2
    cell.set_joint_targets(target)
    cell.step_for(0.6)
    assert cell.joint_positions_rad == pytest.approx(target, abs=1e-3)
    cell.close()
    with pytest.raises(ValueError, match='joint_drive'):
        BulletCell(joint_drive='servo')


def test_every_joint_carries_world_specs_rotor_inertia():
    # From rest at home, one 1 ms step of the PD drive's torques (gravity compensated) on wrist_3: the joints
    # accelerate as (M(q) + diag(armature))^-1 tau, where Bullet's own mass matrix M lacks the rotors.
    cell = BulletCell(joint_drive='pd')
    cell.set_joint_targets(HOME + np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.5]))
    cell.step(1)
    zeros = [0.0] * 6
    gravity = np.array(cell._p.calculateInverseDynamics(cell._robot, HOME.tolist(), zeros, zeros))
    net_torque = cell.joint_efforts_nm - gravity
    mass_matrix = np.array(cell._p.calculateMassMatrix(cell._robot, HOME.tolist()))
    acceleration = cell.joint_velocities_rad_s / cell.dt_s
    cell.close()
    assert net_torque[5] > 1.0
    expected = np.linalg.solve(mass_matrix + np.diag(world_spec.ARM_ARMATURE_KG_M2), net_torque)
    assert acceleration == pytest.approx(expected, rel=0.02, abs=0.05)
    without_rotors = np.linalg.solve(mass_matrix, net_torque)
    assert abs(acceleration[5]) < 0.5 * abs(without_rotors[5])


def test_the_robot_touches_the_table_only_where_a_contact_point_pushes(cell, monkeypatch):
    """Bullet lists manifold points still apart (distance up to its breaking threshold, normal force 0):
    those are not a touch; a point that pushes is, and the referee ends the rally on it."""
    cell.reset()
    cell.launch_ball([1.0, 0.0, 1.0], [-3.0, 0.0, 0.0])
    cell.pop_events()
    blade = (0, cell._robot, cell._table, cell._blade_link, -1, (0.0, 0.0, 0.77), (0.0, 0.0, 0.77), (0.0, 0.0, 1.0))
    points = {'apart': [(*blade, 0.004, 0.0)], 'pushing': [(*blade, -0.0005, 40.0)]}
    for kind, expected in (('apart', False), ('pushing', True)):
        monkeypatch.setattr(
            cell._p,
            'getContactPoints',
            lambda bodyA=None, bodyB=None, _k=kind: points[_k] if bodyB == cell._table else [],
        )
        cell._check_robot_table_contacts()
        touched = referee.TABLE_CONTACT_BY_ROBOT in [e.type for e in cell.pop_events()]
        assert touched == expected, kind
