"""The player's logic without ROS: state machine, limits on every command, stale inputs, rejected messages,
phase-locked timing, and the numpy observation/decoding against the spec's torch ones."""

import math

import numpy as np
import pytest
import torch

from stylepong_player import player_core, spec
from stylepong_player.ball_prediction import predict_ball

PERIOD_S = 1.0 / spec.ACTION_RATE_HZ
HOME = np.asarray(spec.HOME_JOINT_POSITIONS_RAD)
NAMES = list(spec.JOINT_NAMES)
BALL_P = (-0.9, 0.1, 1.0)
BALL_V = (-5.0, 0.0, 0.5)


class WildActor:
    """An actor that answers anything: huge, alternating, occasionally non-finite or the wrong shape."""

    def __init__(self, seed: int = 0):
        self.rng = np.random.default_rng(seed)
        self.calls = 0
        self.observations = []

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        self.calls += 1
        self.observations.append(obs.copy())
        kind = self.calls % 7
        if kind == 3:
            return np.full((1, 6), np.nan, dtype=np.float32)
        if kind == 5:
            return np.zeros((1, 4), dtype=np.float32)
        return (self.rng.normal(0.0, 50.0, (1, 6)) * (-1) ** self.calls).astype(np.float32)


def make_core(actor=None, **config) -> player_core.Player:
    """A player; unless told otherwise without the stream, so that a step's command is the limiter's (the
    stream's own tests say stream_commands=True)."""
    config.setdefault('stream_commands', False)
    return player_core.Player(player_core.PlayerConfig(**config), actor or WildActor())


def check_commands(commands: list[np.ndarray], limits: player_core.JointLimits) -> None:
    """Six finite values within the position limits; per-period velocity and acceleration limits."""
    tol = 1e-9
    previous_velocity = np.zeros(6)
    for k, command in enumerate(commands):
        assert command.shape == (6,) and np.isfinite(command).all()
        assert (command >= limits.lower_rad - tol).all() and (command <= limits.upper_rad + tol).all()
        if k == 0:
            continue
        velocity = (command - commands[k - 1]) / PERIOD_S
        assert (np.abs(velocity) <= limits.velocity_rad_s + 1e-6).all(), (k, velocity)
        if k >= 2:
            acceleration = (velocity - previous_velocity) / PERIOD_S
            assert (np.abs(acceleration) <= limits.acceleration_rad_s2 * (1 + 1e-9) + 1e-6).all(), (k, acceleration)
        previous_velocity = velocity


def test_training_and_player_build_the_same_observation_from_random_inputs():
    """spec.build_observation on torch rows (the training env) and the player's numpy path agree exactly."""
    rng = np.random.default_rng(1)
    rows = 64
    q, qd = HOME + rng.normal(0, 1, (rows, 6)), rng.normal(0, 3, (rows, 6))
    ball_p, ball_v = rng.normal(0, 1, (rows, 3)), rng.normal(0, 5, (rows, 3))
    goal, last = rng.normal(0, 1, (rows, 2)), rng.uniform(-1, 1, (rows, 6))
    training = spec.build_observation(*(torch.from_numpy(a) for a in (q, qd, ball_p, ball_v, goal, last))).numpy()
    assert training.dtype == np.float32 and training.shape == (rows, spec.NUM_OBS)
    order = rng.permutation(6)
    names = [NAMES[i] for i in order]
    index = player_core.JointOrder().index(names)
    for i in range(rows):
        got = player_core.build_observation(
            q[i][order][index], qd[i][order][index], ball_p[i], ball_v[i], goal[i], last[i]
        )
        assert got.dtype == np.float32 and got.shape == (1, spec.NUM_OBS)
        np.testing.assert_array_equal(got[0], training[i])


def test_numpy_decoding_equals_the_torch_decoding():
    """The player decodes one numpy action at a time, training a batch of tensors: the same targets."""
    actions = np.random.default_rng(2).normal(0, 2, (200, 6)).astype(np.float32)
    expected = spec.decode_action(torch.from_numpy(actions)).numpy()
    got = np.stack([spec.decode_action(a) for a in actions])
    assert got.dtype == np.float32
    np.testing.assert_array_equal(got, expected)
    np.testing.assert_array_equal(spec.decode_action(actions), expected)


def test_state_machine_disabled_ready_playing_ready_disabled():
    core = make_core()
    t = 10.0
    core.on_joint_state(NAMES, HOME, np.zeros(6), t)
    assert core.step(t).command is None and core.state == player_core.State.DISABLED
    assert not core.ball_step_due(t) and not core.timer_step_due(t)
    core.set_enabled(True)
    assert core.state == player_core.State.READY and core.timer_step_due(t)
    result = core.step(t)
    np.testing.assert_allclose(result.command, HOME, atol=1e-12)  # already home: holds it
    assert core.at_home()
    # A ball arrives: it drives a policy step at once.
    t += 0.004
    core.on_joint_state(NAMES, HOME, np.zeros(6), t)
    assert core.on_ball('world', t, BALL_P, BALL_V, t) is None
    assert core.ball_step_due(t)
    result = core.step(t)
    assert result.state == player_core.State.PLAYING and result.policy
    # The ball goes (no message for ball_timeout_s): back to ready on the timer.
    t += core.config.ball_timeout_s + 0.01
    core.on_joint_state(NAMES, HOME, np.zeros(6), t)
    assert core.timer_step_due(t)
    result = core.step(t)
    assert result.state == player_core.State.READY and not result.policy and result.command is not None
    core.set_enabled(False)
    assert core.step(t).command is None and core.state == player_core.State.DISABLED


def test_playing_starts_with_a_zero_last_action_and_feeds_back_the_clipped_action():
    actor = WildActor()
    core = make_core(actor)
    core.set_enabled(True)
    t = 1.0
    for k in range(6):
        core.on_joint_state(NAMES, HOME, np.zeros(6), t)
        core.on_ball('world', t, BALL_P, BALL_V, t)
        if core.ball_step_due(t):
            core.step(t)
        t += PERIOD_S
    first, second = actor.observations[0][0], actor.observations[1][0]
    np.testing.assert_array_equal(first[-6:], np.zeros(6))
    assert np.abs(second[-6:]).max() <= 1.0 and np.abs(second[-6:]).max() == 1.0


@pytest.mark.parametrize('predict', [True, False])
def test_the_actor_sees_the_ball_carried_forward_to_the_step(predict):
    """A ball message stamped 30 ms before the step: with predict_ball the actor sees the ball where it is at
    the step, else where the message says it was."""
    actor = WildActor()
    core = make_core(actor, predict_ball=predict)
    core.set_enabled(True)
    t = 2.0
    core.on_joint_state(NAMES, HOME, np.zeros(6), t)
    assert core.on_ball('world', t - 0.03, BALL_P, BALL_V, t) is None
    core.step(t)
    position, velocity = predict_ball(BALL_P, BALL_V, 0.03) if predict else (BALL_P, BALL_V)
    expected = player_core.build_observation(
        HOME, np.zeros(6), np.asarray(position), np.asarray(velocity), core.goal_xy_m, np.zeros(6)
    )
    np.testing.assert_allclose(actor.observations[0], expected, atol=1e-6)
    assert not np.allclose(predict_ball(BALL_P, BALL_V, 0.03)[0], BALL_P, atol=0.05)  # the two differ


def test_every_command_is_within_the_limits_for_adversarial_inputs():
    rng = np.random.default_rng(3)
    core = make_core(WildActor(4))
    core.set_enabled(True)
    limits = core.limits
    commands, t = [], 5.0
    q = HOME.copy()
    for k in range(3000):
        t += PERIOD_S / 2
        if rng.random() < 0.3:  # joints jump by radians, within the URDF limits, or are garbage
            q = rng.uniform(limits.lower_rad, limits.upper_rad)
        bad_joint = rng.random() < 0.1
        joints = [np.nan] * 6 if bad_joint else q
        core.on_joint_state(NAMES, joints, rng.normal(0, 1, 6), t)
        ball = rng.normal(0, 3, 3) if rng.random() < 0.5 else np.array([np.inf, 0, 0])
        accepted = core.on_ball('world', t, ball, rng.normal(0, 5, 3), t) is None
        due = (accepted and core.ball_step_due(t)) or core.timer_step_due(t) or core.fallback_step_due(t)
        if due:
            result = core.step(t)
            if result.command is not None:
                commands.append(result.command)
    assert len(commands) > 500
    check_commands(commands, limits)
    assert core.counts['actor_output_rejected'] > 0


def test_the_stream_reaches_each_command_one_period_after_its_step_along_a_straight_path():
    core = make_core(lambda obs: np.full((1, 6), 0.3, dtype=np.float32), stream_commands=True)
    core.set_enabled(True)
    t = 1.0
    core.on_joint_state(NAMES, HOME, np.zeros(6), t)
    core.on_ball('world', t, BALL_P, BALL_V, t)
    np.testing.assert_allclose(core.step(t).command, HOME, atol=1e-12)  # the path starts where the arm is
    target = core.limiter.position_rad.copy()
    assert np.abs(target - HOME).max() > 1e-3
    core.on_joint_state(NAMES, HOME, np.zeros(6), t + PERIOD_S / 2)
    np.testing.assert_allclose(core.stream_command(t + PERIOD_S / 2), (HOME + target) / 2, atol=1e-12)
    core.on_joint_state(NAMES, HOME, np.zeros(6), t + PERIOD_S)
    np.testing.assert_allclose(core.stream_command(t + PERIOD_S), target, atol=1e-12)
    assert core.stream_command(t + 1.2 * PERIOD_S) is None  # its end was sent: nothing new to say
    # A command before the segment's end: from where the stream is, no faster than the velocity limits.
    stream = player_core.CommandStream(core.limits.velocity_rad_s, PERIOD_S)
    stream.start(HOME)
    stream.aim(HOME + 0.05, 0.0)
    halfway = stream.point(PERIOD_S / 2)
    stream.aim(HOME - 0.05, PERIOD_S / 2)
    np.testing.assert_allclose(stream.point(PERIOD_S / 2), halfway, atol=1e-12)
    duration_s = 0.075 / core.limits.velocity_rad_s.min()
    assert not stream.arrived(PERIOD_S / 2 + 0.99 * duration_s) and stream.arrived(PERIOD_S / 2 + duration_s)


def test_streamed_points_keep_the_limits_in_time_for_adversarial_inputs():
    """Points at joint-state times and at steps: within the position limits, and between any two the
    joints move no faster than the velocity limits (a pause longer than the joint timeout restarts)."""
    rng = np.random.default_rng(5)
    core = make_core(WildActor(6), stream_commands=True)
    core.set_enabled(True)
    limits = core.limits
    points, t, q = [], 5.0, HOME.copy()
    for k in range(6000):
        t += rng.uniform(0.0005, 0.004)
        if rng.random() < 0.05:
            q = rng.uniform(limits.lower_rad, limits.upper_rad)
        core.on_joint_state(NAMES, [np.nan] * 6 if rng.random() < 0.1 else q, rng.normal(0, 1, 6), t)
        ball = rng.normal(0, 3, 3) if rng.random() < 0.5 else np.array([np.inf, 0, 0])
        accepted = rng.random() < 0.3 and core.on_ball('world', t, ball, rng.normal(0, 5, 3), t) is None
        if (accepted and core.ball_step_due(t)) or core.timer_step_due(t) or core.fallback_step_due(t):
            point = core.step(t).command
        else:
            point = core.stream_command(t)
        if point is not None:
            points.append((t, point))
    assert len(points) > 2000
    for (t0, p0), (t1, p1) in zip(points, points[1:]):
        assert (p1 >= limits.lower_rad - 1e-9).all() and (p1 <= limits.upper_rad + 1e-9).all()
        if t1 - t0 < core.config.joint_timeout_periods * PERIOD_S:
            assert (np.abs(p1 - p0) <= limits.velocity_rad_s * (t1 - t0) + 1e-9).all(), (t0, t1)


def test_the_stream_says_nothing_while_disabled_or_with_stale_joint_states():
    core = make_core(stream_commands=True)
    core.set_enabled(True)
    core.on_joint_state(NAMES, HOME + 0.2, np.zeros(6), 0.0)
    core.step(0.0)
    assert core.stream_command(0.5 * PERIOD_S) is not None
    assert core.stream_command(3.5 * PERIOD_S) is None  # no joint state for over 3 periods
    core.on_joint_state(NAMES, HOME + 0.2, np.zeros(6), 3.6 * PERIOD_S)
    core.set_enabled(False)
    assert core.stream_command(3.7 * PERIOD_S) is None


@pytest.mark.parametrize('start', ['lower', 'upper'])
def test_limiter_brakes_before_position_limits_without_exceeding_the_acceleration(start):
    limits = player_core.JointLimits.for_commands(0.02, 1.0, [400.0] * 6)
    limiter = player_core.CommandLimiter(limits, PERIOD_S)
    limiter.start(limits.lower_rad + 0.5 if start == 'lower' else limits.upper_rad - 0.5)
    target = limits.upper_rad + 10 if start == 'lower' else limits.lower_rad - 10  # beyond the far limit
    commands = [limiter.position_rad.copy()] + [limiter.step(target) for _ in range(600)]
    check_commands(commands, limits)
    far = limits.upper_rad if start == 'lower' else limits.lower_rad
    np.testing.assert_allclose(commands[-1], far, atol=1e-9)  # it got there and stopped


def test_limiter_reaches_a_target_and_stops_there():
    limits = player_core.JointLimits.for_commands(0.02, 1.0, [400.0] * 6)
    limiter = player_core.CommandLimiter(limits, PERIOD_S)
    limiter.start(HOME)
    target = HOME + np.array([1.0, -0.7, 0.3, 1.2, -1.4, 0.05])
    commands = [limiter.step(target) for _ in range(120)]
    check_commands([HOME] + commands, limits)
    np.testing.assert_allclose(commands[-1], target, atol=1e-9)
    np.testing.assert_allclose(limiter.velocity_rad_s, 0.0, atol=1e-9)


def test_ready_moves_home_gently_and_arrives():
    core = make_core()
    core.set_enabled(True)
    q = HOME + np.array([0.8, -0.5, 0.4, 0.0, 0.3, -1.0])
    t, commands = 0.0, []
    for _ in range(400):
        core.on_joint_state(NAMES, q, np.zeros(6), t)
        result = core.step(t)
        commands.append(result.command)
        q = result.command  # a perfect servo
        t += PERIOD_S
    steps = np.abs(np.diff(np.array(commands), axis=0)) / PERIOD_S
    assert steps.max() <= core.config.home_speed_rad_s + 1e-9
    np.testing.assert_allclose(commands[-1], HOME, atol=1e-9)
    assert core.at_home()


def test_stale_joint_states_stop_commands_and_restart_from_the_measured_position():
    core = make_core()
    core.set_enabled(True)
    t = 0.0
    core.on_joint_state(NAMES, HOME, np.zeros(6), t)
    assert core.step(t).command is not None
    t += 3.5 * PERIOD_S  # no joint state for more than 3 periods
    result = core.step(t)
    assert result.command is None and 'stale' in result.problem
    moved = HOME + 0.3
    core.on_joint_state(NAMES, moved, np.zeros(6), t)
    command = core.step(t).command
    assert np.abs(command - moved).max() <= core.config.home_speed_rad_s * PERIOD_S + 1e-9


def test_joint_states_back_within_the_timeout_continue_the_commands():
    """Stale joints at one step, back at the next: the commands continue (no jump to where the joints say)."""
    core = make_core()
    core.set_enabled(True)
    core.on_joint_state(NAMES, HOME, np.zeros(6), 0.0)
    last = core.step(2.9 * PERIOD_S).command
    assert last is not None
    assert core.step(3.2 * PERIOD_S).command is None
    core.on_joint_state(NAMES, HOME + 0.3, np.zeros(6), 3.3 * PERIOD_S)
    command = core.step(3.4 * PERIOD_S).command
    assert np.abs(command - last).max() <= core.config.home_speed_rad_s * PERIOD_S + 1e-9


@pytest.mark.parametrize(
    'names, positions, velocities, kind',
    [
        (NAMES[:5], list(HOME[:5]), [0.0] * 5, 'joint_names'),
        (NAMES, list(HOME[:5]), [0.0] * 6, 'joint_length'),
        (NAMES, list(HOME), [], 'joint_length'),
        (NAMES, [math.nan] + list(HOME[1:]), [0.0] * 6, 'joint_not_finite'),
        (NAMES, list(HOME), [math.inf] + [0.0] * 5, 'joint_not_finite'),
        (NAMES, [0.0, 0.0, 4.0, 0.0, 0.0, 0.0], [0.0] * 6, 'joint_out_of_limits'),
        (NAMES, list(HOME), [100.0] + [0.0] * 5, 'joint_speed'),
    ],
)
def test_bad_joint_states_are_rejected(names, positions, velocities, kind):
    core = make_core()
    assert core.on_joint_state(names, positions, velocities, 1.0)
    assert core.rejected[kind] == 1 and not core.joints_fresh(1.0)


@pytest.mark.parametrize(
    'frame, stamp, position, velocity, kind',
    [
        ('base_link', 1.0, BALL_P, BALL_V, 'ball_frame'),
        ('world', 1.0, (math.nan, 0.0, 1.0), BALL_V, 'ball_not_finite'),
        ('world', 1.0, BALL_P, (0.0, math.inf, 0.0), 'ball_not_finite'),
        ('world', 1.0, (40.0, 0.0, 1.0), BALL_V, 'ball_outside_cell'),
        ('world', 1.0, BALL_P, (300.0, 0.0, 0.0), 'ball_speed'),
        ('world', 0.0, BALL_P, BALL_V, 'ball_stamp'),
        ('world', 0.5, BALL_P, BALL_V, 'ball_stamp'),  # 0.5 s old
        ('world', 1.5, BALL_P, BALL_V, 'ball_stamp'),  # from the future
    ],
)
def test_bad_ball_states_are_rejected_and_never_reach_the_actor(frame, stamp, position, velocity, kind):
    actor = WildActor()
    core = make_core(actor)
    core.set_enabled(True)
    core.on_joint_state(NAMES, HOME, np.zeros(6), 1.0)
    assert core.on_ball(frame, stamp, position, velocity, 1.0)
    assert core.rejected[kind] == 1
    assert not core.ball_step_due(1.0) and not core.ball_fresh(1.0)
    core.step(1.0)
    assert actor.calls == 0 and core.state == player_core.State.READY


def test_goal_messages_are_checked():
    core = make_core()
    assert core.on_goal('world', 0.5, 0.2) is None
    np.testing.assert_allclose(core.goal_xy_m, [0.5, 0.2])
    assert core.on_goal('base_link', 0.5, 0.2) and core.rejected['goal_frame'] == 1
    assert core.on_goal('world', -0.5, 0.2) and core.on_goal('world', math.nan, 0.0)
    assert core.rejected['goal_value'] == 2
    np.testing.assert_allclose(core.goal_xy_m, [0.5, 0.2])


def test_steps_are_phase_locked_to_every_second_frame_of_a_120_hz_camera():
    core = make_core(lambda obs: np.zeros((1, 6), dtype=np.float32))
    core.set_enabled(True)
    t, stepped = 2.0, []
    for k in range(240):
        t = 2.0 + k / 120.0
        core.on_joint_state(NAMES, HOME, np.zeros(6), t)
        if core.on_ball('world', t, BALL_P, BALL_V, t + 0.0003) is None and core.ball_step_due(t + 0.0003):
            core.step(t + 0.0003)
            stepped.append(k)
    assert np.all(np.diff(stepped) == 2)
    np.testing.assert_allclose(np.fromiter(core.period.values, float), PERIOD_S, atol=1e-6)


def _play(core, frame_times_s, joint_rate_hz=500.0):
    """Joint states at joint_rate_hz and ball messages arriving at frame_times_s, stepping as the node does
    (a ball that is due, else the fallback on a joint state); the step times."""
    events = sorted(
        [(t, 1, 'ball') for t in frame_times_s]  # at equal times the joint state first
        + [
            (frame_times_s[0] + k / joint_rate_hz, 0, 'joint')
            for k in range(int((frame_times_s[-1] - frame_times_s[0]) * joint_rate_hz) + 1)
        ]
    )
    steps = []
    for t, _, kind in events:
        if kind == 'joint':
            core.on_joint_state(NAMES, HOME, np.zeros(6), t)
            due = core.fallback_step_due(t)
        else:
            due = core.on_ball('world', t - 0.02, BALL_P, BALL_V, t) is None and core.ball_step_due(t)
        if due:
            core.step(t)
            steps.append(t)
    return np.array(steps)


def test_a_lost_frame_costs_one_late_step_and_a_burst_does_not_speed_the_loop_up():
    core = make_core(lambda obs: np.zeros((1, 6), dtype=np.float32))
    core.set_enabled(True)
    frames = [3.0 + k / 120.0 for k in range(40) if k != 10]  # one lost camera frame
    steps = _play(core, frames)
    gaps_ms = np.diff(steps) * 1e3
    late = gaps_ms > PERIOD_S * 1e3 + 0.5
    assert late.sum() == 1 and gaps_ms[late][0] <= (1.0 + player_core.STEP_TOLERANCE_PERIODS) * PERIOD_S * 1e3 + 2.0
    np.testing.assert_allclose(steps[-1] - steps[0], (len(steps) - 1) * PERIOD_S, atol=1e-3)
    # A 1 kHz burst of (valid, increasing) stamps after a pause: a ready step, then one step per period.
    steps = _play(core, [4.0 + k * 0.001 for k in range(200)])
    assert len(steps) <= 1 + 0.2 / PERIOD_S + 1
    assert np.diff(steps[1:]).min() >= (1 - 2 * player_core.STEP_TOLERANCE_PERIODS) * PERIOD_S


def test_steps_keep_60_hz_behind_a_150_hz_tracker_whose_frames_arrive_with_jitter():
    core = make_core(lambda obs: np.zeros((1, 6), dtype=np.float32))
    core.set_enabled(True)
    rng = np.random.default_rng(0)
    frames = np.sort(5.0 + np.arange(300) / 150.0 + rng.uniform(-0.005, 0.005, 300))
    steps = _play(core, list(frames))
    gaps_s = np.diff(steps)
    assert abs(gaps_s.mean() - PERIOD_S) < 1e-4
    # Within the tolerance and the 2 ms between joint states of a period, never two or three frames apart.
    assert np.abs(gaps_s - PERIOD_S).max() <= (2 * player_core.STEP_TOLERANCE_PERIODS) * PERIOD_S + 0.002


def test_fallback_steps_on_the_latest_ball_when_frames_stop():
    core = make_core(lambda obs: np.zeros((1, 6), dtype=np.float32))
    core.set_enabled(True)
    core.on_joint_state(NAMES, HOME, np.zeros(6), 1.0)
    core.on_ball('world', 1.0, BALL_P, BALL_V, 1.0)
    core.step(1.0)
    t = 1.0 + (1.0 + player_core.STEP_TOLERANCE_PERIODS - 0.01) * PERIOD_S
    assert not core.fallback_step_due(t)
    t = 1.0 + (1.0 + player_core.STEP_TOLERANCE_PERIODS + 0.01) * PERIOD_S
    core.on_joint_state(NAMES, HOME, np.zeros(6), t)
    assert core.fallback_step_due(t) and core.step(t).policy


def test_config_refuses_another_rate_and_a_goal_off_the_table():
    with pytest.raises(ValueError, match='rate_hz'):
        player_core.PlayerConfig(rate_hz=50.0).validate()
    with pytest.raises(ValueError, match="opponent's half"):
        player_core.PlayerConfig(goal_xy_m=(-0.5, 0.0)).validate()
