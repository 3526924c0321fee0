"""System tests of the PyBullet cell through ROS: `ros2 run stylepong_sim ur5_bullet` (= ur5_sim with
engine pybullet) serves ur5_sim's topics and services, its referee judges a ball from Bullet's contacts, a
bad engine or actuator is refused at start with one line and exit code 2, a player started on wall time
against it says in one line to set use_sim_time, and rally_eval stops on Ctrl-C or SIGTERM with one line."""

import signal
import subprocess
import time

import numpy as np
import pytest

from stylepong_common.exit_codes import EXIT_CONFIG_ERROR, EXIT_INTERRUPTED
from stylepong_common.node_process import NodeProcess
from stylepong_msgs.msg import RallyEvent
from stylepong_sim import world_spec
from stylepong_sim.testing.ur5_sim_probe import Ur5SimProbe


@pytest.mark.parametrize(
    'executable, param, value',
    [('ur5_sim', 'engine', 'bullet'), ('ur5_bullet', 'actuator', 'servoj'), ('ur5_sim', 'actuator', 'ur-servoj')],
)
def test_a_bad_engine_or_actuator_is_refused_in_one_line(ros_env, executable, param, value):
    result = subprocess.run(
        ['ros2', 'run', 'stylepong_sim', executable, '--ros-args', '-p', f'{param}:={value}'],
        capture_output=True,
        text=True,
        timeout=60,
        env=ros_env,
    )
    assert result.returncode == EXIT_CONFIG_ERROR, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and f'parameter {param} must be one of' in lines[0], result.stderr
    assert result.stdout == ''


def test_ur5_bullet_serves_the_cells_topics_and_judges_a_ball(ros_env):
    params = {'real_time_factor': 0.0, 'actuator': 'ur_servoj', 'servo_rate_hz': 125.0}
    with (
        NodeProcess('stylepong_sim', 'ur5_bullet', params=params) as node,
        NodeProcess('stylepong_player', 'player', params={'use_sim_time': False}) as player,
    ):
        probe = Ur5SimProbe()
        try:
            assert probe.wait_for_sim(60.0), node.output()
            assert probe.joint_names and probe.latest_joint_positions() == pytest.approx(
                np.array(world_spec.HOME_JOINT_POSITIONS_RAD), abs=2e-3
            )
            response = probe.launch(randomize=True, seed=1002)
            assert response.success, response.message
            assert probe.spin_until(lambda: any(e.type == RallyEvent.RALLY_END for e in probe.events), 60.0)
            types = [e.type for e in probe.events if e.ball_id == response.ball_id]
            assert types[0] == RallyEvent.LAUNCHED and RallyEvent.BOUNCE_OWN_SIDE in types
            assert probe.balls and probe.wrenches and probe.clock
            # The ur5_sim logs say which engine and actuator run.
            assert 'UR5 cell ready (pybullet, actuator ur_servoj)' in node.output()
            # The player on wall time hears /clock and says, once, what to set.
            assert probe.spin_until(lambda: 'use_sim_time:=true' in player.output(), 30.0), player.output()
            assert player.output().count('use_sim_time:=true') == 1
        finally:
            probe.close()
        assert node.stop(timeout_s=20.0) == 0


@pytest.mark.parametrize('signum', [signal.SIGINT, signal.SIGTERM])
def test_rally_eval_stops_quietly_on_a_signal(ros_env, signum):
    # No cell: rally_eval is waiting for /sim/launch_ball while its executor spins.
    process = subprocess.Popen(
        ['ros2', 'run', 'stylepong_sim', 'rally_eval', '--balls', '1', '--seeds', '1'],
        env=ros_env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    time.sleep(3.0)
    process.send_signal(signum)
    _, stderr = process.communicate(timeout=20)
    assert process.returncode == EXIT_INTERRUPTED, stderr
    assert stderr.strip() == 'rally_eval: interrupted', stderr
