"""`ros2 run stylepong_viz viewer`: the cell, the teaching and the player in a browser (rerun's web viewer).

    ros2 run stylepong_viz viewer                       # live: prints the page's address
    ros2 run stylepong_viz viewer --bag ros2_ws/bags/<clip>   # a recorded clip (mcap or sqlite3)
    options: --web-port 9090 --grpc-port 9876 --host 127.0.0.1 --memory-limit 512MiB

Live, it subscribes (best effort, so that a slow viewer never holds a publisher back; depth 50):
  /joint_states, /forward_position_controller/commands, /ball/state, /rally/events,
  /force_torque_sensor_broadcaster/wrench, /player/status
and only stores each message; a flush_rate_hz timer draws what arrived (decimated by message time,
cell_view.py). A bad option or a bag that is missing or damaged: one line on stderr, exit code 2.
"""
from __future__ import annotations

import argparse
import collections
import json
import pathlib
import sys
import time

EXIT_CONFIG_ERROR = 2
PROGRAM = 'viewer'
FLUSH_RATE_HZ = 10.0
PENDING_LIMIT = 5000      # 10 s of 500 Hz joint states


def parse_args(argv: list[str]) -> argparse.Namespace:
    """The viewer's own options; everything from --ros-args on is left to rclpy."""
    if '--ros-args' in argv:
        argv = argv[:argv.index('--ros-args')]

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
    args = parser.parse_args(argv)
    for name in ('web_port', 'grpc_port'):
        if not 1 <= getattr(args, name) <= 65535:
            parser.error(f'--{name.replace("_", "-")} must be 1-65535, got {getattr(args, name)}')
    return args


def _start_page(args: argparse.Namespace):
    import rerun as rr

    from stylepong_viz.cell_view import CellView, blueprint
    from stylepong_viz.serve import APPLICATION_ID, serve
    recording = rr.RecordingStream(APPLICATION_ID)
    page = serve(recording, blueprint(), args.web_port, args.grpc_port, args.memory_limit, args.host)
    view = CellView(recording)
    print(f'{PROGRAM}: open {page.url}', flush=True)
    return view, page


def run_bag(args: argparse.Namespace) -> int:
    """Serve a recorded clip until Ctrl-C or SIGTERM."""
    import signal

    from stylepong_viz.bag_view import BagError, _open_reader, show_bag
    try:
        _open_reader(args.bag).close()    # refuse a missing or damaged bag before serving anything
        view, _page = _start_page(args)
        counts = show_bag(args.bag, view)
    except (BagError, OSError) as error:
        print(f'{PROGRAM}: {" ".join(str(error).split())}', file=sys.stderr)
        return EXIT_CONFIG_ERROR
    print(f'{PROGRAM}: {args.bag}: ' + ', '.join(f'{t} {n}' for t, n in sorted(counts.items())) + '; Ctrl-C to stop',
          flush=True)
    stop: list[int] = []
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda received, _frame: stop.append(received))
    while not stop:
        time.sleep(0.2)
    return 0


def make_live_node(args: argparse.Namespace):
    """The live viewer node (rclpy imported here: --bag runs without a ROS graph)."""
    from geometry_msgs.msg import WrenchStamped
    from rclpy.node import Node
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Float64MultiArray, String

    from stylepong_common.node_support import ThrottledLog
    from stylepong_msgs.msg import BallState, RallyEvent
    from stylepong_sim.referee import EVENT_NAMES
    from stylepong_viz.cell_view import stamp_seconds

    class ViewerNode(Node):
        """Stores messages in the callbacks; draws them from a timer."""

        def __init__(self, **node_kwargs):
            super().__init__('stylepong_viewer', **node_kwargs)
            self.view, self.page = _start_page(args)
            self._warnings = ThrottledLog(self.get_logger(), 2.0)
            # Bounded: if drawing ever falls behind, the oldest undrawn messages go, never the graph's time.
            self._pending: collections.deque = collections.deque(maxlen=PENDING_LIMIT)
            qos = QoSProfile(depth=50, reliability=ReliabilityPolicy.BEST_EFFORT)
            self.create_subscription(JointState, '/joint_states', self._store('joints'), qos)
            self.create_subscription(Float64MultiArray, '/forward_position_controller/commands',
                                     self._store('command'), qos)
            self.create_subscription(BallState, '/ball/state', self._store('ball'), qos)
            self.create_subscription(RallyEvent, '/rally/events', self._store('event'), QoSProfile(depth=100))
            self.create_subscription(WrenchStamped, '/force_torque_sensor_broadcaster/wrench', self._store('wrench'),
                                     qos)
            self.create_subscription(String, '/player/status', self._store('status'), QoSProfile(depth=10))
            self.create_timer(1.0 / FLUSH_RATE_HZ, self._draw)
            self.get_logger().info(f'serving {self.page.url}')

        def _store(self, kind: str):
            pending = self._pending
            return lambda msg: pending.append((kind, msg))

        def _draw(self) -> None:
            view = self.view
            for _ in range(len(self._pending)):
                kind, msg = self._pending.popleft()
                try:
                    self._draw_one(view, kind, msg)
                except (ValueError, TypeError, AttributeError) as error:   # a malformed message: not drawn
                    self._warnings.warn(kind, f'{kind} message not drawn: {error}')
            view.flush()

        @staticmethod
        def _draw_one(view, kind: str, msg) -> None:
            if kind == 'joints':
                view.on_joint_state(stamp_seconds(msg.header), msg.name, msg.position, msg.velocity)
            elif kind == 'command':
                view.on_command(view.latest_time_s, list(msg.data))
            elif kind == 'ball':
                p = msg.position
                view.on_ball(stamp_seconds(msg.header), (p.x, p.y, p.z))
            elif kind == 'wrench':
                f = msg.wrench.force
                view.on_wrench(stamp_seconds(msg.header), msg.header.frame_id, (f.x, f.y, f.z))
            elif kind == 'event':
                p = msg.position
                view.on_rally_event(stamp_seconds(msg.header), EVENT_NAMES.get(msg.type, str(msg.type)), msg.reason,
                                    msg.success, (p.x, p.y, p.z))
            elif kind == 'status':
                view.on_player_status(view.latest_time_s, json.loads(msg.data))

    return ViewerNode


def main(argv: list[str] | None = None) -> int:
    """Entry point of the viewer executable."""
    argv = sys.argv[1:] if argv is None else argv
    args = parse_args(argv)
    if args.bag is not None:
        return run_bag(args)
    from stylepong_common.node_support import run_node
    from stylepong_viz.serve import ServeError
    ros_args = argv[argv.index('--ros-args'):] if '--ros-args' in argv else []
    return run_node(PROGRAM, make_live_node(args), [PROGRAM] + ros_args, config_errors=(ServeError,))


if __name__ == '__main__':
    sys.exit(main())
