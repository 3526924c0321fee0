"""A small `ros2` command for a ROS 2 Jazzy installed from PyPI wheels, where ros2cli is unavailable.

It implements the verbs a node graph is debugged with, following the real ros2cli's behaviour and
output style:  run, topic list|echo|hz|info|pub, service list|call, node list,
pkg list|prefix|executables.
`make setup` installs it into the project's virtual environment as `ros2` (tools/ros2, which imports
this module from its sources) only when no real ros2cli exists; when the real one is importable, this
module hands over to it.

Discovery. The real ros2cli asks its long-lived daemon, which has seen the graph for a while. This
command has no daemon: it starts a node of its own, and with Fast DDS a node that is already running
announces itself only every 3 s (the default announcement period), so another node can take up to
that long (longer on a loaded machine) to become visible to a fresh one. The verbs that read the graph
therefore spin for at least `--spin-time` seconds (default 3.5); a smaller one answers faster and may
miss nodes that have not announced themselves yet.
Once a participant is found, its publications and its subscriptions arrive through separate DDS
endpoint-discovery exchanges, which a loaded machine can deliver a second apart: a quiet moment does not
mean the graph is complete. What does: every ROS participant publishes, on the DDS topic
`ros_discovery_info`, the GIDs of all the readers and writers of its nodes (rmw_dds_common's
ParticipantEntitiesInfo). After --spin-time the wait goes on until each participant's discovery info has
arrived and every endpoint it names has been discovered, and the graph has been unchanged for 0.5 s;
a graph that never gets there is read 10 s later at the latest.

Stopping. SIGINT (Ctrl-C) and SIGTERM (`timeout`, `kill`) end every verb quietly with status 0; a
second signal during the clean-up exits at once.
"""

import argparse
import collections
import math
import os
import signal
import sys
import time

DEFAULT_SPIN_TIME_S = 3.5  # Fast DDS's default announcement period (3 s) and a margin
GRAPH_SETTLE_S = 0.5  # after --spin-time, a complete graph must also be unchanged this long
GRAPH_MAX_EXTRA_S = 10.0  # a graph that stays incomplete or keeps changing is read this long after --spin-time
DISCOVERY_INFO_TOPIC = 'ros_discovery_info'  # a DDS topic name, without the rt/ of ROS topics


def _hand_over_to_real_ros2cli() -> None:
    try:
        from ros2cli.cli import main as real_main
    except ImportError:
        return
    sys.exit(real_main())


# ---------------------------------------------------------------------------------------------
# ros2 run / pkg: the ament resource index, exactly as ros2run / ros2pkg use it.


def _package_prefix(package: str) -> str:
    from ament_index_python.packages import PackageNotFoundError, get_package_prefix

    try:
        return get_package_prefix(package)
    except PackageNotFoundError:
        raise SystemExit(f"Package '{package}' not found")


def _executables(package: str) -> list:
    lib_dir = os.path.join(_package_prefix(package), 'lib', package)
    found = []
    for dirpath, dirnames, filenames in os.walk(lib_dir):
        dirnames[:] = [d for d in dirnames if not d.startswith('.')]  # like ros2pkg: skip hidden dirs
        for name in filenames:
            path = os.path.join(dirpath, name)
            if os.access(path, os.X_OK) and not name.startswith('.'):
                found.append(path)
    return sorted(found)


def cmd_run(argv: list) -> int:
    """ros2 run: execute a package's executable."""
    parser = argparse.ArgumentParser(prog='ros2 run', description='Run a package specific executable')
    parser.add_argument(
        '--prefix',
        metavar='PREFIX',
        help='Prefix command, which should go before the executable. '
        'Command must be wrapped in quotes if it contains spaces '
        "(e.g. --prefix 'gdb -ex run --args').",
    )
    parser.add_argument('package_name', help='Name of the ROS package')
    parser.add_argument('executable_name', help='Name of the executable')
    parser.add_argument('argv', nargs=argparse.REMAINDER, help='Pass arbitrary arguments to the executable')
    # --ros-args and everything after it belong to the node, never to this parser.
    if '--ros-args' in argv:
        split = argv.index('--ros-args')
        args = parser.parse_args(argv[:split])
        args.argv = args.argv + argv[split:]
    else:
        args = parser.parse_args(argv)
    matches = [p for p in _executables(args.package_name) if os.path.basename(p) == args.executable_name]
    if not matches:
        raise SystemExit('No executable found')
    if len(matches) > 1:
        raise SystemExit('Multiple executables found:\n' + '\n'.join('- ' + m for m in matches))
    command = ([] if args.prefix is None else args.prefix.split()) + [matches[0]] + args.argv
    sys.stdout.flush()
    sys.stderr.flush()
    # exec, not a child process: Ctrl-C and SIGTERM reach the node itself.
    os.execvp(command[0], command)
    return 1  # not reached


def cmd_pkg(argv: list) -> int:
    """ros2 pkg list | prefix | executables."""
    parser = argparse.ArgumentParser(prog='ros2 pkg')
    sub = parser.add_subparsers(dest='verb', required=True)
    sub.add_parser('list')
    p_prefix = sub.add_parser('prefix')
    p_prefix.add_argument('package_name')
    p_exe = sub.add_parser('executables')
    p_exe.add_argument('package_name', nargs='?')
    args = parser.parse_args(argv)
    from ament_index_python.packages import get_packages_with_prefixes

    if args.verb == 'list':
        for name in sorted(get_packages_with_prefixes()):
            print(name)
    elif args.verb == 'prefix':
        print(_package_prefix(args.package_name))
    else:
        packages = [args.package_name] if args.package_name else sorted(get_packages_with_prefixes())
        for package in packages:
            for path in _executables(package):
                print(package, os.path.basename(path))
    return 0


# ---------------------------------------------------------------------------------------------
# ros2 topic / node: a short-lived node on the graph.


class _Stopped(Exception):
    """SIGINT or SIGTERM arrived: the verb ends quietly."""


_stop_signal: str | None = None  # the name of the SIGINT or SIGTERM that arrived, once one has


def _stop_on_signals() -> None:
    """SIGINT and SIGTERM raise _Stopped in the main thread; a second one exits at once.

    rclpy's own handlers are not installed (see _start_node): on SIGTERM they shut the context down
    under a spinning node, which surfaces as an ExternalShutdownException traceback.
    """

    def on_signal(signum, _frame):
        global _stop_signal
        _stop_signal = signal.Signals(signum).name
        signal.signal(signal.SIGINT, lambda *_: os._exit(128 + signal.SIGINT))
        signal.signal(signal.SIGTERM, lambda *_: os._exit(128 + signal.SIGTERM))
        # _Stopped may land inside a constructor (an rclpy Task half built), whose __del__ then fails at
        # clean-up and Python prints "Exception ignored in ...". After a stop every error is the stop's.
        sys.unraisablehook = lambda _unraisable: None
        raise _Stopped(_stop_signal)

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)


def _start_node(name: str):
    import rclpy
    from rclpy.signals import SignalHandlerOptions

    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node(name, start_parameter_services=False, enable_rosout=False)
    return rclpy, node


def _graph_snapshot(node):
    return (
        sorted((name, tuple(types)) for name, types in node.get_topic_names_and_types()),
        sorted(node.get_node_names_and_namespaces()),
        sorted((name, tuple(types)) for name, types in node.get_service_names_and_types()),
    )


class _DiscoveryInfoReader:
    """A reader of `ros_discovery_info`: which endpoint GIDs each ROS participant's nodes own.

    rclpy cannot subscribe to this topic: rcl makes every topic name absolute, so even with
    avoid_ros_namespace_conventions its DDS topic would be '/ros_discovery_info'. The reader is therefore
    made one level down, with rmw_create_subscription (through ctypes), which takes the DDS name as given;
    its messages are taken serialized and decoded by rclpy. The QoS is the publishers' (rmw_dds_common:
    reliable, transient local), so each participant's latest info arrives even if it was published long
    ago, but with room for many samples: the topic has a single instance, and a depth of 1 would let one
    participant's info replace another's before it is taken.
    """

    def __init__(self, node):
        import ctypes

        from rclpy.type_support import check_for_type_support
        from rmw_dds_common.msg import ParticipantEntitiesInfo

        class RmwTime(ctypes.Structure):
            _fields_ = [('sec', ctypes.c_uint64), ('nsec', ctypes.c_uint64)]

        class RmwQosProfile(ctypes.Structure):  # rmw/types.h, rmw_qos_profile_t
            _fields_ = [
                ('history', ctypes.c_int),
                ('depth', ctypes.c_size_t),
                ('reliability', ctypes.c_int),
                ('durability', ctypes.c_int),
                ('deadline', RmwTime),
                ('lifespan', RmwTime),
                ('liveliness', ctypes.c_int),
                ('liveliness_lease_duration', RmwTime),
                ('avoid_ros_namespace_conventions', ctypes.c_bool),
            ]

        class Allocator(ctypes.Structure):  # rcutils/allocator.h, rcutils_allocator_t: four functions and a state
            _fields_ = [
                (name, ctypes.c_void_p) for name in ('allocate', 'deallocate', 'reallocate', 'zero_allocate', 'state')
            ]

        class SerializedMessage(ctypes.Structure):  # rcutils/types/uint8_array.h, rmw_serialized_message_t
            _fields_ = [
                ('buffer', ctypes.c_void_p),
                ('buffer_length', ctypes.c_size_t),
                ('buffer_capacity', ctypes.c_size_t),
                ('allocator', Allocator),
            ]

        self._ctypes, self._message_type = ctypes, ParticipantEntitiesInfo
        # rclpy has loaded librcl; symbols looked up through it are found in the libraries it links
        # (rcutils, and rmw_implementation or the rmw library itself), whichever the installation has.
        self._lib = lib = ctypes.CDLL('librcl.so')
        lib.rcl_node_get_rmw_handle.restype = ctypes.c_void_p
        lib.rcl_node_get_rmw_handle.argtypes = [ctypes.c_void_p]
        lib.rmw_create_subscription.restype = ctypes.c_void_p
        lib.rmw_create_subscription.argtypes = [ctypes.c_void_p] * 2 + [ctypes.c_char_p] + [ctypes.c_void_p] * 2
        lib.rmw_take_serialized_message.argtypes = [ctypes.c_void_p] * 4
        lib.rmw_destroy_subscription.argtypes = [ctypes.c_void_p] * 2
        lib.rcutils_get_default_allocator.restype = Allocator
        lib.rcutils_uint8_array_init.argtypes = [ctypes.c_void_p, ctypes.c_size_t, ctypes.c_void_p]
        lib.rcutils_uint8_array_fini.argtypes = [ctypes.c_void_p]
        ctypes.pythonapi.PyCapsule_GetPointer.restype = ctypes.c_void_p
        ctypes.pythonapi.PyCapsule_GetPointer.argtypes = [ctypes.py_object, ctypes.c_char_p]

        check_for_type_support(ParticipantEntitiesInfo)
        type_support = ctypes.pythonapi.PyCapsule_GetPointer(ParticipantEntitiesInfo._TYPE_SUPPORT, None)
        qos = RmwQosProfile(
            history=1,
            depth=100,
            reliability=1,
            durability=1,  # keep last, reliable, transient local
            avoid_ros_namespace_conventions=True,
        )
        # rmw_subscription_options_t, all defaults (null payload, local publications delivered, no
        # content filter) are zeros; the buffer is larger than the struct in any rmw version.
        options = (ctypes.c_uint8 * 128)()
        self._rmw_node = lib.rcl_node_get_rmw_handle(node.handle.pointer)
        self._subscription = lib.rmw_create_subscription(
            self._rmw_node, type_support, DISCOVERY_INFO_TOPIC.encode(), ctypes.byref(qos), options
        )
        if not self._subscription:
            lib.rcutils_reset_error()
            raise OSError(f'rmw_create_subscription({DISCOVERY_INFO_TOPIC}) failed')
        self._message = SerializedMessage()
        allocator = lib.rcutils_get_default_allocator()
        if lib.rcutils_uint8_array_init(ctypes.byref(self._message), 4096, ctypes.byref(allocator)) != 0:
            self.close()
            raise OSError('rcutils_uint8_array_init failed')

    def take(self) -> list:
        """The ParticipantEntitiesInfo messages received since the last call."""
        ctypes, messages, taken = self._ctypes, [], self._ctypes.c_bool()
        from rclpy.serialization import deserialize_message

        while (
            self._lib.rmw_take_serialized_message(
                self._subscription, ctypes.byref(self._message), ctypes.byref(taken), None
            )
            == 0
            and taken.value
        ):
            data = ctypes.string_at(self._message.buffer, self._message.buffer_length)
            messages.append(deserialize_message(data, self._message_type))
        return messages

    def close(self) -> None:
        if self._subscription:
            self._lib.rmw_destroy_subscription(self._rmw_node, self._subscription)
            self._subscription = None
        if self._message.buffer:
            self._lib.rcutils_uint8_array_fini(self._ctypes.byref(self._message))


def _open_discovery_info_reader(node):
    """A _DiscoveryInfoReader, or None where rmw cannot be reached this way (the wait then relies on
    the graph being unchanged for GRAPH_SETTLE_S alone)."""
    try:
        return _DiscoveryInfoReader(node)
    except (OSError, AttributeError):  # no librcl by that name, a missing symbol, or rmw refused
        return None


def _named_endpoints(info) -> set:
    """The GIDs of every reader and writer a ParticipantEntitiesInfo names, as bytes."""
    return {
        bytes(gid.data)
        for node_info in info.node_entities_info_seq
        for gid in (*node_info.reader_gid_seq, *node_info.writer_gid_seq)
    }


def _discovered_endpoints(node):
    """The GIDs (bytes) of every discovered reader and writer, and those of the ros_discovery_info writers.

    no_demangle lists the DDS topics as they are, services' rq/ and rr/ topics included.
    """
    endpoints, discovery_info_writers = set(), set()
    for name, _types in node.get_topic_names_and_types(no_demangle=True):
        writers = {bytes(i.endpoint_gid) for i in node.get_publishers_info_by_topic(name, no_mangle=True)}
        readers = {bytes(i.endpoint_gid) for i in node.get_subscriptions_info_by_topic(name, no_mangle=True)}
        endpoints |= writers | readers
        if name == DISCOVERY_INFO_TOPIC:
            discovery_info_writers = writers
    return endpoints, discovery_info_writers


def _undiscovered_participants(discovery_info_writers: set, named: dict, endpoints: set) -> list:
    """The GUID prefixes of the ROS participants whose endpoints are not all discovered yet.

    A GID is a DDS GUID: a 12-byte prefix naming the participant, then 4 bytes naming the entity. Every
    ROS participant has one ros_discovery_info writer, so those writers say which participants are in
    the graph now (one that has left takes its writer along, and its last info no longer counts).
    named: the endpoint GIDs of each participant's latest discovery info, by the participant's prefix.
    A participant is undiscovered while its info has not arrived (nothing says yet which endpoints it
    has) or names a GID that is not among the discovered endpoints. The helper's own participant counts
    like any other: its info arrives locally at once and names only local endpoints, known at once.
    """
    participants = sorted({gid[:12] for gid in discovery_info_writers})
    return [p for p in participants if p not in named or not named[p] <= endpoints]


def _wait_for_graph(node, spin_time: float) -> None:
    """Spin until discovery is complete: at least spin_time, then until every ROS participant's
    endpoints are discovered and the graph has been unchanged for GRAPH_SETTLE_S (at most
    GRAPH_MAX_EXTRA_S more)."""
    import rclpy

    reader = _open_discovery_info_reader(node)
    named = {}  # participant GUID prefix -> endpoint GIDs of its latest discovery info
    start = time.monotonic()
    seen = _graph_snapshot(node)
    last_change = start
    try:
        while True:
            rclpy.spin_once(node, timeout_sec=0.05)
            for info in reader.take() if reader else ():
                named[bytes(info.gid.data)[:12]] = _named_endpoints(info)
            now = time.monotonic()
            current = _graph_snapshot(node)
            if current != seen:
                seen, last_change = current, now
            waited = now - start
            if waited >= spin_time + GRAPH_MAX_EXTRA_S:
                return
            if waited >= spin_time and now - last_change >= GRAPH_SETTLE_S:
                if reader is None:
                    return
                # Listed only now, not at every spin: it costs two queries per DDS topic.
                endpoints, discovery_info_writers = _discovered_endpoints(node)
                if not _undiscovered_participants(discovery_info_writers, named, endpoints):
                    return
    finally:
        if reader:
            reader.close()


def _add_spin_time(parser) -> None:
    parser.add_argument(
        '--spin-time',
        type=float,
        default=DEFAULT_SPIN_TIME_S,
        metavar='SECONDS',
        help='Spin time in seconds to wait for discovery; the wait goes on until every '
        "node's endpoints are discovered and the graph has settled "
        f'(default: {DEFAULT_SPIN_TIME_S})',
    )
    parser.add_argument(
        '--no-daemon',
        action='store_true',
        help='Accepted for compatibility with ros2cli; this command never uses a daemon',
    )


def _topic_type(node, topic: str, wait_s: float):
    deadline = time.monotonic() + wait_s
    import rclpy

    while True:
        for name, types in node.get_topic_names_and_types():
            if name == topic:
                return types[0]
        if time.monotonic() > deadline:
            return None
        rclpy.spin_once(node, timeout_sec=0.1)


def _subscription_qos(node, topic: str):
    """Match the publishers: best effort if any publisher is best effort (what ros2cli does)."""
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    infos = node.get_publishers_info_by_topic(topic)
    qos = QoSProfile(depth=10)
    if any(i.qos_profile.reliability == ReliabilityPolicy.BEST_EFFORT for i in infos):
        qos.reliability = ReliabilityPolicy.BEST_EFFORT
    if infos and all(i.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL for i in infos):
        qos.durability = DurabilityPolicy.TRANSIENT_LOCAL
    return qos


def _resolve(topic: str) -> str:
    return topic if topic.startswith('/') else '/' + topic


def _parser_with_list_verb(prog: str, listed: str):
    """A parser for `prog` with verbs (parser, its subparsers, the `list` verb's): `list` of the graph's `listed`.

    As ros2cli's, `list` takes -t/--show-types; the caller adds the other verbs.
    """
    parser = argparse.ArgumentParser(prog=prog)
    sub = parser.add_subparsers(dest='verb', required=True)
    p_list = sub.add_parser('list', help=f'Output a list of available {listed}')
    p_list.add_argument('-t', '--show-types', action='store_true')
    return parser, sub, p_list


def _print_names_and_types(names_and_types, show_types: bool) -> None:
    """A line a name, sorted, as `ros2 topic list` and `ros2 service list` print them (`name [types]` with -t)."""
    for name, types in sorted(names_and_types):
        print(f'{name} [{", ".join(types)}]' if show_types else name)


def cmd_topic(argv: list) -> int:
    """ros2 topic list | echo | hz | info | pub."""
    parser, sub, p_list = _parser_with_list_verb('ros2 topic', 'topics')
    p_echo = sub.add_parser('echo', help='Output messages from a topic')
    p_echo.add_argument('topic_name')
    p_echo.add_argument('message_type', nargs='?')
    p_echo.add_argument('--once', action='store_true', help='Print the first message received and then exit')
    p_echo.add_argument('--times', type=int, help='Print N messages and then exit')
    p_echo.add_argument('--field', help='Echo a selected field of a message, e.g. position.x')
    p_echo.add_argument('--no-arr', action='store_true', help="Don't print array fields of messages")
    p_echo.add_argument('--flow-style', action='store_true', help='Print collections in the block style')
    p_hz = sub.add_parser('hz', help='Print the average publishing rate to screen')
    p_hz.add_argument('topic_name')
    p_hz.add_argument(
        '-w',
        '--window',
        type=int,
        default=10000,
        help='window size, in # of messages, for calculating rate (default: 10000)',
    )
    p_info = sub.add_parser('info', help='Print information about a topic')
    p_info.add_argument('topic_name')
    for verb_parser in (p_list, p_echo, p_hz, p_info):
        _add_spin_time(verb_parser)
    _add_pub_arguments(sub.add_parser('pub', help='Publish a message to a topic'))
    args = parser.parse_args(argv)
    if args.verb == 'pub':
        return _pub(args)

    rclpy, node = _start_node('_ros2cli_topic_%d' % os.getpid())
    try:
        if args.verb == 'list':
            _wait_for_graph(node, args.spin_time)
            _print_names_and_types(node.get_topic_names_and_types(), args.show_types)
            return 0
        topic = _resolve(args.topic_name)
        if args.verb == 'info':
            _wait_for_graph(node, args.spin_time)
            types = dict(node.get_topic_names_and_types()).get(topic)
            if types is None:
                raise SystemExit(f"Unknown topic '{topic}'")
            print(f'Type: {"; ".join(types)}')
            print(f'Publisher count: {node.count_publishers(topic)}')
            print(f'Subscription count: {node.count_subscribers(topic)}')
            return 0
        # Wait for the topic even when its type is given: the subscription's QoS follows its publishers.
        found_type = _topic_type(node, topic, wait_s=args.spin_time)
        type_name = getattr(args, 'message_type', None) or found_type
        if type_name is None:
            print(f'WARNING: topic [{topic}] does not appear to be published yet', file=sys.stderr)
            type_name = _topic_type(node, topic, wait_s=float('inf'))
        msg_class = _message_class(type_name)
        qos = _subscription_qos(node, topic)
        if args.verb == 'echo':
            return _echo(rclpy, node, topic, msg_class, qos, args)
        return _hz(rclpy, node, topic, msg_class, qos, args.window)
    finally:
        _stop_node(rclpy, node)


def _stop_node(rclpy, node) -> None:
    node.destroy_node()
    rclpy.try_shutdown()


def _message_class(type_name: str):
    """'sensor_msgs/msg/JointState' -> the Python class (rosidl_runtime_py is not among the wheels)."""
    import importlib

    package, interface, name = type_name.split('/')
    return getattr(importlib.import_module(f'{package}.{interface}'), name)


def _to_plain(value, no_arr: bool):
    """A message as nested dicts/lists in field order, the shape ros2 topic echo prints."""
    if hasattr(value, 'get_fields_and_field_types'):
        out = {}
        for field in value.get_fields_and_field_types():
            item = getattr(value, field)
            is_sequence = isinstance(item, (list, tuple)) or hasattr(item, 'tolist')
            if no_arr and is_sequence:
                out[field] = f'<sequence type: {value.get_fields_and_field_types()[field]}, length: {len(item)}>'
            else:
                out[field] = _to_plain(item, no_arr)
        return out
    if hasattr(value, 'tolist'):
        value = value.tolist()
    if isinstance(value, (list, tuple)):
        return [_to_plain(v, no_arr) for v in value]
    if isinstance(value, bytes):
        return list(value)
    return value


def message_to_yaml(msg, no_arr: bool = False, flow_style: bool = False) -> str:
    """A message as YAML, the way ros2 topic echo prints it."""
    import yaml

    plain = _to_plain(msg, no_arr)
    if not isinstance(plain, (dict, list)):
        return f'{plain}\n'
    return yaml.dump(plain, sort_keys=False, default_flow_style=flow_style, allow_unicode=True, width=float('inf'))


def _echo(rclpy, node, topic, msg_class, qos, args) -> int:
    limit = 1 if args.once else args.times
    printed = [0]

    def on_message(msg):
        if args.field:
            for part in args.field.split('.'):
                msg = getattr(msg, part)
        text = message_to_yaml(msg, args.no_arr, args.flow_style)
        sys.stdout.write(text + '---\n')
        sys.stdout.flush()
        printed[0] += 1

    node.create_subscription(msg_class, topic, on_message, qos)
    while rclpy.ok() and (limit is None or printed[0] < limit):
        rclpy.spin_once(node, timeout_sec=0.1)
    return 0


def _hz(rclpy, node, topic, msg_class, qos, window: int) -> int:
    arrivals = collections.deque(maxlen=window + 1)
    node.create_subscription(msg_class, topic, lambda _msg: arrivals.append(time.monotonic()), qos)
    next_print = time.monotonic() + 1.0
    while rclpy.ok():
        rclpy.spin_once(node, timeout_sec=0.05)
        now = time.monotonic()
        if now < next_print:
            continue
        next_print = now + 1.0
        if len(arrivals) < 2:
            print('no new messages')
            continue
        stamps = list(arrivals)
        periods = [b - a for a, b in zip(stamps, stamps[1:])]
        mean = sum(periods) / len(periods)
        std = math.sqrt(sum((p - mean) ** 2 for p in periods) / len(periods))
        print(
            f'average rate: {1.0 / mean:.3f}\n'
            f'\tmin: {min(periods):.3f}s max: {max(periods):.3f}s std dev: {std:.5f}s window: {len(periods) + 1}',
            flush=True,
        )
    return 0


def _positive_float(text: str) -> float:
    value = float(text)
    if not value > 0.0:
        raise argparse.ArgumentTypeError(f'{text} is not positive')
    return value


def _nonnegative_int(text: str) -> int:
    value = int(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f'{text} is negative')
    return value


def _add_pub_arguments(parser) -> None:
    """ros2cli's `ros2 topic pub` arguments (Jazzy), with the same names, defaults and meaning."""
    parser.add_argument('topic_name', help="Name of the ROS topic to publish to (e.g. '/chatter')")
    parser.add_argument('message_type', help="Type of the ROS message (e.g. 'std_msgs/msg/String')")
    parser.add_argument(
        'values',
        nargs='?',
        default='{}',
        help='Values to fill the message with in YAML format (e.g. "{data: true}"), '
        'otherwise the message is published with default values',
    )
    parser.add_argument(
        '-r', '--rate', metavar='N', type=_positive_float, default=1.0, help='Publishing rate in Hz (default: 1)'
    )
    parser.add_argument(
        '-p',
        '--print',
        metavar='N',
        type=int,
        default=1,
        help='Only print every N-th published message (default: 1; 0: none)',
    )
    once_or_times = parser.add_mutually_exclusive_group()
    once_or_times.add_argument('-1', '--once', action='store_true', help='Publish one message and exit')
    once_or_times.add_argument(
        '-t', '--times', type=_nonnegative_int, default=0, help='Publish this number of times and then exit'
    )
    parser.add_argument(
        '-w',
        '--wait-matching-subscriptions',
        type=_nonnegative_int,
        default=None,
        help='Wait until finding the specified number of matching subscriptions. '
        'Defaults to 1 when using "-1"/"--once"/"--times", otherwise defaults to 0.',
    )
    parser.add_argument(
        '--max-wait-time-secs',
        type=_positive_float,
        default=None,
        help='Give up waiting for matching subscriptions after this many seconds and '
        'publish anyway (default: wait for ever)',
    )
    parser.add_argument(
        '--keep-alive',
        metavar='N',
        type=_positive_float,
        default=0.1,
        help='Keep publishing node alive for N seconds after the last msg (default: 0.1)',
    )
    parser.add_argument('-n', '--node-name', help='Name of the created publishing node')
    parser.add_argument(
        '--qos-depth',
        metavar='N',
        type=_nonnegative_int,
        default=10,
        help='Queue size setting to publish with (default: 10)',
    )
    parser.add_argument(
        '--qos-reliability',
        choices=('reliable', 'best_effort'),
        default='reliable',
        help='Quality of service reliability setting to publish with (default: reliable)',
    )
    parser.add_argument(
        '--qos-durability',
        choices=('volatile', 'transient_local'),
        default='volatile',
        help='Quality of service durability setting to publish with (default: volatile)',
    )


def _pub(args) -> int:
    """ros2 topic pub: the message is built (and any error in it reported) before a node exists."""
    import yaml
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    msg_class = _message_class(args.message_type)
    msg = msg_class()
    stamp_fields = []
    try:
        values = yaml.safe_load(args.values)
    except yaml.YAMLError as error:
        raise SystemExit(f'The passed value needs to be a dictionary in YAML format: {error}')
    _set_fields(msg, values, stamp_fields)
    times = 1 if args.once else args.times
    wait_for = args.wait_matching_subscriptions
    if wait_for is None:
        wait_for = 1 if times else 0
    qos = QoSProfile(
        depth=args.qos_depth,
        reliability=ReliabilityPolicy[args.qos_reliability.upper()],
        durability=DurabilityPolicy[args.qos_durability.upper()],
    )

    rclpy, node = _start_node(args.node_name or '_ros2cli_%d' % os.getpid())
    try:
        publisher = node.create_publisher(msg_class, _resolve(args.topic_name), qos)
        # A --once message sent before the subscriber is matched would be lost: wait for it first.
        deadline = None if args.max_wait_time_secs is None else time.monotonic() + args.max_wait_time_secs
        announced = False
        while publisher.get_subscription_count() < wait_for:
            if deadline is not None and time.monotonic() > deadline:
                break
            if not announced:
                print('Waiting for at least %d matching subscription(s)...' % wait_for, flush=True)
                announced = True
            rclpy.spin_once(node, timeout_sec=0.1)
        print('publisher: beginning loop', flush=True)
        period = 1.0 / args.rate
        count = 0
        next_publish = time.monotonic()
        while rclpy.ok() and (times == 0 or count < times):
            wait = next_publish - time.monotonic()
            if wait > 0.0:
                rclpy.spin_once(node, timeout_sec=wait)
                continue
            for stamp in stamp_fields:
                stamp(time.time_ns())
            publisher.publish(msg)
            count += 1
            if args.print > 0 and count % args.print == 0:
                print(f'publishing #{count}: {msg!r}\n', flush=True)
            # A fixed schedule, not a sleep after each message, so the rate holds however long publishing
            # takes; after a stall it resumes from now rather than sending the missed messages in a burst.
            next_publish = max(next_publish + period, time.monotonic())
        # Reliable delivery of the last message happens after publish() returns: stay up a moment.
        end = time.monotonic() + args.keep_alive
        while time.monotonic() < end:
            rclpy.spin_once(node, timeout_sec=max(0.0, end - time.monotonic()))
        return 0
    finally:
        _stop_node(rclpy, node)


def cmd_node(argv: list) -> int:
    """ros2 node list."""
    parser = argparse.ArgumentParser(prog='ros2 node')
    sub = parser.add_subparsers(dest='verb', required=True)
    _add_spin_time(sub.add_parser('list', help='Output a list of available nodes'))
    args = parser.parse_args(argv)
    rclpy, node = _start_node('_ros2cli_node_%d' % os.getpid())
    try:
        _wait_for_graph(node, args.spin_time)
        own = node.get_name()
        names = sorted(
            (ns.rstrip('/') + '/' + name) for name, ns in node.get_node_names_and_namespaces() if name != own
        )
        for name in names:
            print(name)
    finally:
        _stop_node(rclpy, node)
    return 0


def _set_fields(msg, values, stamp_fields: list | None = None) -> None:
    """Fill a message from a YAML mapping, like rosidl_runtime_py.set_message_fields.

    Nested messages take nested mappings, sequences of messages take lists of mappings, and numbers
    are converted to the field's type (YAML reads `1` as an int where the field is a double). As in
    ros2cli, a `builtin_interfaces/Time` given as `now` and a `std_msgs/Header` given as `auto` are
    stamped with the current time; the setters that do it are appended to `stamp_fields` so that a
    publisher can stamp every message it sends afresh.
    """
    if values is None:
        return
    if not isinstance(values, dict):
        raise SystemExit(
            f"Failed to populate message '{type(msg).__name__}': expected a mapping of "
            f'field names to values, got {values!r}'
        )
    fields = msg.get_fields_and_field_types()
    for name, value in values.items():
        if name not in fields:
            raise SystemExit(f"Failed to populate field: '{type(msg).__name__}' object has no attribute '{name}'")
        current = getattr(msg, name)
        try:
            setattr(msg, name, _field_value(current, fields[name], value, stamp_fields))
        except (AssertionError, TypeError, ValueError) as error:
            detail = f': {error}' if str(error) else ''
            raise SystemExit(
                f"Failed to populate field '{name}' of '{type(msg).__name__}' ({fields[name]}) with {value!r}{detail}"
            )


_BASIC_TYPES = {
    'float': float,
    'double': float,
    'boolean': bool,
    'string': str,
    'wstring': str,
    'char': int,
    'octet': bytes,
    'byte': bytes,
}


def _basic_converter(type_name: str):
    """The Python type a basic ROS field element takes: int8..uint64 are ints, float/double floats."""
    base = type_name.split('<')[0]
    if base in _BASIC_TYPES:
        return _BASIC_TYPES[base]
    if base.startswith(('int', 'uint')):
        return int
    return None


def _element_type(type_name: str) -> str:
    """'sequence<double, 6>' -> 'double', 'double[6]' -> 'double', 'sequence<geometry_msgs/Point>' -> ..."""
    if type_name.startswith('sequence<'):
        return type_name[len('sequence<') : -1].split(',')[0].strip()
    return type_name.split('[')[0]


def _now_setter(stamp) -> callable:
    def set_now(now_ns: int) -> None:
        stamp.sec, stamp.nanosec = divmod(now_ns, 1_000_000_000)

    return set_now


def _field_value(current, type_name: str, value, stamp_fields):
    """The value a field of type `type_name` (now holding `current`) is set to from YAML's `value`."""
    if hasattr(current, 'get_fields_and_field_types'):
        kind = f'{type(current).__module__.split(".")[0]}/{type(current).__name__}'
        if value == 'now' and kind == 'builtin_interfaces/Time' and stamp_fields is not None:
            stamp_fields.append(_now_setter(current))
        elif value == 'auto' and kind == 'std_msgs/Header' and stamp_fields is not None:
            stamp_fields.append(_now_setter(current.stamp))
        else:
            _set_fields(current, value, stamp_fields)
        return current
    is_array = type_name.startswith('sequence<') or type_name.endswith(']')
    if not is_array:
        convert = _basic_converter(type_name) or type(current)
        if convert is bool and not isinstance(value, bool):
            raise ValueError('expected true or false')
        if convert is bytes:
            return bytes([value]) if isinstance(value, int) else bytes(value)
        return convert(value)
    if not isinstance(value, list):
        raise ValueError('expected a list')
    element = _element_type(type_name)
    convert = _basic_converter(element)
    if convert is None:
        # A sequence of messages: each item a mapping for a fresh instance of the element type.
        element_class = _message_class(element.replace('/', '/msg/', 1) if element.count('/') == 1 else element)
        items = []
        for item in value:
            instance = element_class()
            _set_fields(instance, item, stamp_fields)
            items.append(instance)
        return items
    if convert is bytes:
        return [bytes([v]) if isinstance(v, int) else bytes(v) for v in value]
    return [convert(v) for v in value]


def cmd_service(argv: list) -> int:
    """ros2 service list | call."""
    parser, sub, p_list = _parser_with_list_verb('ros2 service', 'services')
    p_call = sub.add_parser('call', help='Call a service')
    p_call.add_argument('service_name')
    p_call.add_argument('service_type', help="e.g. 'std_srvs/srv/Trigger'")
    p_call.add_argument('values', nargs='?', default='{}', help='request values in YAML, e.g. "{label: forward}"')
    _add_spin_time(p_list)
    args = parser.parse_args(argv)
    rclpy, node = _start_node('_ros2cli_service_%d' % os.getpid())
    try:
        if args.verb == 'list':
            _wait_for_graph(node, args.spin_time)
            own = f'/{node.get_name()}/'
            others = [(name, types) for name, types in node.get_service_names_and_types() if not name.startswith(own)]
            _print_names_and_types(others, args.show_types)
            return 0
        import yaml

        srv_class = _message_class(args.service_type)
        request = srv_class.Request()
        stamp_fields = []
        _set_fields(request, yaml.safe_load(args.values), stamp_fields)
        for stamp in stamp_fields:
            stamp(time.time_ns())
        client = node.create_client(srv_class, _resolve(args.service_name))
        if not client.service_is_ready():
            print('waiting for service to become available...')
            client.wait_for_service()
        print(f'requester: making request: {request!r}\n')
        future = client.call_async(request)
        rclpy.spin_until_future_complete(node, future)
        print(f'response:\n{future.result()!r}\n')
        return 0
    finally:
        _stop_node(rclpy, node)


VERBS = {'run': cmd_run, 'topic': cmd_topic, 'service': cmd_service, 'node': cmd_node, 'pkg': cmd_pkg}
GRAPH_VERBS = ('topic', 'service', 'node')  # the verbs that start a node; `run` execs, `pkg` reads files


def main() -> int:
    """Dispatch to the real ros2cli if installed, else to this command's verbs."""
    _hand_over_to_real_ros2cli()
    if len(sys.argv) < 2 or sys.argv[1] in ('-h', '--help') or sys.argv[1] not in VERBS:
        print(
            'usage: ros2 <command> [<args>]\n\nCommands (StylePong minimal ros2cli for PyPI wheels):\n'
            '  run    Run a package specific executable\n'
            '  topic  Various topic related sub-commands (list, echo, hz, info, pub)\n'
            '  service  Various service related sub-commands (list, call)\n'
            '  node   Various node related sub-commands (list)\n'
            '  pkg    Various package related sub-commands (list, prefix, executables)',
            file=sys.stderr if len(sys.argv) >= 2 and sys.argv[1] not in ('-h', '--help') else sys.stdout,
        )
        return 0 if len(sys.argv) >= 2 and sys.argv[1] in ('-h', '--help') else 2
    if sys.argv[1] not in GRAPH_VERBS:
        return VERBS[sys.argv[1]](sys.argv[2:])
    _stop_on_signals()
    return _run_graph_verb(VERBS[sys.argv[1]], sys.argv[2:])


def _run_graph_verb(verb, argv: list) -> int:
    """Run a verb that starts a node; a stop signal or a closed stdout ends it quietly with status 0."""
    try:
        return verb(argv)
    except _Stopped:
        return 0
    except BrokenPipeError:
        # `ros2 topic echo ... | head`: the reader has gone; let the interpreter's final flush go nowhere.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except Exception:
        # _Stopped raised while a C extension was calling back into Python (rclpy building a received
        # message) comes out as that extension's error instead: after a stop signal, any error is the stop.
        if _stop_signal is not None:
            return 0
        raise


if __name__ == '__main__':
    sys.exit(main())
