"""`ros2 run stylepong_viz viewer`: the cell, the teaching and the player in a browser (rerun's web viewer).

    ros2 run stylepong_viz viewer                       # live: prints the page's address
    ros2 run stylepong_viz viewer --bag ros2_ws/bags/<clip>   # a recorded clip (mcap or sqlite3)
    options: --web-port 9090 --grpc-port 9876 --host 127.0.0.1 --memory-limit 512MiB --nice 10

Live, it subscribes (best effort, so that a slow viewer never holds a publisher back) to
  /joint_states, /forward_position_controller/commands, /ball/state, /force_torque_sensor_broadcaster/wrench
  (raw: a message's stamp is read from its bytes and the message decoded only if the view keeps it),
  /rally/events, /player/status
and calls back on none of them: a FLUSH_RATE_HZ timer takes what queued, the view decimates it by message
time (cell_view.py) and sends what it kept. Once serving, the process lowers its CPU priority (--nice): on a
busy machine the graph's nodes run first and the page waits.
A bad option or a bag that is missing or damaged: one line on stderr, exit code 2.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import pathlib
import sys
import time

from stylepong_common.exit_codes import EXIT_CONFIG_ERROR

PROGRAM = 'viewer'
FLUSH_RATE_HZ = 10.0  # the page's updates a second: each one a batch per entity
DEFAULT_NICE = 10  # a display yields the CPU to the nodes it watches
QUEUE_DEPTH = 100  # messages a subscription holds between two ticks: 500 Hz gives 33
ARM_SENT_MESSAGE = 'the arm is served at its /joint_states pose'  # logged once, at the first arm frame sent


def parse_args(argv: list[str]) -> argparse.Namespace:
    """The viewer's own options; everything from --ros-args on is left to rclpy."""
    if '--ros-args' in argv:
        argv = argv[: argv.index('--ros-args')]

    class OneLineParser(argparse.ArgumentParser):
        def error(self, message: str):
            print(f'{PROGRAM}: {message}', file=sys.stderr)
            raise SystemExit(EXIT_CONFIG_ERROR)

    parser = OneLineParser(prog=PROGRAM, description=__doc__.split('\n')[0])
    parser.add_argument('--bag', type=pathlib.Path, help='show a recorded clip (rosbag2 folder or .mcap/.db3 file)')
    parser.add_argument('--web-port', type=int, default=9090, help='HTTP port of the page (default 9090)')
    parser.add_argument('--grpc-port', type=int, default=9876, help="port of the page's data (default 9876)")
    parser.add_argument('--host', default='127.0.0.1', help='host name printed in the address (default 127.0.0.1)')
    parser.add_argument('--memory-limit', default='512MiB', help='data kept for the page; oldest dropped first')
    parser.add_argument(
        '--nice',
        type=int,
        default=DEFAULT_NICE,
        help=f"CPU priority given up, live, 0-19 (default {DEFAULT_NICE}; 0 keeps the caller's)",
    )
    args = parser.parse_args(argv)
    if not 0 <= args.nice <= 19:
        parser.error(f'--nice must be 0-19, got {args.nice}')
    for name in ('web_port', 'grpc_port'):
        if not 1 <= getattr(args, name) <= 65535:
            parser.error(f'--{name.replace("_", "-")} must be 1-65535, got {getattr(args, name)}')
    return args


def _start_page(args: argparse.Namespace):
    import rerun as rr

    from stylepong_viz.cell_view import CellView, blueprint
    from stylepong_viz.serve import APPLICATION_ID, serve

    # Rows logged one at a time leave for the page at each flush of the view, not rerun's default 0.2 s.
    recording = rr.RecordingStream(
        APPLICATION_ID, batcher_config=rr.ChunkBatcherConfig(flush_tick=datetime.timedelta(seconds=1.0 / FLUSH_RATE_HZ))
    )
    before = thread_ids()
    page = serve(recording, blueprint(), args.web_port, args.grpc_port, args.memory_limit, args.host)
    view = CellView(recording)
    print(f'{PROGRAM}: open {page.url}', flush=True)
    return view, page, thread_ids() - before


def thread_ids() -> set[int]:
    """The ids of this process's threads now."""
    return {int(task.name) for task in pathlib.Path('/proc/self/task').iterdir()}


def lower_priority(increment: int, keep: set[int] = frozenset()) -> None:
    """Every thread of this process but `keep` `increment` nicer (at most 19). On Linux a priority is a
    thread's, and a thread started later takes its starter's: the ones rclpy starts afterwards are nicer too."""
    for tid in thread_ids() - set(keep):
        try:
            os.setpriority(os.PRIO_PROCESS, tid, min(19, os.getpriority(os.PRIO_PROCESS, tid) + increment))
        except OSError:  # the thread ended meanwhile
            continue


def run_bag(args: argparse.Namespace) -> int:
    """Serve a recorded clip until Ctrl-C or SIGTERM."""
    import signal

    from stylepong_viz.bag_view import BagError, _open_reader, show_bag

    try:
        _open_reader(args.bag).close()  # refuse a missing or damaged bag before serving anything
        view, _page, _ = _start_page(args)
        counts = show_bag(args.bag, view)
    except (BagError, OSError) as error:
        print(f'{PROGRAM}: {" ".join(str(error).split())}', file=sys.stderr)
        return EXIT_CONFIG_ERROR
    print(
        f'{PROGRAM}: {args.bag}: ' + ', '.join(f'{t} {n}' for t, n in sorted(counts.items())) + '; Ctrl-C to stop',
        flush=True,
    )
    stop: list[int] = []
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda received, _frame: stop.append(received))
    while not stop:
        time.sleep(0.2)
    return 0


def take_all(subscription) -> list[tuple[int, object]]:
    """Every message waiting in `subscription`'s queue as (receive time ns, message: bytes when raw), oldest
    first; taken the way rclpy's executors take one before calling back (rclpy.executors)."""
    taken = []
    with subscription.handle:
        while (message_info := subscription.handle.take_message(subscription.msg_type, subscription.raw)) is not None:
            message, info = message_info
            taken.append((info['received_timestamp'], message))
    return taken


def make_live_node(args: argparse.Namespace):
    """The live viewer node (rclpy imported here: --bag runs without a ROS graph)."""
    from geometry_msgs.msg import WrenchStamped
    from rclpy.node import Node
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from rclpy.serialization import deserialize_message
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Float64MultiArray, String

    from stylepong_common.node_support import ThrottledLog
    from stylepong_fdcc.sensor_messages import wrench_from_cdr
    from stylepong_msgs.msg import BallState, RallyEvent
    from stylepong_recording.joint_state_cdr import CdrLayoutError
    from stylepong_sim.referee import EVENT_NAMES
    from stylepong_viz.cell_view import stamp_seconds
    from stylepong_viz.raw_messages import JointStateBytes, header_stamp_s

    def never_called(_message) -> None:
        """rclpy wants a callback; no executor spins the inputs' node, so none is ever called."""

    class ViewerNode(Node):
        """A timer takes the messages queued since its last tick, hands the view each one's stamp and a reader
        it calls only for the samples it keeps, and sends what was kept."""

        def __init__(self, **node_kwargs):
            super().__init__('stylepong_viewer', **node_kwargs)
            self.view, self.page, page_threads = _start_page(args)
            self._warnings = ThrottledLog(self.get_logger())
            self._joint_bytes = JointStateBytes()
            # The subscriptions hang on a second node that no executor spins: no callback, no wake-up per
            # message (a Python callback per 500 Hz message was most of the viewer's CPU). Best effort, so
            # that a slow viewer never holds a publisher back; a queue holds a tick's messages with room to
            # spare, and a late tick loses the oldest, never the graph's time. The 500 Hz streams are taken
            # raw: a message the view drops costs its stamp's 8 bytes.
            self._inputs = Node('stylepong_viewer_inputs', context=self.context, start_parameter_services=False)
            queue = QoSProfile(depth=QUEUE_DEPTH, reliability=ReliabilityPolicy.BEST_EFFORT)
            subscribe = self._inputs.create_subscription
            self._streams = (
                (
                    subscribe(JointState, '/joint_states', never_called, queue, raw=True),
                    'joint state',
                    self._joint_state,
                ),
                (
                    subscribe(
                        Float64MultiArray, '/forward_position_controller/commands', never_called, queue, raw=True
                    ),
                    'command',
                    self._command,
                ),
                (subscribe(BallState, '/ball/state', never_called, queue, raw=True), 'ball', self._ball),
                (
                    subscribe(WrenchStamped, '/force_torque_sensor_broadcaster/wrench', never_called, queue, raw=True),
                    'wrench',
                    self._wrench,
                ),
                (
                    subscribe(RallyEvent, '/rally/events', never_called, QoSProfile(depth=100)),
                    'rally event',
                    self._event,
                ),
                (
                    subscribe(String, '/player/status', never_called, QoSProfile(depth=10)),
                    'player status',
                    self._status,
                ),
            )
            self._arm_sent = False
            self.create_timer(1.0 / FLUSH_RATE_HZ, self._draw)
            # Started at the caller's priority (the page comes up sooner); from here on the graph goes first,
            # but for the threads that serve the page (started by serve()): starved, a browser's first
            # connection timed out and it stayed on rerun's welcome screen.
            lower_priority(args.nice, keep=page_threads)
            self.get_logger().info(f'serving {self.page.url} (nice +{args.nice})')

        def _draw(self) -> None:
            # In arrival order across topics: a command takes the time of the joint state before it.
            arrived = [
                (received_ns, k, message)
                for k, (subscription, _, _) in enumerate(self._streams)
                for received_ns, message in take_all(subscription)
            ]
            arrived.sort(key=lambda item: item[:2])
            for _, k, message in arrived:
                _, kind, show = self._streams[k]
                try:
                    show(message)
                except (ValueError, TypeError, AttributeError, RuntimeError) as error:  # malformed: not drawn
                    self._warnings.warn(kind, f'{kind} message not drawn: {error}')
            self.view.flush()
            if not self._arm_sent and self.view.counts['arm_frames']:
                # The viewer's side of "the page shows the cell": the static scene was logged before the address
                # was printed, and the arm's first pose has now gone to rerun, which serves it to the page. The
                # rest is the browser's work: the system test times this line, not the page's drawing.
                self._arm_sent = True
                self.get_logger().info(f'{ARM_SENT_MESSAGE} (message time {self.view.latest_time_s:.3f} s)')

        def _stamped(self, raw: bytes, msg_type):
            """(stamp s, None), or (stamp s, message) when the bytes had to be deserialised to find the stamp."""
            stamp = header_stamp_s(raw)
            if stamp is not None:
                return stamp, None
            msg = deserialize_message(raw, msg_type)
            return stamp_seconds(msg.header), msg

        def _joint_state(self, raw: bytes) -> None:
            stamp_s, msg = self._stamped(raw, JointState)

            def read():
                if msg is None:
                    try:
                        return self._joint_bytes.read(raw)
                    except CdrLayoutError:
                        pass
                full = msg or deserialize_message(raw, JointState)
                return full.name, full.position, full.velocity

            self.view.on_joint_state(stamp_s, read)

        def _command(self, raw: bytes) -> None:
            self.view.on_command(lambda: list(deserialize_message(raw, Float64MultiArray).data))

        def _ball(self, raw: bytes) -> None:
            stamp_s, msg = self._stamped(raw, BallState)

            def read() -> tuple[float, float, float]:
                p = (msg or deserialize_message(raw, BallState)).position
                return p.x, p.y, p.z

            self.view.on_ball(stamp_s, read)

        def _wrench(self, raw: bytes) -> None:
            stamp_s, _ = self._stamped(raw, WrenchStamped)
            self.view.on_wrench(stamp_s, lambda: wrench_from_cdr(raw))

        def _event(self, msg: RallyEvent) -> None:
            p = msg.position
            self.view.on_rally_event(
                stamp_seconds(msg.header),
                EVENT_NAMES.get(msg.type, str(msg.type)),
                msg.reason,
                msg.success,
                (p.x, p.y, p.z),
            )

        def _status(self, msg: String) -> None:
            self.view.on_player_status(self.view.latest_time_s, json.loads(msg.data))

        def close(self) -> None:
            """On the way out (stylepong_common.node_support.run_node): the inputs' node goes too."""
            self._inputs.destroy_node()

    return ViewerNode


def main(argv: list[str] | None = None) -> int:
    """Entry point of the viewer executable."""
    argv = sys.argv[1:] if argv is None else argv
    args = parse_args(argv)
    if args.bag is not None:
        return run_bag(args)
    from stylepong_common.node_support import run_node
    from stylepong_viz.serve import ServeError

    ros_args = argv[argv.index('--ros-args') :] if '--ros-args' in argv else []
    return run_node(PROGRAM, make_live_node(args), [PROGRAM] + ros_args, config_errors=(ServeError,))


if __name__ == '__main__':
    sys.exit(main())
