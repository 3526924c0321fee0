"""The shipped actor through the player's logic on a cell, without ROS: which part of a cell decides a sim2sim figure.

    ros2 run stylepong_policy offline_rallies --engine pybullet --actuator ideal --joint-drive motor|pd
        --first-seed 1000 --balls 10 [--actor PATH.pt|PATH.onnx] [--no-stream] [--no-predict] [--realistic-sensing]

The player (stylepong_player.player_core.Player, the node's logic: the limiter, phase-locked steps) drives a
cell stepped here at 1 ms: the camera at 125 Hz, joint states at 500 Hz, no ROS timing; perfect sensing, or
with --realistic-sensing the ball camera of config/realistic_sensing.yaml (latency, noise, lost frames). Balls
and goals are rally_eval's for the seed. Prints each ball's verdict (and, on the PyBullet cell, which robot link
touched the ball or the table), then the success count. Swapping one part of the cell at a time (engine, joint
drive, actuator) tells which one a through-ROS figure depends on. Needs `source ros2_ws/install/setup.bash`.
"""

from __future__ import annotations

import argparse
import pathlib
import sys

import numpy as np
import yaml

from stylepong_description import robot_model
from stylepong_player import player_core
from stylepong_policy import paths
from stylepong_sim import referee, world_spec
from stylepong_sim.cells import sensing, ur_servoj
from stylepong_sim.nodes.rally_eval import balls_for_seed, goals_for_seed

ACTOR = paths.MODELS / 'amp_actor.pt'
REALISTIC_SENSING = paths.REPOSITORY / 'ros2_ws/src/stylepong_sim/config/realistic_sensing.yaml'
CAMERA_PERIOD_STEPS = 8  # 125 Hz
JOINT_STATE_PERIOD_STEPS = 2  # 500 Hz
SETTLE_STEPS = 300


def make_cell(engine: str, actuator: str, joint_drive: str):
    """The cell to play in (ur_servoj at the CB3's 125 Hz, look-ahead 0.03 s, gain 2000)."""
    servoj = ur_servoj.ServojSettings(125.0, 0.03, 2000.0)
    if engine == 'pybullet':
        from stylepong_sim.cells.bullet_cell import BulletCell

        return BulletCell(actuator=actuator, servoj=servoj, joint_drive=joint_drive)
    from stylepong_sim.cells.cell import Cell

    return Cell(actuator=actuator, servoj=servoj)


def camera_config(realistic: bool) -> sensing.SensingConfig:
    """A perfect ball camera, or the one sim2sim runs with (its noise, latency, lost frames and seed)."""
    if not realistic:
        return sensing.SensingConfig()
    params = yaml.safe_load(REALISTIC_SENSING.read_text())['ur5_sim']['ros__parameters']
    return sensing.SensingConfig(
        seed=params['sensing_seed'],
        **{
            name: params[name]
            for name in (
                'ball_position_noise_std_m',
                'ball_velocity_noise_std_m_s',
                'ball_latency_s',
                'ball_dropout_probability',
            )
        },
    )


def touching_links(cell, event_type: int) -> list[str]:
    """The PyBullet cell's robot links in contact with the ball (or with the table and net)."""
    p = getattr(cell, '_p', None)
    if p is None:
        return []
    if event_type == referee.ROBOT_CONTACT:
        links = [c[4] for c in p.getContactPoints(bodyA=cell._ball_body, bodyB=cell._robot)]
    else:
        links = [
            c[3] for obstacle in (cell._table, cell._net) for c in p.getContactPoints(bodyA=cell._robot, bodyB=obstacle)
        ]
    return sorted({p.getJointInfo(cell._robot, link)[12].decode() for link in links})


def play(cell, player, camera, position, velocity, goal) -> tuple[str, list[str]]:
    """One rally: the arm at home and ready, the ball launched, the player stepped as the node steps it."""
    names = list(robot_model.JOINT_NAMES)

    def drive(now_s: float, step: int, ball: bool) -> None:
        due = False
        if step % JOINT_STATE_PERIOD_STEPS == 0:
            player.on_joint_state(names, cell.joint_positions_rad, cell.joint_velocities_rad_s, now_s)
            if not player.fallback_step_due(now_s):
                point = player.stream_command(now_s)
                if point is not None:
                    cell.set_joint_targets(point)
        if ball and step % CAMERA_PERIOD_STEPS == 0 and cell.ball_in_play:
            camera.observe(now_s, cell.ball_position_m, cell.ball_velocity_m_s)
        for seen in camera.delivered(now_s):
            if player.on_ball('world', seen.stamp_s, seen.position_m, seen.velocity_m_s, now_s) is None:
                due = player.ball_step_due(now_s)
        if due or player.timer_step_due(now_s) or player.fallback_step_due(now_s):
            result = player.step(now_s)
            if result.command is not None:
                cell.set_joint_targets(result.command)

    cell.reset()
    cell.pop_events()
    player.on_goal('world', float(goal[0]), float(goal[1]))
    for step in range(SETTLE_STEPS):
        cell.step(1)
        drive(cell.time_s, step, ball=False)
    cell.launch_ball(position, velocity)
    start_s, links = cell.time_s, []
    for step in range(1, 3300):
        cell.step(1)
        drive(cell.time_s, step, ball=True)
        for event in cell.pop_events():
            if event.type in (referee.ROBOT_CONTACT, referee.TABLE_CONTACT_BY_ROBOT):
                links = touching_links(cell, event.type)
            if event.type == referee.RALLY_END:
                return event.reason, links
        if cell.time_s - start_s > 3.2:
            break
    return 'no_verdict', links


def main(argv: list[str] | None = None) -> int:
    """Play the balls and print the verdicts; the exit code."""
    parser = argparse.ArgumentParser(prog='offline_rallies', description=__doc__.split('\n\n')[0])
    parser.add_argument('--engine', choices=('mujoco', 'pybullet'), default='pybullet')
    parser.add_argument('--actuator', choices=ur_servoj.ACTUATORS, default=ur_servoj.IDEAL)
    parser.add_argument('--joint-drive', choices=('motor', 'pd'), default='motor', help='PyBullet cell only')
    parser.add_argument('--first-seed', type=int, default=world_spec.FIRST_EVALUATION_SEED)
    parser.add_argument('--seeds', type=int, default=1)
    parser.add_argument('--balls', type=int, default=10)
    parser.add_argument('--no-stream', action='store_true', help="the player's stream_commands false")
    parser.add_argument('--no-predict', action='store_true', help="the player's predict_ball false")
    parser.add_argument('--actor', type=pathlib.Path, default=ACTOR, help='default: the shipped style actor')
    parser.add_argument(
        '--realistic-sensing', action='store_true', help="the ball camera of sim2sim's realistic_sensing.yaml"
    )
    args = parser.parse_args(argv)
    actor = player_core.load_actor(args.actor, 'onnx')
    cell = make_cell(args.engine, args.actuator, args.joint_drive)
    camera_settings = camera_config(args.realistic_sensing)
    successes = total = 0
    for seed in range(args.first_seed, args.first_seed + args.seeds):
        positions, velocities = balls_for_seed(seed, args.balls, 'all')
        goals = goals_for_seed(seed, args.balls)
        for i in range(args.balls):
            config = player_core.PlayerConfig(stream_commands=not args.no_stream, predict_ball=not args.no_predict)
            player = player_core.Player(config, actor)
            player.set_enabled(True)
            camera = sensing.BallCamera(camera_settings, np.random.default_rng([camera_settings.seed, total]))
            reason, links = play(cell, player, camera, positions[i], velocities[i], goals[i])
            successes += reason == referee.REASON_RETURNED
            total += 1
            print(f'seed {seed} ball {i}: {reason}{" " + ",".join(links) if links else ""}', flush=True)
    stream = 'one command per period' if args.no_stream else 'streamed commands'
    seen = 'realistic sensing' if args.realistic_sensing else 'perfect sensing'
    ball = 'the ball as measured' if args.no_predict else 'the ball carried forward'
    print(
        f'{args.engine} {args.actuator} joint_drive {args.joint_drive}, {stream}, {seen}, {ball}: '
        f'{successes}/{total} returned'
    )
    return 0


if __name__ == '__main__':
    sys.exit(main())
