"""The batched world's parts: kinematics and dynamics against Pinocchio, the ball's contacts, the referee's
rules in batch, the servo's limits and the vectorised incoming-ball distribution."""

import math

import numpy as np
import pinocchio as pin
import pytest
import torch

from stylepong_description import robot_model
from stylepong_sim import referee, world_spec
from stylepong_sim.batched import batched_kinematics, batched_launcher, batched_world

HOME = torch.tensor(world_spec.HOME_JOINT_POSITIONS_RAD, dtype=torch.float64)


@pytest.fixture(scope='module')
def model64():
    return batched_kinematics.build_arm_model(dtype=torch.float64)


def _random_configurations(n, seed=7):
    rng = np.random.default_rng(seed)
    return rng.uniform(-math.pi, math.pi, size=(n, 6)), rng.uniform(-3.0, 3.0, size=(n, 6))


def test_forward_kinematics_matches_pinocchio(model64):
    q, _ = _random_configurations(20)
    kin = batched_kinematics.forward_kinematics(model64, torch.tensor(q).T)
    model = robot_model.pinocchio_model()
    data = model.createData()
    base = pin.SE3(*world_spec.robot_base_pose())
    frame = model.getFrameId(robot_model.PADDLE_CENTRE_FRAME)
    for i in range(len(q)):
        pin.framesForwardKinematics(model, data, q[i])
        paddle = base * data.oMf[frame]
        np.testing.assert_allclose(kin.paddle_pos_m[:, i].numpy(), paddle.translation, atol=1e-12)
        np.testing.assert_allclose(kin.paddle_rot[..., i].numpy(), paddle.rotation, atol=1e-12)
        for j in range(6):
            joint = base * data.oMi[j + 1]
            np.testing.assert_allclose(kin.origin_m[:, j, i].numpy(), joint.translation, atol=1e-12)
            np.testing.assert_allclose(kin.rot[:, :, j, i].numpy(), joint.rotation, atol=1e-12)


def test_mass_matrix_and_bias_torques_match_pinocchio(model64):
    q, qd = _random_configurations(20)
    sp = batched_kinematics.spatial(model64, batched_kinematics.forward_kinematics(model64, torch.tensor(q).T))
    mass = batched_kinematics.mass_matrix(sp)
    coriolis = batched_kinematics.bias_torques(sp, torch.tensor(qd).T)
    with_gravity = batched_kinematics.bias_torques(sp, torch.tensor(qd).T, world_spec.GRAVITY_M_S2)
    model = robot_model.pinocchio_model()
    data = model.createData()
    for i in range(len(q)):
        expected = pin.crba(model, data, q[i])
        expected = np.triu(expected) + np.triu(expected, 1).T
        np.testing.assert_allclose(mass[..., i].numpy(), expected, atol=1e-12)
        np.testing.assert_allclose(
            with_gravity[:, i].numpy(), pin.rnea(model, data, q[i], qd[i], np.zeros(6)), atol=1e-11
        )
        model.gravity.linear[:] = 0.0
        np.testing.assert_allclose(coriolis[:, i].numpy(), pin.rnea(model, data, q[i], qd[i], np.zeros(6)), atol=1e-11)
        model.gravity.linear[:] = (0.0, 0.0, -world_spec.GRAVITY_M_S2)


def test_link_capsules_enclose_the_collision_meshes():
    import mujoco

    mj = robot_model.mujoco_model()
    for capsule in batched_kinematics.link_capsules():
        if capsule.name == 'paddle_handle':
            continue
        body = mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_BODY, capsule.name)
        a, b = np.array(capsule.a_m), np.array(capsule.b_m)
        for geom in range(mj.ngeom):
            if mj.geom_bodyid[geom] != body or mj.geom_type[geom] != mujoco.mjtGeom.mjGEOM_MESH:
                continue
            mesh = mj.geom_dataid[geom]
            vertices = mj.mesh_vert[mj.mesh_vertadr[mesh] : mj.mesh_vertadr[mesh] + mj.mesh_vertnum[mesh]]
            points = vertices @ batched_kinematics._quat_to_matrix(mj.geom_quat[geom]).T + mj.geom_pos[geom]
            t = np.clip((points - a) @ (b - a) / max(float((b - a) @ (b - a)), 1e-12), 0.0, 1.0)
            distance = np.linalg.norm(points - (a + t[:, None] * (b - a)), axis=1)
            assert distance.max() <= capsule.radius_m + 1e-9, capsule.name


def _world(n=1, **kwargs):
    return batched_world.BatchedWorld(n, dtype=torch.float64, **kwargs)


def _launch(world, positions, velocities, hit=None):
    n = len(positions)
    ids = torch.arange(n)
    world.reset_envs(
        ids,
        world.q_rad[:, :n].clone(),
        torch.tensor(positions, dtype=torch.float64).T,
        torch.tensor(velocities, dtype=torch.float64).T,
    )
    if hit is not None:
        world.hit[ids] = torch.tensor(hit)


def _run_to_verdict(world, max_steps=240):
    command = world.q_rad.clone()
    for _ in range(max_steps):
        world.step(command)
        if not bool(world.open.any()):
            break
    return [referee.REASONS[int(r)] if r >= 0 else None for r in world.reason]


def test_free_flight_matches_a_fine_reference():
    world = _world()
    _launch(world, [(1.2, 0.1, 1.3)], [(-5.0, 0.3, 2.0)])
    for _ in range(18):  # 0.3 s, before any contact
        world.step(world.q_rad.clone())
    p = np.array([1.2, 0.1, 1.3])
    v = np.array([-5.0, 0.3, 2.0])
    dt = 1e-5
    for _ in range(int(round(0.3 / dt))):
        v = v + (np.array([0.0, 0.0, -world_spec.GRAVITY_M_S2]) + world_spec.drag_acceleration(v)) * dt
        p = p + v * dt
    np.testing.assert_allclose(world.ball_pos_m[:, 0].numpy(), p, atol=2e-4)
    np.testing.assert_allclose(world.ball_vel_m_s[:, 0].numpy(), v, atol=2e-3)


def test_table_bounce_follows_the_contact_law_and_nothing_tunnels():
    # Balls dropped fast onto the table (up to 30 m/s: 25 cm per physics step) bounce, none passes through.
    speeds = [3.0, 10.0, 20.0, 30.0]
    world = _world(len(speeds))
    _launch(world, [(-0.5, 0.0, 1.2)] * len(speeds), [(2.0, 0.0, -s) for s in speeds])
    bounced = torch.zeros(len(speeds), dtype=torch.bool)
    for _ in range(10):
        events = world.step(world.q_rad.clone())
        bounced |= events.own_bounce
        assert (world.ball_pos_m[2] > world_spec.TABLE_HEIGHT_M).all()
    assert bounced.all()
    assert (world.ball_pos_m[2] > world_spec.TABLE_HEIGHT_M).all()
    # A ball bouncing vertically at 4 m/s leaves at restitution x 4 m/s.
    world = _world()
    _launch(world, [(-0.5, 0.0, world_spec.TABLE_CONTACT_HEIGHT_M + 0.02)], [(0.0, 0.0, -4.0)])
    world.step(world.q_rad.clone())
    assert world.own_bounces[0] == 1
    # Midpoint flight after the bounce: v_z = e * v_in - g * t_after (drag small at this speed).
    assert float(world.ball_vel_m_s[2, 0]) == pytest.approx(world_spec.TABLE_RESTITUTION * 4.0, abs=0.2)


def test_fast_ball_does_not_tunnel_through_the_blade():
    world = _world(3)
    centre = world.paddle_pos_m[:, 0].numpy()
    normal = world.paddle_rot[:, 2, 0].numpy()
    starts, velocities = [], []
    for speed in (5.0, 15.0, 30.0):
        starts.append(tuple(centre + 0.2 * normal))
        velocities.append(tuple(-speed * normal))
    _launch(world, starts, velocities)
    hit = torch.zeros(3, dtype=torch.bool)
    for _ in range(4):
        hit |= world.step(world.q_rad.clone()).paddle_hit
    assert hit.all()
    # The balls left on the face's side, away from the blade.
    offsets = world.ball_pos_m.numpy().T - centre
    assert (offsets @ normal > 0).all()


@pytest.mark.parametrize(
    'start, velocity, hit, reason',
    [
        ((-1.0, 0.0, 1.05), (5.0, 0.0, 1.0), True, referee.REASON_RETURNED),  # over the net onto the far half
        ((-1.0, 0.0, 1.0), (1.5, 0.0, 0.5), True, referee.REASON_OWN_SIDE),  # short: first bounce on own half
        ((-0.5, 0.0, 0.9), (6.0, 0.0, 0.0), True, referee.REASON_NET),  # straight into the net
        ((-1.0, 0.0, 1.05), (12.0, 0.0, 1.0), True, referee.REASON_OUT),  # long
        ((-1.0, 0.5, 1.0), (0.0, 3.0, 0.5), True, referee.REASON_OUT),  # off the side
        ((-0.6, 0.0, 1.1), (-0.5, 0.0, 0.0), False, referee.REASON_SECOND_BOUNCE_OWN_SIDE),
        ((-1.0, 1.0, 1.2), (0.0, 1.0, 0.0), False, referee.REASON_NO_HIT),  # falls beside the table
    ],
)
def test_referee_rules(start, velocity, hit, reason):
    world = _world()
    _launch(world, [start], [velocity], hit=[hit])
    assert _run_to_verdict(world) == [reason]
    assert bool(world.success[0]) == (reason == referee.REASON_RETURNED)


def test_referee_rules_in_one_batch_match_one_by_one():
    cases = [
        ((-1.0, 0.0, 1.05), (5.0, 0.0, 1.0), True),
        ((-0.5, 0.0, 0.9), (6.0, 0.0, 0.0), True),
        ((-0.6, 0.0, 1.1), (-0.5, 0.0, 0.0), False),
        ((-1.0, 1.0, 1.2), (0.0, 1.0, 0.0), False),
    ]
    world = _world(len(cases))
    _launch(world, [c[0] for c in cases], [c[1] for c in cases], hit=[c[2] for c in cases])
    batch = _run_to_verdict(world)
    singles = []
    for start, velocity, hit in cases:
        single = _world()
        _launch(single, [start], [velocity], hit=[hit])
        singles += _run_to_verdict(single)
    assert batch == singles


def test_ball_on_the_arm_is_robot_contact_and_a_second_touch_is_a_double_hit():
    world = _world(2)
    kin = world.kinematics
    forearm = kin.origin_m[:, 2, 0] + 0.5 * (kin.origin_m[:, 3, 0] - kin.origin_m[:, 2, 0])  # mid forearm
    above = forearm + torch.tensor([0.0, 0.0, 0.3], dtype=torch.float64)
    centre = world.paddle_pos_m[:, 0]
    normal = world.paddle_rot[:, 2, 0]
    _launch(
        world,
        [tuple(above.tolist()), tuple((centre + 0.3 * normal).tolist())],
        [(0.0, 0.0, -3.0), tuple((-4.0 * normal).tolist())],
        hit=[False, True],
    )
    assert _run_to_verdict(world, 30) == [referee.REASON_ROBOT_CONTACT, referee.REASON_DOUBLE_HIT]


def test_paddle_on_the_table_ends_the_rally():
    world = _world()
    _launch(world, [(1.2, 0.0, 1.3)], [(-4.0, 0.0, 1.0)])
    # Shoulder lift down and elbow stretched: the blade goes down onto the table's end.
    command = world.q_rad.clone()
    command[1] += 0.9
    command[2] -= 0.6
    for _ in range(90):
        world.step(command)
        if not bool(world.open[0]):
            break
    assert referee.REASONS[int(world.reason[0])] == referee.REASON_TABLE_CONTACT_BY_ROBOT


def test_a_command_into_the_table_is_told_apart_from_one_above_it():
    world = _world(3)
    home = world.q_rad[:, :1].clone()
    into = home.clone()
    into[1] += 0.9  # the command of the test above: the arm would reach down onto the table's end
    into[2] -= 0.6
    under = home.clone()
    under[1] += 1.6  # further: the forearm goes through the top and below the slab
    commands = torch.cat((home, into, under), dim=1)
    assert world.commands_below_table_top(commands).tolist() == [False, True, True]
    # Only the first lies above the top; the check is of the command, not of where the arm is.
    assert not bool(world.commands_below_table_top(world.q_rad).any())


def test_timeout():
    world = _world(timeout_s=0.5)
    _launch(world, [(0.0, 0.0, 2.0)], [(0.0, 0.0, 0.0)])
    world.params.gravity_m_s2[:] = 0.0  # a ball that hangs in the air
    assert _run_to_verdict(world) == [referee.REASON_TIMEOUT]
    assert float(world.time_s[0]) == pytest.approx(0.5, abs=1e-9)


def test_servo_respects_velocity_and_effort_limits_and_targets_are_clipped_to_the_joint_range():
    world = _world()
    limits = robot_model.joint_limits()
    command = HOME[:, None] + torch.tensor([3.0, -3.0, 3.0, -3.0, 3.0, -3.0], dtype=torch.float64)[:, None]
    peak = torch.zeros(6, dtype=torch.float64)
    for _ in range(60):
        world.step(command)
        peak = torch.maximum(peak, world.qd_rad_s[:, 0].abs())
    assert (peak <= torch.tensor(limits.velocity_rad_s) + 1e-9).all()
    assert (peak >= 0.99 * torch.tensor(limits.velocity_rad_s)).all()  # it does run at the limit
    assert (world.q_cmd_rad[:, 0] <= torch.tensor(limits.upper_rad)).all()
    assert (world.q_cmd_rad[:, 0] >= torch.tensor(limits.lower_rad)).all()


def test_action_delay_holds_the_previous_command():
    world = _world(2)
    command = world.q_rad.clone()
    command[0] += 0.5
    world.step(command, delay_steps=torch.tensor([0, world.physics_steps]))
    moved = (world.q_rad[0] - HOME[0]).abs()
    assert moved[0] > 1e-3 and moved[1] < 1e-9


def test_action_delay_of_d_physics_steps_applies_each_command_d_steps_late_per_env_and_reset_clears_it():
    """Per env, the servo target in each physics step is the command given d physics steps earlier: with
    d = physics_steps the previous period's command, never one that stays stuck at its reset value."""
    world = _world(3)
    n, steps = world.num_envs, world.physics_steps
    delays = torch.arange(steps + 1)  # one env per delay: 0, 1, ..., physics_steps
    targets = []  # the servo target in every physics step
    arm_step = world._arm_step

    def recording_arm_step(dynamics):
        targets.append(world.q_cmd_rad[0].clone())
        arm_step(dynamics)

    world._arm_step = recording_arm_step
    home = world.q_rad[0].clone()
    commands = [home + 0.1 * (i + 1) for i in range(4)]  # joint 0's target in each policy period
    for value in commands:
        q_cmd = world.q_rad.clone()
        q_cmd[0] = value
        world.step(q_cmd, delay_steps=delays)
    # Physics step t of env e tracks the command given at physics step t - d_e (its reset pose before 0).
    expected = torch.stack(
        [
            torch.stack([commands[(t - int(d)) // steps][e] if t >= int(d) else home[e] for e, d in enumerate(delays)])
            for t in range(steps * len(commands))
        ]
    )
    torch.testing.assert_close(torch.stack(targets), expected, rtol=0.0, atol=0.0)
    assert (world.q_rad[0] - home).abs().min() > 1e-3  # every env's arm follows its commands

    # A reset forgets the command in flight: the delayed env then holds its reset pose, not the old command.
    targets.clear()
    world.reset_envs(
        torch.arange(n),
        world.q_rad.clone(),
        torch.zeros(3, n, dtype=torch.float64),
        torch.zeros(3, n, dtype=torch.float64),
    )
    start = world.q_rad[0].clone()
    q_cmd = world.q_rad.clone()
    q_cmd[0] = start + 0.3
    world.step(q_cmd, delay_steps=delays)
    torch.testing.assert_close(targets[0][-1], start[-1], rtol=0.0, atol=0.0)
    torch.testing.assert_close(targets[-1][-1], start[-1], rtol=0.0, atol=0.0)
    torch.testing.assert_close(targets[0][0], start[0] + 0.3, rtol=0.0, atol=0.0)


@pytest.mark.slow  # over 7 s on the 2-core machine: .ci/run runs it, `make test` skips it
def test_incoming_balls_follow_the_world_spec_distribution():
    """Same candidates, same verdicts: launch velocities agree with world_spec's aim (its 2 ms Euler flights
    differ by millimetres) and the accept/reject decisions agree except on borderline draws."""
    sampler = batched_launcher.IncomingBallSampler(seed=11, batch=256)
    start, velocity, bounce, accepted = sampler._candidates(256)
    checked, disagreements = 0, 0
    for i in range(60):
        st, b = start[:, i].numpy(), bounce[:, i].numpy()
        speed = float(torch.linalg.vector_norm(velocity[:, i]))
        reference = world_spec._aim(st, b, speed)
        if reference is None:
            expected = False
        else:
            contact_p, contact_v, _, clearance = world_spec.fly_to_table(st, reference)
            expected = clearance >= world_spec.INCOMING.net_clearance_m and world_spec.rebound_reaches(
                contact_p, contact_v
            )
            if expected and bool(accepted[i]):
                np.testing.assert_allclose(velocity[:, i].numpy(), reference, atol=0.05)
                # The launch lands on its drawn bounce point (a fine reference flight).
                landing, _, _, _ = world_spec.fly_to_table(st, velocity[:, i].numpy(), dt_s=1e-4)
                assert np.linalg.norm(landing[:2] - b) < 2e-3
        checked += 1
        disagreements += expected != bool(accepted[i])
    assert checked == 60 and disagreements <= 2


def test_incoming_ball_statistics_and_reproducibility():
    sampler = batched_launcher.IncomingBallSampler(speed_range_m_s=world_spec.SPEED_RANGES_M_S['high'], seed=3)
    position, velocity, bounce = sampler.sample(3000)
    speed = torch.linalg.vector_norm(velocity, dim=0)
    d = world_spec.INCOMING
    assert speed.min() >= 5.8 - 1e-4 and speed.max() <= 6.6 + 1e-4
    for axis, bounds in enumerate((d.launch_x_m, d.launch_y_m, d.launch_z_m)):
        assert position[axis].min() >= bounds[0] and position[axis].max() <= bounds[1]
    for axis, bounds in enumerate((d.bounce_x_m, d.bounce_y_m)):
        assert bounce[axis].min() >= bounds[0] and bounce[axis].max() <= bounds[1]
    # Left and right are symmetric in the distribution; the mean lateral bounce is near the middle.
    assert abs(float(bounce[1].mean())) < 0.05
    high_speeds_m_s = world_spec.SPEED_RANGES_M_S['high']
    again = batched_launcher.IncomingBallSampler(speed_range_m_s=high_speeds_m_s, seed=3).sample(3000)
    assert torch.equal(again[0], position) and torch.equal(again[1], velocity)
    other = batched_launcher.IncomingBallSampler(speed_range_m_s=world_spec.SPEED_RANGES_M_S['high'], seed=4).sample(10)
    assert not torch.equal(other[0], position[:, :10])


def test_the_velocity_drive_follows_the_reference_and_settles_where_commanded():
    """velocity_drive 1 (a stiff joint motor) follows a small step within its torque closer than the PD (0),
    a half share in between; a large step saturates every drive; every share settles on the target. A world
    built without velocity_drive steps the PD alone, whatever the parameter says."""
    world = _world(3, velocity_drive=True)
    world.params.velocity_drive = torch.tensor([0.0, 0.5, 1.0], dtype=torch.float64)
    pd_only = _world(3)
    pd_only.params.velocity_drive = world.params.velocity_drive.clone()
    home = world.q_rad.clone()
    small = home.clone()
    small[5] += 5e-4  # wrist_3: 13 N m of its 28 at the motor's acceleration
    world.step(small)
    pd_only.step(small)
    torch.testing.assert_close(pd_only.q_rad[:, 2], pd_only.q_rad[:, 0], rtol=0.0, atol=0.0)
    torch.testing.assert_close(pd_only.q_rad[:, 0], world.q_rad[:, 0], rtol=0.0, atol=1e-12)
    error = (world.q_rad[5] - small[5]).abs() / 5e-4
    assert error[2] < 0.04 and error[2] < error[1] < error[0], error
    large = home.clone()
    large[0] += 0.2
    large[5] += 0.2
    for _ in range(30):
        world.step(large)
    torch.testing.assert_close(world.q_rad, large, atol=1e-3, rtol=0.0)
