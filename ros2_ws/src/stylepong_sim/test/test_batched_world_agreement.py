"""The batched torch world agrees with the MuJoCo cell (stylepong_sim.cells.cell) on the same inputs.

* Ball: the same launched ball touches the table within 6 mm of where it touches it in the cell, and
  after that first bounce it lands on the floor within 7 mm of the cell's landing (measured: at most
  5.6 mm and 6.1 mm).
* Arm: the same joint-position step command gives joint trajectories within 2 % RMS of the cell's
  (RMS of the difference over 1 s, relative to the RMS of the cell's motion from its start; measured:
  at most 1.8 %).
These are the figures stylepong_sim.batched.batched_world's docstring states; both simulators are deterministic,
so the margins hold from run to run.
The cell steps at 1 ms and is sampled at the batched world's policy instants (linear interpolation
between its 1 ms samples); the batched world runs at its defaults (120 Hz physics, 60 Hz policy).
"""

import numpy as np
import pytest
import torch

from stylepong_sim import referee, world_spec
from stylepong_sim.batched import batched_world
from stylepong_sim.cells.cell import Cell

HOME = np.array(world_spec.HOME_JOINT_POSITIONS_RAD)
POLICY_DT_S = 1.0 / world_spec.POLICY_RATE_HZ
TABLE_CONTACT_TOLERANCE_M = 0.006
LANDING_TOLERANCE_M = 0.007
JOINT_RMS_TOLERANCE = 0.02  # of the RMS of the cell's motion


def _cell_ball_run(position, velocity, duration_s):
    """Launch a ball in a cell with the robot at home; returns (times, positions every 1 ms, events)."""
    cell = Cell()
    cell.launch_ball(position, velocity)
    times, positions, events = [0.0], [np.asarray(position, float)], []
    for _ in range(int(round(duration_s / cell.dt_s))):
        cell.step()
        events += cell.pop_events()
        if not cell.ball_in_play:
            break
        times.append(cell.time_s)
        positions.append(cell.ball_position_m)
    return np.array(times), np.array(positions), events


def _world_ball_run(positions, velocities, duration_s):
    """The same balls in one batched world (robot at home); returns ball positions [steps+1, 3, N]
    and the first table contact of each ball [3, N]."""
    n = len(positions)
    world = batched_world.BatchedWorld(n, dtype=torch.float64)
    world.reset_envs(
        torch.arange(n), world.q_rad.clone(), torch.tensor(np.array(positions)).T, torch.tensor(np.array(velocities)).T
    )
    command = world.q_rad.clone()
    trajectory = [world.ball_pos_m.clone()]
    first_contact = torch.full((3, n), float('nan'), dtype=torch.float64)
    for _ in range(int(round(duration_s / POLICY_DT_S))):
        world.step(command)
        touched = torch.isnan(first_contact[0]) & (world.table_contact_pos_m.abs().sum(0) > 0)
        first_contact[:, touched] = world.table_contact_pos_m[:, touched]
        trajectory.append(world.ball_pos_m.clone())
    return torch.stack(trajectory).numpy(), first_contact.numpy()


def _floor_crossing(times, positions):
    """Where the ball's bottom first reaches the floor (linear interpolation between samples)."""
    z = positions[:, 2] - world_spec.BALL_RADIUS_M
    below = np.nonzero(z <= 0.0)[0]
    assert below.size, 'the ball never reached the floor'
    k = below[0]
    f = z[k - 1] / (z[k - 1] - z[k])
    return positions[k - 1] + f * (positions[k] - positions[k - 1])


def test_incoming_balls_bounce_where_the_cell_bounces_them():
    launches = [world_spec.incoming_ball_for_seed(seed) for seed in range(6)]
    _, first_contact = _world_ball_run([b.position_m for b in launches], [b.velocity_m_s for b in launches], 1.0)
    for i, launch in enumerate(launches):
        _, _, events = _cell_ball_run(launch.position_m, launch.velocity_m_s, 1.0)
        bounces = [e for e in events if e.type == referee.BOUNCE_OWN_SIDE]
        assert bounces, f'ball {i} never bounced in the cell'
        cell_bounce = np.array(bounces[0].position_m)
        assert np.linalg.norm(first_contact[:2, i] - cell_bounce[:2]) < TABLE_CONTACT_TOLERANCE_M, (
            first_contact[:, i],
            cell_bounce,
        )
        # The distribution aims at its drawn bounce point; both simulators land there (drag included).
        assert np.linalg.norm(cell_bounce[:2] - launch.bounce_point_m) < 0.02


# Balls struck from in front of the robot over the net: they bounce on the far half, then fly off the
# table's end (or its side) onto the floor: the landing after the first bounce.
RETURNS = [
    ((-1.0, 0.0, 1.05), (5.0, 0.0, 1.0)),
    ((-0.9, 0.3, 1.0), (4.0, -0.6, 1.6)),
    ((-1.0, 0.3, 1.1), (4.5, -0.5, 1.2)),
    ((-1.1, -0.3, 1.0), (6.0, 0.5, 1.0)),
    ((-0.9, 0.0, 1.2), (4.0, 0.0, 0.5)),
]


def test_landing_after_the_first_bounce_agrees_with_the_cell():
    trajectories, first_contact = _world_ball_run([p for p, _ in RETURNS], [v for _, v in RETURNS], 2.0)
    world_times = POLICY_DT_S * np.arange(trajectories.shape[0])
    for i, (position, velocity) in enumerate(RETURNS):
        times, positions, events = _cell_ball_run(position, velocity, 2.0)
        bounces = [e for e in events if e.type in (referee.BOUNCE_OPPONENT_SIDE, referee.BOUNCE_OWN_SIDE)]
        assert bounces and bounces[0].type == referee.BOUNCE_OPPONENT_SIDE, [str(e) for e in events]
        assert np.linalg.norm(first_contact[:2, i] - np.array(bounces[0].position_m)[:2]) < TABLE_CONTACT_TOLERANCE_M
        cell_landing = _floor_crossing(times, positions)
        world_landing = _floor_crossing(world_times, trajectories[:, :, i])
        assert np.linalg.norm(world_landing[:2] - cell_landing[:2]) < LANDING_TOLERANCE_M, (world_landing, cell_landing)


def test_a_ball_off_the_still_paddle_lands_where_it_lands_in_the_cell():
    cell = Cell()
    centre, rotation = cell.paddle_pose()
    normal = rotation[:, 2]
    # At the blade from 0.8 m in front of its face, rising: it comes back and bounces on the table.
    start = centre + 0.8 * normal + np.array([0.0, 0.0, -0.05])
    velocity = -5.0 * normal + np.array([0.0, 0.0, 1.2])
    cell.launch_ball(start, velocity)
    events = []
    for _ in range(1500):
        cell.step()
        events += cell.pop_events()
        if any(e.type == referee.RALLY_END for e in events):
            break
    kinds = [e.type for e in events]
    assert referee.PADDLE_HIT in kinds, [str(e) for e in events]
    cell_table = [e for e in events if e.type in (referee.BOUNCE_OWN_SIDE, referee.BOUNCE_OPPONENT_SIDE)][0]
    world = batched_world.BatchedWorld(1, dtype=torch.float64)
    world.reset_envs(
        torch.arange(1), world.q_rad.clone(), torch.tensor(start)[:, None], torch.tensor(velocity)[:, None]
    )
    hit = False
    for _ in range(90):
        events_world = world.step(world.q_rad.clone())
        hit |= bool(events_world.paddle_hit[0])
        if bool(events_world.decided[0]):
            break
    assert hit and world.hit[0]
    assert (
        np.linalg.norm(world.table_contact_pos_m[:2, 0].numpy() - np.array(cell_table.position_m)[:2])
        < TABLE_CONTACT_TOLERANCE_M
    )


STEP_COMMANDS = [
    (0.4, -0.3, 0.5, 0.6, -0.5, 0.8),  # a large step: velocity and effort limits active
    (-0.8, 0.5, -0.6, -0.9, 0.9, -1.2),  # larger, the other way
    (0.15, 0.15, -0.15, 0.2, 0.2, -0.2),  # a small step: mostly the PD's own response
]


@pytest.mark.parametrize('step', STEP_COMMANDS)
def test_joint_step_response_agrees_with_the_cell(step):
    duration_s = 1.0
    target = HOME + np.array(step)
    cell = Cell()
    cell.set_joint_targets(target)
    cell_times, cell_q = [0.0], [cell.joint_positions_rad]
    for _ in range(int(round(duration_s / cell.dt_s))):
        cell.step()
        cell_times.append(cell.time_s)
        cell_q.append(cell.joint_positions_rad)
    cell_times, cell_q = np.array(cell_times), np.array(cell_q)

    world = batched_world.BatchedWorld(1, dtype=torch.float64)
    command = torch.tensor(target)[:, None]
    world_q = []
    for _ in range(int(round(duration_s / POLICY_DT_S))):
        world.step(command)
        world_q.append(world.q_rad[:, 0].numpy().copy())
    world_q = np.array(world_q)
    times = POLICY_DT_S * np.arange(1, len(world_q) + 1)
    reference = np.stack([np.interp(times, cell_times, cell_q[:, j]) for j in range(6)], axis=1)
    rms_error = np.sqrt(((world_q - reference) ** 2).mean(axis=0))
    rms_motion = np.sqrt(((reference - HOME) ** 2).mean(axis=0))
    assert (rms_error <= JOINT_RMS_TOLERANCE * rms_motion).all(), (rms_error / rms_motion).round(4)
    # And both arrive: the command is reached within a few milliradians after a second.
    np.testing.assert_allclose(world_q[-1], target, atol=5e-3)
