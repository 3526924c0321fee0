"""drag_teach against the MuJoCo cell: `ros2 run stylepong_sim ur5_sim` + `ros2 run stylepong_fdcc drag_teach`,
both with their defaults, driven and watched through their topics (the first three drag_teach checks of
docs/ACCEPTANCE.md), then its services (enable, tare) and, with stiffness, a target pose
on ~/target_pose."""

import math
import subprocess
import sys
import threading
import time

import numpy as np
import pinocchio as pin
import pytest
import rclpy
from geometry_msgs.msg import PoseStamped, WrenchStamped
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from std_srvs.srv import SetBool, Trigger

from stylepong_common.node_process import NodeProcess, wait_until
from stylepong_description import robot_model
from stylepong_sim.teaching.teacher import CellKinematics

CONTROL_RATE_HZ = 500.0  # drag_teach's default
LIMITS = robot_model.joint_limits()
KIN = CellKinematics()
TOOL = KIN.frame_id(robot_model.TOOL_FRAME)


class CellProbe:
    """Watches /joint_states and the commands, pushes through /sim/hand_wrench."""

    def __init__(self):
        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node('drag_teach_probe', context=self.context)
        self.lock = threading.Lock()
        self.joints: list[tuple[float, np.ndarray, np.ndarray]] = []
        self.commands: list[tuple[float, np.ndarray]] = []
        self.node.create_subscription(JointState, '/joint_states', self._on_joints, qos_profile_sensor_data)
        self.node.create_subscription(Float64MultiArray, '/forward_position_controller/commands', self._on_command, 100)
        self.hand = self.node.create_publisher(WrenchStamped, '/sim/hand_wrench', 10)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.thread = threading.Thread(target=self._spin, daemon=True)
        self.thread.start()

    def _spin(self):
        while self.context.ok():
            try:
                self.executor.spin_once(timeout_sec=0.05)
            except Exception:  # noqa: BLE001 - shutting down
                return

    def _on_joints(self, msg: JointState):
        index = [list(msg.name).index(n) for n in robot_model.JOINT_NAMES]
        with self.lock:
            self.joints.append((time.monotonic(), np.array(msg.position)[index], np.array(msg.velocity)[index]))

    def _on_command(self, msg: Float64MultiArray):
        with self.lock:
            self.commands.append((time.monotonic(), np.array(msg.data)))

    def latest_q(self) -> np.ndarray:
        with self.lock:
            return self.joints[-1][1].copy()

    def joints_between(self, start: float, end: float):
        with self.lock:
            return [(t, q, v) for t, q, v in self.joints if start <= t <= end]

    def commands_between(self, start: float, end: float):
        with self.lock:
            return [(t, c) for t, c in self.commands if start <= t <= end]

    def commanding(self) -> bool:
        with self.lock:
            return len(self.commands) > 50 and len(self.joints) > 50

    def push(self, force_world_n, duration_s: float, rate_hz: float = 200.0) -> tuple[float, float]:
        """A constant force at the tool (world axes) for duration_s, then a zero wrench. Returns (start, end)."""
        msg = WrenchStamped()
        msg.header.frame_id = 'world'
        start = time.monotonic()
        while time.monotonic() - start < duration_s:
            msg.wrench.force.x, msg.wrench.force.y, msg.wrench.force.z = (float(f) for f in force_world_n)
            self.hand.publish(msg)
            time.sleep(1.0 / rate_hz)
        end = time.monotonic()
        msg.wrench.force.x = msg.wrench.force.y = msg.wrench.force.z = 0.0
        for _ in range(5):
            self.hand.publish(msg)
            time.sleep(0.01)
        return start, end

    def close(self):
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)
        self.thread.join(timeout=2.0)


def tool_position(q: np.ndarray) -> np.ndarray:
    return KIN.pose(q, TOOL).translation.copy()


@pytest.fixture(scope='module')
def cell(module_ros_domain):
    """ur5_sim and drag_teach (defaults) in a ROS domain of their own, and a probe; shared by the tests below."""
    sim = NodeProcess('stylepong_sim', 'ur5_sim').start()
    drag = NodeProcess('stylepong_fdcc', 'drag_teach').start()
    probe = CellProbe()
    try:
        if not wait_until(probe.commanding, 60.0):
            pytest.fail('drag_teach never commanded the arm:\n' + sim.output()[-2000:] + drag.output()[-2000:])
        time.sleep(1.0)
        yield probe, sim, drag
    finally:
        probe.close()
        drag.stop()
        sim.stop()


@pytest.mark.slow  # over 10 s on the 2-core machine: .ci/run runs it, `make test` skips it
def test_without_a_push_no_joint_moves_for_10_s(cell):
    probe, _, drag = cell
    start_q = probe.latest_q()
    start = time.monotonic()
    time.sleep(10.0)
    samples = probe.joints_between(start, time.monotonic())
    assert len(samples) > 1000, 'joint states stopped'
    drift = np.max(np.abs(np.array([q for _, q, _ in samples]) - start_q), axis=0)
    assert np.all(drift < 1e-3), f'joints moved {drift} rad without a push'
    assert drag.running()


def test_a_10_n_push_along_x_moves_the_tool_along_x_and_it_stays_where_it_was_left(cell):
    probe, _, _ = cell
    before = tool_position(probe.latest_q())
    _, push_end = probe.push([10.0, 0.0, 0.0], 1.0)
    time.sleep(2.0)
    at_rest = push_end + 2.0
    recent = probe.joints_between(at_rest - 0.1, at_rest + 0.05)
    assert recent, 'no joint states after the push'
    speeds = np.max(np.abs(np.array([v for _, _, v in recent])))
    assert speeds < 0.05, f'joints still moving at {speeds:.3f} rad/s 2 s after the push'
    left_at = tool_position(recent[-1][1])
    displacement = left_at - before
    distance = float(np.linalg.norm(displacement))
    print(
        f'a 10 N push for 1 s moved the tool {distance * 100:.1f} cm, direction {np.round(displacement / distance, 4)}'
    )
    # About 0.3 m (stylepong_fdcc.fdcc_solver: 0.29-0.33 m): the push's impulse over the default damping,
    # 10 N s / 30 N s/m = 0.333 m, less what the cell's transport delays take (measured here: 0.295 m).
    impulse_over_damping_m = 10.0 * 1.0 / 30.0
    assert 0.8 * impulse_over_damping_m <= distance <= 1.05 * impulse_over_damping_m, (
        f'the tool moved {distance * 100:.1f} cm, not about {impulse_over_damping_m * 100:.0f} cm'
    )
    assert displacement[0] / distance >= 0.9, f'the tool moved along {displacement / distance}'
    time.sleep(3.0)
    after = probe.joints_between(recent[-1][0], time.monotonic())
    wander = max(np.linalg.norm(tool_position(q) - left_at) for _, q, _ in after[::10])
    assert wander < 0.01, f'the tool moved {wander * 100:.1f} cm after coming to rest (spring-back)'


# A separate process floods the sensor topic, so that this test's own listener keeps its share of the CPU.
FLOODER = """
import math, sys, time
import rclpy
import pinocchio as pin
from geometry_msgs.msg import PoseStamped, WrenchStamped
GARBAGE = ([math.nan] * 6, [math.inf, 0, 0, 0, 0, 0], [0, 0, 0, 0, -math.inf, 0], [1e6, 0, 0, 0, 0, 0],
           [0, -1e6, 0, 0, 0, 0], [0, 0, 1e6, 0, 0, 1e6], [-1e6, 1e6, -1e6, 0, 0, 0], [0, 0, 0, 1e6, -1e6, 0],
           [1.0, math.nan, 2.0, 0, 0, 0])
rclpy.init()
node = rclpy.create_node('wrench_flooder')
pub = node.create_publisher(WrenchStamped, '/force_torque_sensor_broadcaster/wrench', 10)
time.sleep(1.0)   # discovery
msg = WrenchStamped()
msg.header.frame_id = 'tool0'
start, sent = time.monotonic(), 0
print('start', time.monotonic(), flush=True)
while time.monotonic() - start < float(sys.argv[1]):
    w = GARBAGE[sent % len(GARBAGE)]
    (msg.wrench.force.x, msg.wrench.force.y, msg.wrench.force.z,
     msg.wrench.torque.x, msg.wrench.torque.y, msg.wrench.torque.z) = (float(v) for v in w)
    pub.publish(msg)
    sent += 1
    if sent % 2 == 0:   # about 2000 a second: a flood, four times the sensor's own rate
        time.sleep(0.001)
print('end', time.monotonic(), sent, flush=True)
"""


@pytest.mark.slow  # over 7 s on the 2-core machine: .ci/run runs it, `make test` skips it
def test_a_flood_of_nan_inf_and_huge_wrenches_never_makes_a_bad_command(cell):
    probe, _, drag = cell
    flood = subprocess.run([sys.executable, '-c', FLOODER, '5.0'], capture_output=True, text=True, timeout=60)
    assert flood.returncode == 0, flood.stderr
    lines = dict(line.split(' ', 1) for line in flood.stdout.splitlines())
    start = float(lines['start'])
    end, sent = (float(v) for v in lines['end'].split())
    assert sent > 2500, f'only {sent:.0f} garbage wrenches were sent'
    commands = probe.commands_between(start, end)
    times = np.array([t for t, _ in commands])
    q = np.array([c for _, c in commands])
    assert drag.running()
    # Keeps publishing: commands all through the flood (rates on this shared 2-core machine vary too
    # much under a flood to ask for 500 Hz here; the benchmark measures the rate).
    assert len(commands) > 0.1 * CONTROL_RATE_HZ * (end - start), (
        f'only {len(commands)} commands in {end - start:.1f} s'
    )
    assert np.max(np.diff(np.concatenate([[start], times, [end]]))) < 1.0, 'drag_teach stopped publishing'
    assert np.all(np.isfinite(q))
    assert np.all(q >= LIMITS.lower_rad) and np.all(q <= LIMITS.upper_rad)
    implied_speed = np.abs(np.diff(q, axis=0)) * CONTROL_RATE_HZ  # per control period
    assert np.all(implied_speed <= 1.1 * LIMITS.velocity_rad_s), implied_speed.max(axis=0)
    # Still there afterwards, and it said why it ignored those wrenches.
    count = len(probe.commands_between(0.0, time.monotonic()))
    assert wait_until(lambda: len(probe.commands_between(0.0, time.monotonic())) > count + 50, 5.0)
    assert 'wrench rejected' in drag.output()


def test_disabled_it_publishes_nothing_enabled_it_resumes_where_the_arm_is_and_it_tares(cell):
    probe, _, _ = cell
    node = probe.node
    enable = node.create_client(SetBool, '/drag_teach/enable')
    tare = node.create_client(Trigger, '/drag_teach/tare')
    assert enable.wait_for_service(10.0) and tare.wait_for_service(10.0)

    def call(client, request):
        future = client.call_async(request)
        assert wait_until(future.done, 10.0)
        return future.result()

    assert call(enable, SetBool.Request(data=False)).success
    time.sleep(0.3)  # commands already on their way
    quiet_from = time.monotonic()
    time.sleep(1.0)
    assert not probe.commands_between(quiet_from, time.monotonic()), 'commands while disabled'
    held = probe.latest_q()
    assert call(enable, SetBool.Request(data=True)).success
    assert wait_until(lambda: len(probe.commands_between(quiet_from + 1.0, time.monotonic())) > 20, 5.0)
    first = probe.commands_between(quiet_from + 1.0, time.monotonic())[0][1]
    assert np.max(np.abs(first - held)) < 1e-3  # re-synchronised with the arm: no jump
    response = call(tare, Trigger.Request())
    assert response.success and 'bias force' in response.message


def test_with_stiffness_it_is_a_compliance_controller_around_the_target_pose(ros_env):
    stiffness = [300.0, 300.0, 300.0, 30.0, 30.0, 30.0]
    sim = NodeProcess('stylepong_sim', 'ur5_sim').start()
    drag = NodeProcess('stylepong_fdcc', 'drag_teach', params={'stiffness': stiffness}).start()
    probe = CellProbe()
    try:
        assert wait_until(probe.commanding, 60.0), drag.output()[-2000:]
        time.sleep(0.5)
        start = KIN.base.actInv(KIN.pose(probe.latest_q(), TOOL))  # tool0 in base_link
        target = start.translation + np.array([0.05, -0.03, 0.04])
        publisher = probe.node.create_publisher(PoseStamped, '/drag_teach/target_pose', 10)
        msg = PoseStamped()
        msg.header.frame_id = robot_model.BASE_FRAME
        msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = (float(v) for v in target)
        x, y, z, w = pin.Quaternion(start.rotation).coeffs()
        msg.pose.orientation.x, msg.pose.orientation.y, msg.pose.orientation.z, msg.pose.orientation.w = x, y, z, w
        assert wait_until(lambda: publisher.get_subscription_count() > 0, 10.0)
        # The target is sent again every 0.5 s, as a user's tool streams it. Sent once, it was not reached
        # within the 10 s once in a full run of the suite and was in every rerun: a message published as
        # soon as the publisher sees the subscription can be lost while discovery completes, and the
        # test is about the compliance, not about one message's delivery.
        last_sent = [-math.inf]

        def at_target() -> bool:
            if time.monotonic() - last_sent[0] > 0.5:
                publisher.publish(msg)
                last_sent[0] = time.monotonic()
            reached = KIN.base.actInv(KIN.pose(probe.latest_q(), TOOL))
            return np.linalg.norm(reached.translation - target) < 0.005

        assert wait_until(at_target, 10.0), 'the tool never reached the target pose'
    finally:
        probe.close()
        drag.stop()
        sim.stop()
