"""`ros2 run stylepong_sim cell_calibration`: how far the three simulators disagree on the ball, and the actuator
models on a step, in numbers (results/calibration.md and .json).

    cell_calibration [--out results] [--first-seed 1000] [--balls 10]

* Ball: the evaluation seeds' incoming balls (world_spec.incoming_ball_for_seed), the arm at home, in the batched
  training world, the MuJoCo cell (ur5_sim) and the PyBullet cell (ur5_bullet): the first bounce point, and
  where the rebound crosses the plane x = CROSSING_X_M (y, z, speed). Differences against the MuJoCo cell.
* Paddle: scripted strokes (a step command to a joint target from home, world_spec's ideal servo in every
  simulator) meet a ball thrown at the blade's centre along its face normal; the return's speed, elevation
  and heading at the first 60 Hz sample after the hit, and its first table contact (landing point).
* Actuators: a step of STEP_RAD on shoulder_pan and wrist_3 in both cells under each actuator model (ideal,
  ur_servoj at several settings): delay to 10 %, rise 10-90 %, settling to 2 %, overshoot; and the lag
  behind a 1 rad/s ramp commanded at the policy's 60 Hz (what the actor meets while it swings).
Every simulator samples the ball on the same 60 Hz grid (the batched world's policy steps) so that differences
come from the physics, not from when they were looked at.
"""

from __future__ import annotations

import argparse
import json
import math
import pathlib
import sys
from dataclasses import dataclass, field

import numpy as np

from stylepong_sim import referee, world_spec
from stylepong_sim.cells import ur_servoj

CROSSING_X_M = -1.2  # before the paddle at home (x = -1.47): the arm does not touch the rebound
POLICY_DT_S = 1.0 / world_spec.POLICY_RATE_HZ
HOME = np.array(world_spec.HOME_JOINT_POSITIONS_RAD)
# Scripted strokes: joint offsets from home, commanded as one step at t = 0; the ball meets the blade at HIT_TIME_S.
STROKES = {
    'push (lift + 0.3, elbow - 0.3)': np.array([0.0, 0.3, -0.3, 0.0, 0.0, 0.0]),
    'sweep (pan + 0.6)': np.array([0.6, 0.0, 0.0, 0.0, 0.0, 0.0]),
    'flick (wrist 1 - 0.6)': np.array([0.0, 0.0, 0.0, -0.6, 0.0, 0.0]),
}
HIT_TIME_S = 0.15
INCOMING_SPEED_M_S = 5.0
STEP_RAD = 0.2
STEP_JOINTS = (0, 5)  # shoulder_pan (150 N m), wrist_3 (28 N m)
ACTUATOR_SETTINGS = {
    'ideal': (ur_servoj.IDEAL, ur_servoj.ServojSettings()),
    'ur_servoj 125 Hz, 0.03 s, 2000': (ur_servoj.UR_SERVOJ, ur_servoj.ServojSettings(125.0, 0.03, 2000.0)),
    'ur_servoj 500 Hz, 0.03 s, 2000': (ur_servoj.UR_SERVOJ, ur_servoj.ServojSettings(500.0, 0.03, 2000.0)),
    'ur_servoj 125 Hz, 0.1 s, 300': (ur_servoj.UR_SERVOJ, ur_servoj.ServojSettings(125.0, 0.1, 300.0)),
}
SIMULATORS = ('batched', 'mujoco', 'pybullet')


@dataclass
class BallTrace:
    """A ball on the 60 Hz grid and its events (times from the launch)."""

    times_s: list[float] = field(default_factory=list)
    positions_m: list[np.ndarray] = field(default_factory=list)
    velocities_m_s: list[np.ndarray] = field(default_factory=list)
    first_bounce_m: np.ndarray | None = None
    hit_time_s: float | None = None
    landing_m: np.ndarray | None = None  # first table contact after the hit


def make_cell(
    engine: str, actuator: str = ur_servoj.IDEAL, servoj: ur_servoj.ServojSettings = ur_servoj.ServojSettings()
):
    """A fresh cell of `engine` ('mujoco' or 'pybullet')."""
    if engine == 'pybullet':
        from stylepong_sim.cells.bullet_cell import BulletCell

        return BulletCell(actuator=actuator, servoj=servoj)
    from stylepong_sim.cells.cell import Cell

    return Cell(actuator=actuator, servoj=servoj)


def cell_ball_trace(engine: str, position_m, velocity_m_s, q_target=None, duration_s: float = 1.2) -> BallTrace:
    """Launch the ball in a fresh cell (arm at home, commanded to q_target from the launch on) and trace it."""
    cell = make_cell(engine)
    if q_target is not None:
        cell.set_joint_targets(q_target)
    cell.launch_ball(position_m, velocity_m_s)
    trace = BallTrace()
    steps_per_sample = round(POLICY_DT_S / cell.dt_s)
    for k in range(1, round(duration_s / POLICY_DT_S) + 1):
        for _ in range(steps_per_sample):
            cell.step(1)
            for event in cell.pop_events():
                _note_event(trace, event.type, event.time_s, np.array(event.position_m))
            if not cell.ball_in_play:
                break
        if not cell.ball_in_play:
            break
        trace.times_s.append(k * POLICY_DT_S)
        trace.positions_m.append(cell.ball_position_m)
        trace.velocities_m_s.append(cell.ball_velocity_m_s)
    close = getattr(cell, 'close', None)
    if close is not None:
        close()
    return trace


def _note_event(trace: BallTrace, event_type: int, time_s: float, position_m: np.ndarray) -> None:
    bounce = event_type in (referee.BOUNCE_OWN_SIDE, referee.BOUNCE_OPPONENT_SIDE)
    if bounce and trace.first_bounce_m is None and trace.hit_time_s is None:
        trace.first_bounce_m = position_m
    elif event_type == referee.PADDLE_HIT and trace.hit_time_s is None:
        trace.hit_time_s = time_s
    elif bounce and trace.hit_time_s is not None and trace.landing_m is None:
        trace.landing_m = position_m


def batched_ball_traces(
    positions_m: np.ndarray, velocities_m_s: np.ndarray, q_target=None, duration_s: float = 1.2
) -> list[BallTrace]:
    """The same balls [N, 3] in one batched world (float64, its default rates), arm commanded to q_target."""
    import torch

    from stylepong_sim.batched import batched_world

    n = len(positions_m)
    world = batched_world.BatchedWorld(n, dtype=torch.float64)
    world.reset_envs(torch.arange(n), world.q_rad.clone(), torch.tensor(positions_m).T, torch.tensor(velocities_m_s).T)
    command = world.q_rad.clone() if q_target is None else torch.tensor(q_target)[:, None].repeat(1, n)
    traces = [BallTrace() for _ in range(n)]
    contact_before = world.table_contact_pos_m.clone()
    for k in range(1, round(duration_s / POLICY_DT_S) + 1):
        events = world.step(command)
        moved = (world.table_contact_pos_m - contact_before).abs().sum(0) > 0
        for i, trace in enumerate(traces):
            if events.paddle_hit[i] and trace.hit_time_s is None:
                trace.hit_time_s = k * POLICY_DT_S
            if moved[i]:
                _note_event(trace, referee.BOUNCE_OWN_SIDE, k * POLICY_DT_S, world.table_contact_pos_m[:, i].numpy())
            trace.times_s.append(k * POLICY_DT_S)
            trace.positions_m.append(world.ball_pos_m[:, i].numpy().copy())
            trace.velocities_m_s.append(world.ball_vel_m_s[:, i].numpy().copy())
        contact_before = world.table_contact_pos_m.clone()
    return traces


def crossing(trace: BallTrace, x_m: float = CROSSING_X_M) -> tuple[float, float, float] | None:
    """(y, z, speed) where the ball first crosses the plane x = x_m going towards the robot (linear
    interpolation between 60 Hz samples); None if it does not."""
    for (p0, v0), (p1, v1) in zip(
        zip(trace.positions_m, trace.velocities_m_s), zip(trace.positions_m[1:], trace.velocities_m_s[1:])
    ):
        if p0[0] > x_m >= p1[0]:
            f = (p0[0] - x_m) / (p0[0] - p1[0])
            p = p0 + f * (p1 - p0)
            v = v0 + f * (v1 - v0)
            return float(p[1]), float(p[2]), float(np.linalg.norm(v))
    return None


def return_after_hit(trace: BallTrace) -> dict | None:
    """The return: speed, elevation and heading (deg) at the first 60 Hz sample after the hit, landing point."""
    if trace.hit_time_s is None:
        return None
    k = next((i for i, t in enumerate(trace.times_s) if t > trace.hit_time_s + 1e-9), None)
    if k is None:
        return None
    v = trace.velocities_m_s[k]
    horizontal = math.hypot(v[0], v[1])
    return {
        'speed_m_s': float(np.linalg.norm(v)),
        'elevation_deg': math.degrees(math.atan2(v[2], horizontal)),
        'heading_deg': math.degrees(math.atan2(v[1], v[0])),
        'landing_xy_m': None if trace.landing_m is None else [float(trace.landing_m[0]), float(trace.landing_m[1])],
    }


def aimed_throw(
    target_m: np.ndarray, direction: np.ndarray, speed_m_s: float, flight_s: float
) -> tuple[np.ndarray, np.ndarray]:
    """A launch (position, velocity) whose flight with gravity and drag reaches target_m after flight_s,
    arriving roughly along -direction at about speed_m_s (secant corrections of the launch velocity)."""
    start = target_m + direction * speed_m_s * flight_s
    velocity = -direction * speed_m_s + np.array([0.0, 0.0, 0.5 * world_spec.GRAVITY_M_S2 * flight_s])
    for _ in range(6):
        end = _fly(start, velocity, flight_s)
        velocity = velocity + (target_m - end) / flight_s
    return start, velocity


def _fly(position_m: np.ndarray, velocity_m_s: np.ndarray, duration_s: float, dt_s: float = 1e-4) -> np.ndarray:
    p, v = position_m.copy(), velocity_m_s.copy()
    gravity = np.array([0.0, 0.0, -world_spec.GRAVITY_M_S2])
    for _ in range(round(duration_s / dt_s)):
        v = v + (gravity + world_spec.drag_acceleration(v)) * dt_s
        p = p + v * dt_s
    return p


def blade_at(q_target: np.ndarray, time_s: float, engine: str = 'mujoco') -> tuple[np.ndarray, np.ndarray]:
    """Where the blade's centre is and where its face points, time_s into the stroke (ideal servo)."""
    cell = make_cell(engine)
    cell.set_joint_targets(q_target)
    cell.step_for(time_s)
    centre, rotation = cell.paddle_pose()
    return centre, rotation[:, 2]


def step_response(engine: str, actuator: str, servoj: ur_servoj.ServojSettings) -> dict:
    """Delay to 10 %, rise 10-90 %, settling to 2 % (ms) and overshoot (%) of a STEP_RAD step on STEP_JOINTS,
    and the lag (ms) behind a 1 rad/s ramp commanded at 60 Hz on shoulder_pan."""
    cell = make_cell(engine, actuator, servoj)
    target = HOME.copy()
    target[list(STEP_JOINTS)] += STEP_RAD
    cell.set_joint_targets(target)
    times, positions = [], []
    for _ in range(800):
        cell.step(1)
        times.append(cell.time_s)
        positions.append(cell.joint_positions_rad)
    times_s, q = np.array(times), np.array(positions)
    result = {}
    for joint in STEP_JOINTS:
        fraction = (q[:, joint] - HOME[joint]) / STEP_RAD
        t10 = times_s[np.argmax(fraction >= 0.1)]
        t90 = times_s[np.argmax(fraction >= 0.9)]
        outside = np.flatnonzero(np.abs(fraction - 1.0) > 0.02)
        settle = times_s[outside[-1] + 1] if outside.size and outside[-1] + 1 < len(times_s) else float('nan')
        name = 'shoulder_pan' if joint == 0 else 'wrist_3'
        result[name] = {
            'delay_10_ms': 1e3 * t10,
            'rise_10_90_ms': 1e3 * (t90 - t10),
            'settle_2pct_ms': 1e3 * settle,
            'overshoot_pct': 100.0 * max(0.0, fraction.max() - 1.0),
        }
    cell.reset()
    start_s = cell.time_s
    lags = []
    for _ in range(900):
        t = cell.time_s - start_s
        command = HOME.copy()
        command[0] += 1.0 * math.floor(t / POLICY_DT_S) * POLICY_DT_S  # held commands, as the player sends them
        cell.set_joint_targets(command)
        cell.step(1)
        if t > 0.5:
            lags.append(cell.time_s - start_s - (cell.joint_positions_rad[0] - HOME[0]))
    result['ramp_lag_ms'] = 1e3 * float(np.mean(lags))
    close = getattr(cell, 'close', None)
    if close is not None:
        close()
    return result


def ball_part(first_seed: int, balls: int) -> list[dict]:
    """The seeds' balls in the three simulators, arm at home: first bounce and crossing, per seed."""
    launches = [world_spec.incoming_ball_for_seed(seed) for seed in range(first_seed, first_seed + balls)]
    positions = np.array([b.position_m for b in launches])
    velocities = np.array([b.velocity_m_s for b in launches])
    traces = {
        'batched': batched_ball_traces(positions, velocities),
        'mujoco': [cell_ball_trace('mujoco', p, v) for p, v in zip(positions, velocities)],
        'pybullet': [cell_ball_trace('pybullet', p, v) for p, v in zip(positions, velocities)],
    }
    rows = []
    for i, seed in enumerate(range(first_seed, first_seed + balls)):
        row = {'seed': seed}
        for name in SIMULATORS:
            trace = traces[name][i]
            bounce = trace.first_bounce_m
            row[name] = {
                'bounce_xy_m': None if bounce is None else [float(bounce[0]), float(bounce[1])],
                'crossing_y_z_speed': crossing(trace),
            }
        rows.append(row)
    return rows


def stroke_part() -> list[dict]:
    """Each scripted stroke meets a thrown ball in the three simulators: the returns, and the Bullet blade's offset."""
    rows = []
    for name, offset in STROKES.items():
        q_target = HOME + offset
        centre, normal = blade_at(q_target, HIT_TIME_S)
        start, velocity = aimed_throw(
            centre + normal * world_spec.BALL_RADIUS_M, normal, INCOMING_SPEED_M_S, HIT_TIME_S
        )
        row = {
            'stroke': name,
            'joint_offset_rad': offset.tolist(),
            'launch_m': start.tolist(),
            'launch_velocity_m_s': velocity.tolist(),
            'batched': return_after_hit(batched_ball_traces(start[None], velocity[None], q_target)[0]),
        }
        for engine in ('mujoco', 'pybullet'):
            row[engine] = return_after_hit(cell_ball_trace(engine, start, velocity, q_target))
        # Where the PyBullet arm has the blade when the MuJoCo arm's blade meets the ball (same command).
        bullet_centre, bullet_normal = blade_at(q_target, HIT_TIME_S, 'pybullet')
        row['pybullet_blade_offset_mm'] = 1e3 * float(np.linalg.norm(bullet_centre - centre))
        row['pybullet_blade_tilt_deg'] = math.degrees(math.acos(min(1.0, float(np.dot(bullet_normal, normal)))))
        rows.append(row)
    return rows


def actuator_part() -> dict:
    """Step and ramp responses of every actuator setting in both cells."""
    return {
        label: {engine: step_response(engine, actuator, settings) for engine in ('mujoco', 'pybullet')}
        for label, (actuator, settings) in ACTUATOR_SETTINGS.items()
    }


def _distance_mm(a, b) -> float:
    if a is None or b is None:
        return float('nan')
    return 1e3 * float(np.linalg.norm(np.asarray(a) - np.asarray(b)))


def summarise_ball(rows: list[dict]) -> dict:
    """Per simulator against the MuJoCo cell: bounce point and crossing differences (mm, m/s), max and mean."""
    summary = {}
    for name in ('batched', 'pybullet'):
        bounce = [_distance_mm(r[name]['bounce_xy_m'], r['mujoco']['bounce_xy_m']) for r in rows]
        ours = [r[name]['crossing_y_z_speed'] for r in rows]
        ref = [r['mujoco']['crossing_y_z_speed'] for r in rows]
        both = [(a, b) for a, b in zip(ours, ref) if a is not None and b is not None]
        summary[name] = {
            'bounce_mm_max': float(np.nanmax(bounce)),
            'bounce_mm_mean': float(np.nanmean(bounce)),
            'crossing_y_mm_max': max((1e3 * abs(a[0] - b[0]) for a, b in both), default=float('nan')),
            'crossing_z_mm_max': max((1e3 * abs(a[1] - b[1]) for a, b in both), default=float('nan')),
            'crossing_z_mm_mean': float(np.mean([1e3 * (a[1] - b[1]) for a, b in both])) if both else float('nan'),
            'crossing_speed_m_s_max': max((abs(a[2] - b[2]) for a, b in both), default=float('nan')),
            'crossings_compared': len(both),
            'balls': len(rows),
        }
    return summary


def _fmt(value, digits: int = 1) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return '-'
    return f'{value:.{digits}f}'


def markdown(result: dict) -> list[str]:
    """calibration.md's lines."""
    lines = [
        '# Calibration: the three simulators and the actuator models side by side',
        '',
        f'Written by `{result["command"]}` ({result["wall_time_s"]:.0f} s). Reference: the MuJoCo cell '
        '(`ur5_sim`); the batched world is what training runs; the PyBullet cell (`ur5_bullet`) shares no contact '
        'code with either. Ideal servo in every simulator unless the actuator table says otherwise.',
        '',
        f'## Ball: first bounce and rebound (seeds {result["seeds"][0]}-{result["seeds"][-1]}, arm at home)',
        '',
        f'Differences against the MuJoCo cell; the crossing is where the rebound passes x = {CROSSING_X_M} m.',
        '',
        '| simulator | bounce point, max / mean (mm) | crossing y, max (mm) | crossing z, max / mean signed (mm) '
        '| crossing speed, max (m/s) |',
        '|---|---|---|---|---|',
    ]
    for name, s in result['ball_summary'].items():
        lines.append(
            f'| {name} | {_fmt(s["bounce_mm_max"])} / {_fmt(s["bounce_mm_mean"])} | '
            f'{_fmt(s["crossing_y_mm_max"])} | '
            f'{_fmt(s["crossing_z_mm_max"])} / {_fmt(s["crossing_z_mm_mean"])} | '
            f'{_fmt(s["crossing_speed_m_s_max"], 3)} |'
        )
    lines += [
        '',
        '## Paddle: the return of scripted strokes',
        '',
        f"A step command from home to the stroke's joint offsets at t = 0; a ball thrown at the blade's centre "
        f'along its face normal at {INCOMING_SPEED_M_S} m/s meets it at {HIT_TIME_S} s (aimed with the MuJoCo '
        "arm's blade). The return at the first 60 Hz sample after the hit, and its first table contact. The "
        "batched world's arm is held to the MuJoCo arm by its agreement test; the PyBullet arm (Bullet's joint "
        'motors, gravity within the torque limits) has its blade elsewhere at the hit time:',
        '',
    ]
    lines += [
        f'- {row["stroke"]}: PyBullet blade {row["pybullet_blade_offset_mm"]:.0f} mm from the MuJoCo blade, '
        f'its face turned {row["pybullet_blade_tilt_deg"]:.1f} deg'
        for row in result['strokes']
    ]
    lines += [
        '',
        '| stroke | simulator | speed (m/s) | elevation (deg) | heading (deg) | landing x, y (m) |',
        '|---|---|---|---|---|---|',
    ]
    for row in result['strokes']:
        for name in SIMULATORS:
            r = row[name]
            if r is None:
                lines.append(f'| {row["stroke"]} | {name} | no hit | | | |')
                continue
            landing = '-' if r['landing_xy_m'] is None else f'{r["landing_xy_m"][0]:.3f}, {r["landing_xy_m"][1]:.3f}'
            lines.append(
                f'| {row["stroke"]} | {name} | {r["speed_m_s"]:.2f} | {r["elevation_deg"]:.1f} | '
                f'{r["heading_deg"]:.1f} | {landing} |'
            )
    lines += [
        '',
        '## Actuators: step and ramp',
        '',
        f'A {STEP_RAD} rad step on shoulder_pan and wrist_3 together; the ramp is 1 rad/s on shoulder_pan '
        'commanded at 60 Hz (held between commands), its lag averaged after 0.5 s. ur_servoj settings: rate, '
        'look-ahead, gain '
        '(`stylepong_sim/cells/ur_servoj.py`).',
        '',
        '| actuator | cell | pan delay 10 % (ms) | pan rise 10-90 % (ms) | pan settle 2 % (ms) '
        '| pan overshoot (%) '
        '| wrist_3 delay / rise / settle (ms) | ramp lag (ms) |',
        '|---|---|---|---|---|---|---|---|',
    ]
    for label, cells in result['actuators'].items():
        for engine, r in cells.items():
            pan, wrist = r['shoulder_pan'], r['wrist_3']
            lines.append(
                f'| {label} | {engine} | {pan["delay_10_ms"]:.0f} | {pan["rise_10_90_ms"]:.0f} | '
                f'{_fmt(pan["settle_2pct_ms"], 0)} | {pan["overshoot_pct"]:.1f} | '
                f'{wrist["delay_10_ms"]:.0f} / {wrist["rise_10_90_ms"]:.0f} / '
                f'{_fmt(wrist["settle_2pct_ms"], 0)} | '
                f'{r["ramp_lag_ms"]:.1f} |'
            )
    return lines


def run(argv: list[str] | None = None) -> int:
    """The command: all three parts, written to --out; its exit code."""
    import time

    parser = argparse.ArgumentParser(prog='cell_calibration', description=__doc__.split('\n\n')[0])
    parser.add_argument(
        '--out',
        type=pathlib.Path,
        default=pathlib.Path('results'),
        help='folder for calibration.md and calibration.json',
    )
    parser.add_argument('--first-seed', type=int, default=world_spec.FIRST_EVALUATION_SEED)
    parser.add_argument('--balls', type=int, default=10)
    args = parser.parse_args(argv)
    if args.balls < 1:
        print('cell_calibration: --balls must be at least 1', file=sys.stderr)
        return 2
    started = time.monotonic()
    rows = ball_part(args.first_seed, args.balls)
    arguments = ' '.join(argv if argv is not None else sys.argv[1:])
    result = {
        'command': f'ros2 run stylepong_sim cell_calibration {arguments}',
        'seeds': [r['seed'] for r in rows],
        'ball': rows,
        'ball_summary': summarise_ball(rows),
        'strokes': stroke_part(),
        'actuators': actuator_part(),
    }
    result['command'] = result['command'].strip()
    result['wall_time_s'] = time.monotonic() - started
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / 'calibration.json').write_text(json.dumps(result, indent=2) + '\n')
    text = '\n'.join(markdown(result)) + '\n'
    (args.out / 'calibration.md').write_text(text)
    print(text)
    return 0


def main() -> None:
    """Entry point of cell_calibration."""
    sys.exit(run())
