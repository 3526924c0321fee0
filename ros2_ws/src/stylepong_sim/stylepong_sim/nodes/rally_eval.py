"""`ros2 run stylepong_sim rally_eval`: success rate of whatever plays the arm in ur5_sim, through ROS.

    rally_eval --balls 20 --first-seed 1000 --seeds 1 --speed all|low|high --json out.json
               [--ball-timeout-s 60] [--settle-timeout-s 20] [--no-enable]

Serves balls through /sim/launch_ball and judges them by ur5_sim's referee on /rally/events. For seed S
the balls are those of `ros2 run stylepong_policy evaluate` for S: the batched world's incoming-ball
sampler seeded with S, in the same batch size, so ball i here is environment i's first ball there (the
launch state exactly; what differs is the cell: MuJoCo at 1 kHz instead of the batched world's physics,
and ROS timing). Each ball gets a goal drawn from the task's goal distribution (uniform over centres of
a ws.GOAL_RADIUS_M region wholly on the opponent's half, seeded with S), sent on /player/goal.

Between balls: wait until the rally has ended (RALLY_END for that ball), the ball is gone and the player
is back at home (/player/status: ready and at_home; without a player, until /joint_states is at home
and at rest), then /sim/reset (removes nothing the arm needs, so no jump) and the next launch. A player
that is disabled is enabled on /player/enable unless --no-enable. Waits are in wall time, so the cell
may run at any real_time_factor the machine keeps up with. Run ur5_sim with a small max_lag_s (0.01):
where the machine (or video rendering) holds the cell back, it then runs slower than real time instead
of catching up in bursts of up to 0.25 s of simulated time during which no command can reach it (a
closed loop judged that way measured 5 % instead of 95 % success).

Prints one line per ball and the summary, and writes the summary as JSON: success_rate (mean over
seeds), success_rate_std, per_seed, hit_rate, failures (reason -> count), balls, seeds, as evaluate does,
plus balls_per_seed, speed, the rallies' outcomes and the player's last status (timing figures).
Exit codes: 0 done; 2 a bad flag (one line on stderr naming it, as the nodes do for a bad parameter,
stylepong_common.node_support); 1 ur5_sim or the player failed it; 130 Ctrl-C.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import signal
import sys
import time
from dataclasses import dataclass, field
from typing import NoReturn

import numpy as np
import rclpy
from geometry_msgs.msg import PointStamped
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import QoSProfile
from rclpy.signals import SignalHandlerOptions
from rclpy.utilities import remove_ros_args
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool, String
from std_srvs.srv import Trigger

from stylepong_common.command_line import print_and_write_json
from stylepong_common.exit_codes import EXIT_CONFIG_ERROR, EXIT_INTERRUPTED
from stylepong_common.node_process import wait_until
from stylepong_msgs.msg import BallState, RallyEvent
from stylepong_msgs.srv import LaunchBall
from stylepong_sim import world_spec
from stylepong_sim.referee import REASON_RETURNED

HOME_TOLERANCE_RAD = 0.02
REST_SPEED_RAD_S = 0.05
BALL_GONE_S = 0.3  # no /sim/ball/ground_truth for this long (wall): the ball has left the cell


@dataclass
class Rally:
    """One served ball and its verdict."""

    seed: int
    index: int
    ball_id: int = -1
    success: bool = False
    hit: bool = False
    reason: str = ''
    duration_s: float = 0.0  # sim time from launch to the verdict


@dataclass
class SeedResult:
    """The rallies of one seed."""

    seed: int
    rallies: list[Rally] = field(default_factory=list)

    @property
    def success_rate(self) -> float:
        return sum(r.success for r in self.rallies) / max(1, len(self.rallies))


def balls_for_seed(seed: int, count: int, speed: str) -> tuple[np.ndarray, np.ndarray]:
    """Launch positions [count, 3] and velocities [count, 3]: evaluate's first balls for this seed (its
    task builds the sampler with batch max(1024, 2 N) and draws all N environments' balls at once)."""
    from stylepong_sim.batched import batched_launcher

    sampler = batched_launcher.IncomingBallSampler(
        tuple(world_spec.SPEED_RANGES_M_S[speed]), seed=seed, device='cpu', batch=max(1024, 2 * count)
    )
    position, velocity, _ = sampler.sample(count)
    return position.T.double().numpy(), velocity.T.double().numpy()


def goals_for_seed(seed: int, count: int) -> np.ndarray:
    """Goal centres [count, 2], uniform so that a ws.GOAL_RADIUS_M region lies on the opponent's half."""
    rng = np.random.default_rng(seed)
    r = world_spec.GOAL_RADIUS_M
    return np.stack(
        (
            rng.uniform(r, world_spec.HALF_LENGTH_M - r, count),
            rng.uniform(-world_spec.HALF_WIDTH_M + r, world_spec.HALF_WIDTH_M - r, count),
        ),
        axis=1,
    )


def summarise(results: list[SeedResult], args: argparse.Namespace) -> dict:
    """The JSON summary of an evaluation: success and hit rates, failures and every rally."""
    rates = [r.success_rate for r in results]
    rallies = [rally for r in results for rally in r.rallies]
    failures: dict[str, int] = {}
    for rally in rallies:
        if not rally.success:
            failures[rally.reason] = failures.get(rally.reason, 0) + 1
    return {
        'success_rate': float(np.mean(rates)),
        'success_rate_std': float(np.std(rates)),
        'per_seed': [round(x, 4) for x in rates],
        'hit_rate': sum(r.hit for r in rallies) / max(1, len(rallies)),
        'failures': dict(sorted(failures.items(), key=lambda kv: -kv[1])),
        'balls': len(rallies),
        'seeds': [r.seed for r in results],
        'balls_per_seed': args.balls,
        'speed': args.speed,
        'through': 'ros (ur5_sim referee)',
        'rallies': [
            {
                'seed': r.seed,
                'ball': r.index,
                'success': r.success,
                'hit': r.hit,
                'reason': r.reason,
                'duration_s': round(r.duration_s, 3),
            }
            for r in rallies
        ],
    }


class RallyEvalNode(Node):
    """rally_eval's node: watches rally events, player status and the ball; enables the player, serves balls."""

    def __init__(self):
        super().__init__('rally_eval')
        qos = QoSProfile(depth=10)
        self.events: list[RallyEvent] = []
        self.status: dict | None = None
        self.joint_state: JointState | None = None
        self.last_ball_wall_s = -float('inf')
        self.create_subscription(RallyEvent, '/rally/events', self.events.append, QoSProfile(depth=100))
        self.create_subscription(String, '/player/status', self._on_status, qos)
        # The cell's truth, not /ball/state: whether a ball is still in the cell is the referee's business.
        self.create_subscription(BallState, '/sim/ball/ground_truth', self._on_ball, qos)
        self._joint_sub = None
        self.enable_pub = self.create_publisher(Bool, '/player/enable', qos)
        self.goal_pub = self.create_publisher(PointStamped, '/player/goal', qos)
        self.launch_client = self.create_client(LaunchBall, '/sim/launch_ball')
        self.reset_client = self.create_client(Trigger, '/sim/reset')

    def _on_status(self, msg: String) -> None:
        try:
            self.status = json.loads(msg.data)
        except json.JSONDecodeError:
            pass

    def _on_ball(self, _msg: BallState) -> None:
        self.last_ball_wall_s = time.monotonic()

    def watch_joint_states(self) -> None:
        """Without a player status, home is judged from /joint_states (500 Hz: subscribed only then)."""
        if self._joint_sub is None:
            self._joint_sub = self.create_subscription(
                JointState, '/joint_states', lambda m: setattr(self, 'joint_state', m), QoSProfile(depth=10)
            )

    def arm_settled(self) -> bool:
        if self.status is not None:
            return self.status.get('state') == 'ready' and bool(self.status.get('at_home'))
        msg = self.joint_state
        if msg is None:
            return False
        index = {n: i for i, n in enumerate(msg.name)}
        from stylepong_description.robot_model import JOINT_NAMES

        try:
            q = np.array([msg.position[index[n]] for n in JOINT_NAMES])
            qd = np.array([msg.velocity[index[n]] for n in JOINT_NAMES])
        except (KeyError, IndexError):
            return False
        return bool(
            np.abs(q - np.asarray(world_spec.HOME_JOINT_POSITIONS_RAD)).max() < HOME_TOLERANCE_RAD
            and np.abs(qd).max() < REST_SPEED_RAD_S
        )


class Evaluator:
    """Serves balls through ur5_sim one at a time and waits for each verdict."""

    def __init__(self, node: RallyEvalNode, executor: SingleThreadedExecutor, args: argparse.Namespace):
        self.node, self.executor, self.args = node, executor, args

    def spin_until(self, predicate, timeout_s: float) -> bool:
        return wait_until(predicate, timeout_s, spin=lambda: self.executor.spin_once(timeout_sec=0.01))

    def call(self, client, request, timeout_s: float = 10.0):
        future = client.call_async(request)
        if not self.spin_until(future.done, timeout_s):
            raise RuntimeError(f'{client.srv_name} did not answer within {timeout_s} s')
        return future.result()

    def prepare(self) -> None:
        node = self.node
        for client in (node.launch_client, node.reset_client):
            if not self.spin_until(client.service_is_ready, self.args.start_timeout_s):
                raise RuntimeError(
                    f'{client.srv_name} not available after {self.args.start_timeout_s} s: is ur5_sim running?'
                )
        if not self.spin_until(lambda: node.status is not None, self.args.player_timeout_s):
            print('rally_eval: no /player/status: judging home from /joint_states', file=sys.stderr, flush=True)
            node.watch_joint_states()
            return
        deadline = time.monotonic() + self.args.player_timeout_s
        while self.args.enable and node.status.get('state') == 'disabled':
            if time.monotonic() > deadline:
                raise RuntimeError('the player did not leave the disabled state after /player/enable true')
            node.enable_pub.publish(Bool(data=True))
            self.spin_until(lambda: node.status.get('state') != 'disabled', 0.6)

    def settle(self) -> None:
        """Ball gone and arm at home (or force it with /sim/reset after settle_timeout_s)."""
        node = self.node

        def gone_and_home() -> bool:
            return time.monotonic() - node.last_ball_wall_s > BALL_GONE_S and node.arm_settled()

        if not self.spin_until(gone_and_home, self.args.settle_timeout_s):
            print('rally_eval: arm not back home in time: resetting the cell', file=sys.stderr, flush=True)
        self.call(node.reset_client, Trigger.Request())
        self.spin_until(node.arm_settled, self.args.settle_timeout_s)

    def play(self, seed: int, index: int, position: np.ndarray, velocity: np.ndarray, goal: np.ndarray) -> Rally:
        node = self.node
        rally = Rally(seed=seed, index=index)
        self.settle()
        goal_msg = PointStamped()
        goal_msg.header.frame_id = 'world'
        goal_msg.point.x, goal_msg.point.y, goal_msg.point.z = float(goal[0]), float(goal[1]), world_spec.TABLE_HEIGHT_M
        node.goal_pub.publish(goal_msg)
        self.spin_until(lambda: False, 0.05)  # the goal arrives before the ball
        request = LaunchBall.Request(randomize=False)
        request.position.x, request.position.y, request.position.z = (float(v) for v in position)
        request.velocity.x, request.velocity.y, request.velocity.z = (float(v) for v in velocity)
        node.events.clear()
        response = self.call(node.launch_client, request)
        if not response.success:
            raise RuntimeError(f'seed {seed} ball {index}: {response.message}')
        rally.ball_id = response.ball_id

        def mine() -> list[RallyEvent]:
            return [e for e in node.events if e.ball_id == rally.ball_id]

        def ended() -> bool:
            return any(e.type == RallyEvent.RALLY_END for e in mine())

        if not self.spin_until(ended, self.args.ball_timeout_s):
            rally.reason = 'no_verdict'
            return rally
        events = mine()
        end = next(e for e in events if e.type == RallyEvent.RALLY_END)
        launched = next((e for e in events if e.type == RallyEvent.LAUNCHED), end)
        rally.success = bool(end.success)
        rally.reason = REASON_RETURNED if end.success else end.reason
        rally.hit = any(e.type == RallyEvent.PADDLE_HIT for e in events)
        rally.duration_s = (end.header.stamp.sec - launched.header.stamp.sec) + (
            end.header.stamp.nanosec - launched.header.stamp.nanosec
        ) * 1e-9
        return rally


class OneLineArgumentParser(argparse.ArgumentParser):
    """argparse that refuses a bad flag the way the nodes refuse a bad parameter: `<prog>: <reason>`, one
    line on stderr (no usage block: a launch script's log shows the reason, not the whole synopsis), and
    EXIT_CONFIG_ERROR (argparse's own code for a usage error, too)."""

    def error(self, message: str) -> NoReturn:
        print(f'{self.prog}: {" ".join(message.split())}', file=sys.stderr)
        sys.exit(EXIT_CONFIG_ERROR)


def parse_args(argv: list[str]) -> argparse.Namespace:
    """The command line of rally_eval."""
    parser = OneLineArgumentParser(prog='rally_eval', description=__doc__.split('\n\n')[0])
    parser.add_argument('--balls', type=int, default=world_spec.ROS_EVALUATION_BALLS_PER_SEED, help='balls per seed')
    parser.add_argument(
        '--first-seed',
        type=int,
        default=world_spec.FIRST_EVALUATION_SEED,
        help=f'first seed (evaluation seeds are >= {world_spec.FIRST_EVALUATION_SEED})',
    )
    parser.add_argument('--seeds', type=int, default=world_spec.EVALUATION_SEEDS, help='number of seeds')
    parser.add_argument(
        '--speed', choices=tuple(world_spec.SPEED_RANGES_M_S), default='all', help='incoming speed band'
    )
    parser.add_argument('--json', type=pathlib.Path, help='write the summary here')
    parser.add_argument('--ball-timeout-s', type=float, default=60.0, help='wall time to wait for a verdict')
    parser.add_argument(
        '--settle-timeout-s',
        type=float,
        default=20.0,
        help='wall time to wait for the ball to go and the arm to be home',
    )
    parser.add_argument('--start-timeout-s', type=float, default=60.0, help='wall time to wait for ur5_sim')
    parser.add_argument('--player-timeout-s', type=float, default=15.0, help='wall time to wait for the player')
    parser.add_argument('--no-enable', dest='enable', action='store_false', help='do not enable a disabled player')
    args = parser.parse_args(argv)
    for name in ('balls', 'seeds'):
        if getattr(args, name) < 1:
            parser.error(f'--{name} must be at least 1')
    if args.first_seed < 0:
        parser.error('--first-seed must not be negative')
    return args


def _interrupt(_signum, _frame) -> NoReturn:
    raise KeyboardInterrupt


def main(argv: list[str] | None = None) -> int:
    """Entry point of the rally_eval executable."""
    argv = sys.argv if argv is None else ['rally_eval', *argv]
    args = parse_args(remove_ros_args(argv)[1:])
    if args.first_seed < world_spec.FIRST_EVALUATION_SEED:
        print(
            f'rally_eval: seeds below {world_spec.FIRST_EVALUATION_SEED} are training/validation seeds', file=sys.stderr
        )
    # Ctrl-C and SIGTERM end the evaluation with one line: rclpy's own handlers would shut the context down
    # under the executor and leave a traceback or a misleading 'not available' instead.
    rclpy.init(args=argv, signal_handler_options=SignalHandlerOptions.NO)
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, _interrupt)
    node = RallyEvalNode()
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    evaluator = Evaluator(node, executor, args)
    started = time.monotonic()
    results: list[SeedResult] = []
    try:
        evaluator.prepare()
        for seed in range(args.first_seed, args.first_seed + args.seeds):
            positions, velocities = balls_for_seed(seed, args.balls, args.speed)
            goals = goals_for_seed(seed, args.balls)
            result = SeedResult(seed)
            for i in range(args.balls):
                rally = evaluator.play(seed, i, positions[i], velocities[i], goals[i])
                result.rallies.append(rally)
                print(
                    f'seed {seed} ball {i}: {"returned" if rally.success else rally.reason}'
                    f'{" (hit)" if rally.hit and not rally.success else ""}, {rally.duration_s:.2f} s',
                    flush=True,
                )
            results.append(result)
            print(
                f'seed {seed}: success {result.success_rate:.3f} '
                f'({sum(r.success for r in result.rallies)}/{len(result.rallies)})',
                flush=True,
            )
        evaluator.settle()
    except KeyboardInterrupt:
        print('rally_eval: interrupted', file=sys.stderr)
        return EXIT_INTERRUPTED
    except RuntimeError as error:
        print(f'rally_eval: {error}', file=sys.stderr)
        return 1
    finally:
        for signum in (signal.SIGINT, signal.SIGTERM):  # a second signal must not break the clean-up
            signal.signal(signum, signal.SIG_IGN)
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()
    summary = summarise(results, args)
    summary['wall_time_s'] = round(time.monotonic() - started, 2)
    summary['player_status'] = node.status
    print_and_write_json(summary, args.json)
    return 0


if __name__ == '__main__':
    sys.exit(main())
