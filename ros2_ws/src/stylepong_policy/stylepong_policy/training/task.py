"""The table-tennis task: the batched world (stylepong_sim.batched.batched_world) as an RL environment.

Where things live: the world (physics, robot, referee) is a simulator of the cell and sits with the
cell in stylepong_sim; what makes it a learning problem (observations through stylepong_player.spec,
rewards, goals, domain randomisation, sensing noise and latency, resets) is here, beside PPO.

One episode = one incoming ball, from its launch (world_spec's distribution, vectorised) until the
referee's verdict; the environment then resets itself (new ball, new goal, new randomisation, arm near
home). It follows the batched-env contract of stylepong_policy.rl.env (see TableTennisEnv.step); the
ball outcomes are counted here, once, and reach the runner through the contract's log and `evaluate`
through the per-ball 'outcome' extras.

Rewards (per 60 Hz step; the paper's terms, its exponentials given the minus signs they lack):
  before the hit   bat    w_bat  exp(-d(paddle, ball) / sigma_bat)       (d over `bat_axes`: the paper
                                                                          uses y only; default y and z)
  the hit          hit    w_hit  once, when the paddle first touches the ball
                   aim    w_aim  exp(-|predicted landing - goal| / sigma_aim), once, at the hit, gated
                          softly on the drag-free flight from the ball's new state clearing the net (the
                          landing point to goal, credited to the stroke that sets it)
  after the hit    goal   w_goal exp(-|ball - goal| / sigma_goal)        (every step until the verdict)
  verdict          land   w_land exp(-|landing point - goal| / sigma_land) for a returned ball
                   success  w_success for a returned ball
                   illegal  -w_illegal for robot contact, the robot touching the table, a double hit
  regularisation   acc    w_acc (exp(-|qddot| / sigma_acc) - 1)         (in [-w, 0]: the penalties
                   dof    w_dof (exp(-|q - home| / sigma_dof) - 1)        only ever lower the reward)
                   rate   w_rate (exp(-|a_t - a_t-1| / sigma_rate) - 1)
                   action -w_action max|a_t|
                   command  -w_command when the commanded joint positions put the arm below the table top
                          (a stiff drive would take it there; the PD's lag hides it). 0 by default: no cost.
  r = the sum of the above: the task reward. The style reward of the motion prior is added by the
  trainer (stylepong_policy.rl.amp), from the arm states this env reports as its style frames.
Goal: the centre of a 0.25 m region drawn uniformly so that the region lies on the opponent's half,
resampled at every reset. Success (the referee's 'returned') does not need the goal.

Domain randomisation (`randomize`, per episode): table, paddle restitution and tangential factors
(world_spec ranges), drag (air density and drag coefficient), gravity, the servo's Kp and Kd, the
sensing noise level (0 to the maximum stds), the ball and joint observation delays and the action
delay. With randomize=False everything is nominal and noiseless (the evaluation protocol).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, fields

import torch

from stylepong_player import spec
from stylepong_policy.evaluation import strokes
from stylepong_policy.rl import env as env_contract
from stylepong_sim import referee, world_spec
from stylepong_sim.batched import batched_launcher, batched_world

FAILURE_REASONS: tuple[str, ...] = referee.REASONS
SUCCESS_INDEX = referee.REASON_INDEX[referee.REASON_RETURNED]
ILLEGAL_REASONS = (referee.REASON_ROBOT_CONTACT, referee.REASON_TABLE_CONTACT_BY_ROBOT, referee.REASON_DOUBLE_HIT)
ARM_STATE_SIZE = 2 * spec.NUM_ACTIONS
# The slowest approach the style clock divides by: a ball this slow along x is about to be decided anyway.
MIN_APPROACH_SPEED_M_S = 0.5
REWARD_TERMS = ('bat', 'hit', 'aim', 'goal', 'land', 'success', 'illegal', 'acc', 'dof', 'rate', 'action', 'command')


@dataclass
class TaskConfig:
    """Every parameter of the environment, its randomisation and its reward (YAML: the `task` section)."""

    num_envs: int = 1024  # config/ppo.yaml's (the source; see rl.config)
    speed_range_m_s: tuple[float, float] = tuple(world_spec.SPEED_RANGES_M_S['all'])
    randomize: bool = True
    # World
    physics_rate_hz: float = batched_world.PHYSICS_RATE_HZ
    arm_substeps: int = batched_world.ARM_SUBSTEPS
    cpu_threads: int = 1  # torch threads while the env steps (0: leave as set)
    compile_world: bool = False  # torch.compile the world's stages (3x faster, ~1 min start)
    episode_length_s: float = world_spec.BALL_TIMEOUT_S  # the referee's timeout ends every episode by then
    reset_joint_noise_rad: float = 0.05  # arm start: home + uniform noise (randomize only)
    goal_radius_m: float = world_spec.GOAL_RADIUS_M
    # Sensing noise: maximum standard deviations; each episode draws a level in [0, 1] times these.
    noise_joint_position_rad: float = 0.003
    noise_joint_velocity_rad_s: float = 0.03
    noise_ball_position_m: float = 0.01
    noise_ball_velocity_m_s: float = 0.15
    # Latencies, drawn uniformly per episode in [0, max].
    max_ball_delay_s: float = 0.025  # camera tracking
    max_joint_delay_s: float = 0.008  # joint state
    max_action_delay_s: float = 1.0 / 60.0  # command to servo (whole physics steps)
    # Physics randomisation ranges.
    table_restitution_range: tuple[float, float] = tuple(world_spec.TABLE_RESTITUTION_RANGE)
    table_tangential_range: tuple[float, float] = tuple(world_spec.TABLE_TANGENTIAL_FACTOR_RANGE)
    paddle_restitution_range: tuple[float, float] = tuple(world_spec.PADDLE_RESTITUTION_RANGE)
    paddle_tangential_range: tuple[float, float] = (0.70, 0.80)
    drag_scale_range: tuple[float, float] = (0.95, 1.05)
    gravity_range_m_s2: tuple[float, float] = (9.76, 9.86)
    kp_scale_range: tuple[float, float] = (0.8, 1.2)
    kd_scale_range: tuple[float, float] = (0.8, 1.2)
    # The joint drive, from the cells' PD (0) to a stiff velocity motor (1: Bullet's, a UR's own joint
    # control; batched_world.PhysicsParams.velocity_drive): an actor trained on one drive alone returned
    # 56 of 100 balls behind Bullet's motors against 90 behind MuJoCo's PD (docs/DESIGN.md, Known limits).
    velocity_drive_range: tuple[float, float] = (0.0, 0.0)
    armature_scale_range: tuple[float, float] = (1.0, 1.0)  # of world_spec's rotor inertia
    # Reward weights and scales.
    w_bat: float = 0.1
    sigma_bat_m: float = 0.3
    bat_axes: str = 'yz'  # which of x, y, z the paddle-ball distance uses
    w_hit: float = 2.0
    w_aim: float = 3.0
    sigma_aim_m: float = 0.7
    w_goal: float = 0.5
    sigma_goal_m: float = 1.0
    w_land: float = 3.0
    sigma_land_m: float = 0.5
    w_success: float = 5.0
    w_illegal: float = 2.0
    w_acc: float = 0.02
    sigma_acc_rad_s2: float = 200.0
    w_dof: float = 0.02
    sigma_dof_rad: float = 1.0
    w_rate: float = 0.02
    sigma_rate: float = 0.5
    w_action: float = 0.01
    w_command: float = 0.0
    # A factor on the motion prior's style weight from the paddle's first touch of the ball, where no task
    # term pays for how the arm moves (1: the same weight throughout; PPO ignores it). It lasts
    # style_weight_after_hit_s (0.3 s: the follow-through evaluate's strokes include), or to the verdict
    # when that is 0; then above 1 it pays for a longer flight, and at 5 the policy learned to lob and lost
    # returns (docs/DESIGN.md, Known limits).
    style_weight_after_hit: float = 1.0
    style_weight_after_hit_s: float = 0.0

    def __post_init__(self):
        for f in fields(self):
            value = getattr(self, f.name)
            if isinstance(value, list):
                setattr(self, f.name, tuple(float(v) for v in value))
        self.validate()

    def validate(self) -> None:
        if self.num_envs < 1:
            raise ValueError(f'num_envs must be at least 1, got {self.num_envs}')
        lo, hi = self.speed_range_m_s
        if not 0.0 < lo <= hi:
            raise ValueError(f'speed_range_m_s must be (low, high) with 0 < low <= high, got {self.speed_range_m_s}')
        for f in fields(self):
            if f.name.endswith('_range') or f.name.endswith('_range_m_s2'):
                a, b = getattr(self, f.name)
                if not a <= b:
                    raise ValueError(f'{f.name} must be (low, high), got {(a, b)}')
        if not set(self.bat_axes) <= set('xyz') or not self.bat_axes:
            raise ValueError(f"bat_axes must be letters of 'xyz', got {self.bat_axes!r}")
        for name in (
            'max_ball_delay_s',
            'max_joint_delay_s',
            'max_action_delay_s',
            'style_weight_after_hit',
            'style_weight_after_hit_s',
        ):
            if getattr(self, name) < 0.0:
                raise ValueError(f'{name} must not be negative')

    def as_dict(self) -> dict:
        return asdict(self)


PRIVILEGED_LAYOUT: tuple[tuple[str, int], ...] = (
    ('true_joint_position_offset_rad', 6),
    ('true_joint_velocity_rad_s', 6),
    ('true_ball_position_m', 3),
    ('true_ball_velocity_m_s', 3),
    ('paddle_position_m', 3),
    ('paddle_normal', 3),
    ('ball_hit', 1),
    ('own_bounces', 1),
    ('time_since_launch_s', 1),
    ('physics', 8),
    ('noise_std', 4),
    ('delays_s', 3),
)


@dataclass
class _Episode:
    """Per-environment quantities drawn at each reset ([N] unless noted)."""

    goal_xy_m: torch.Tensor  # [N, 2]
    noise_std: torch.Tensor  # [N, 4]: joint pos, joint vel, ball pos, ball vel
    ball_delay_steps: torch.Tensor  # in policy steps (fractional)
    joint_delay_steps: torch.Tensor
    action_delay_physics_steps: torch.Tensor  # long
    direction: torch.Tensor  # long: index into strokes.DIRECTIONS of the stroke the ball asks for
    reward_sums: dict = field(default_factory=dict)


def launch_directions(
    position_m: torch.Tensor, velocity_m_s: torch.Tensor, plane_x_m: float, paddle_home_y_m: float
) -> torch.Tensor:
    """Index into strokes.DIRECTIONS [K] of balls launched at position_m, velocity_m_s [3, K]: where they
    will cross the paddle's home plane (x = plane_x_m), by strokes.direction_of's thresholds. In this world
    a ball's heading over the table never turns (drag acts along the velocity, no spin) and a bounce scales
    both horizontal components alike, so the crossing lies on the launch heading: the label `evaluate`
    gives the ball afterwards, known from its launch."""
    arrival_y_m = position_m[1] + (plane_x_m - position_m[0]) * velocity_m_s[1] / velocity_m_s[0]
    offset_m = arrival_y_m - paddle_home_y_m
    index = strokes.DIRECTIONS.index
    return torch.where(
        offset_m > strokes.LEFTWARD_ABOVE_M,
        index('leftward'),
        torch.where(offset_m < strokes.RIGHTWARD_BELOW_M, index('rightward'), index('forward')),
    )


class TableTennisEnv:
    """N table-tennis episodes in parallel (see the module docstring)."""

    HISTORY = 3  # policy steps of sensed state kept for the observation delays

    def __init__(self, cfg: TaskConfig, device: str | torch.device = 'cpu', seed: int = 0):
        self.cfg = cfg
        self.device = torch.device(device)
        self.num_envs = int(cfg.num_envs)
        self.num_actions = spec.NUM_ACTIONS
        self.num_obs = spec.NUM_OBS
        self.num_critic_obs = spec.NUM_OBS + sum(size for _, size in PRIVILEGED_LAYOUT)
        threads = int(cfg.cpu_threads) if cfg.cpu_threads > 0 and self.device.type == 'cpu' else None
        self.world = batched_world.BatchedWorld(
            self.num_envs,
            self.device,
            physics_rate_hz=cfg.physics_rate_hz,
            arm_substeps=cfg.arm_substeps,
            timeout_s=cfg.episode_length_s,
            cpu_threads=None,
            compile=cfg.compile_world,
            velocity_drive=max(cfg.velocity_drive_range) > 0.0,
        )
        self.cpu_threads = threads
        self.policy_dt_s = self.world.policy_dt_s
        if (
            cfg.max_ball_delay_s > (self.HISTORY - 1) * self.policy_dt_s
            or cfg.max_joint_delay_s > (self.HISTORY - 1) * self.policy_dt_s
        ):
            raise ValueError(f'observation delays above {(self.HISTORY - 1) * self.policy_dt_s:.3f} s are not kept')
        if cfg.max_action_delay_s > self.policy_dt_s + 1e-9:
            raise ValueError(f'max_action_delay_s must not exceed one policy period ({self.policy_dt_s:.4f} s)')
        # Two streams: the balls (the sampler's own generator) and everything else the task draws.
        self.sampler = batched_launcher.IncomingBallSampler(
            cfg.speed_range_m_s, seed=seed, device=self.device, batch=max(1024, 2 * self.num_envs)
        )
        self.generator = torch.Generator(device=self.device)
        self.generator.manual_seed(int(seed) * 7919 + 104729)
        n, kw = self.num_envs, dict(device=self.device, dtype=torch.float32)
        self._home = torch.tensor(spec.HOME_JOINT_POSITIONS_RAD, **kw)
        # Constants of the resets and the privileged observation, made once rather than every step.
        self._max_noise_std = torch.tensor(
            [
                cfg.noise_joint_position_rad,
                cfg.noise_joint_velocity_rad_s,
                cfg.noise_ball_position_m,
                cfg.noise_ball_velocity_m_s,
            ],
            **kw,
        )
        self._kp_nominal = torch.tensor(world_spec.ARM_KP_NM_PER_RAD, **kw)[:, None]
        self._kd_nominal = torch.tensor(world_spec.ARM_KD_NMS_PER_RAD, **kw)[:, None]
        self._goal_z_m = world_spec.TABLE_CONTACT_HEIGHT_M
        self._bat_axes = torch.tensor(['xyz'.index(a) for a in cfg.bat_axes], device=self.device)
        self.last_action = torch.zeros(n, spec.NUM_ACTIONS, **kw)
        self._qd_prev = torch.zeros(n, spec.NUM_ACTIONS, **kw)
        self._joint_history = torch.zeros(self.HISTORY, n, 2 * spec.NUM_ACTIONS, **kw)
        self._ball_history = torch.zeros(self.HISTORY, n, 6, **kw)
        self.episode = _Episode(
            goal_xy_m=torch.zeros(n, 2, **kw),
            noise_std=torch.zeros(n, 4, **kw),
            ball_delay_steps=torch.zeros(n, **kw),
            joint_delay_steps=torch.zeros(n, **kw),
            action_delay_physics_steps=torch.zeros(n, dtype=torch.long, device=self.device),
            direction=torch.zeros(n, dtype=torch.long, device=self.device),
            reward_sums={name: torch.zeros(n, **kw) for name in REWARD_TERMS},
        )
        self.launch_velocity_m_s = torch.zeros(n, 3, **kw)  # this episode's ball at launch
        # Policy steps since the ball was struck (0 before, and again from the next ball, whose hit flag is clear).
        self._steps_since_hit = torch.zeros(n, dtype=torch.long, device=self.device)
        self._style_weight_steps = round(cfg.style_weight_after_hit_s / self.policy_dt_s)
        # A stroke ends this many steps after the paddle's touch, as `evaluate` cuts strokes (strokes module).
        self._follow_through_steps = round(strokes.FOLLOW_THROUGH_S / self.policy_dt_s)
        self.num_style_features = ARM_STATE_SIZE
        # The kinds of motion a step may ask the motion prior for (rl.env's style labels): the stroke each
        # ball needs, labelled as the demonstrations are.
        self.style_labels = strokes.DIRECTIONS
        # The stroke's length after the touch (rl.env): the pose prior plays the clips' follow-through over it.
        self.style_follow_through_s = strokes.FOLLOW_THROUGH_S
        paddle_home_m = strokes.paddle_home_position_m()
        self._plane_x_m, self._paddle_home_y_m = paddle_home_m[0], paddle_home_m[1]

    # --- what the outside reads -------------------------------------------------------------------
    @property
    def ball_position_m(self) -> torch.Tensor:
        """True ball positions [N, 3] (rendering, tests)."""
        return self.world.ball_pos_m.T

    @property
    def goal_xy_m(self) -> torch.Tensor:
        return self.episode.goal_xy_m

    def style_state(self) -> torch.Tensor:
        """The arm state (q, qdot) [N, 12] in URDF order now: one frame of the discriminator's input,
        the same quantities the demonstrations record (rl.env contract)."""
        return torch.cat((self.world.q_rad.T, self.world.qd_rad_s.T), dim=1)

    # --- episodes ---------------------------------------------------------------------------------
    def _uniform(self, shape, bounds) -> torch.Tensor:
        lo, hi = bounds
        return lo + (hi - lo) * torch.rand(shape, generator=self.generator, device=self.device)

    def _reset_envs(self, env_ids: torch.Tensor) -> None:
        k = int(env_ids.numel())
        if k == 0:
            return
        cfg = self.cfg
        position, velocity, _ = self.sampler.sample(k)
        q = self._home[:, None].expand(-1, k)
        if cfg.randomize and cfg.reset_joint_noise_rad > 0.0:
            q = q + self._uniform((spec.NUM_ACTIONS, k), (-cfg.reset_joint_noise_rad, cfg.reset_joint_noise_rad))
        params = self._physics_params(k)
        self.world.reset_envs(env_ids, q, position, velocity, params)
        # Goal region wholly on the opponent's half.
        r = cfg.goal_radius_m
        goal = torch.stack(
            (
                self._uniform(k, (r, world_spec.HALF_LENGTH_M - r)),
                self._uniform(k, (-world_spec.HALF_WIDTH_M + r, world_spec.HALF_WIDTH_M - r)),
            ),
            dim=1,
        )
        self.episode.goal_xy_m[env_ids] = goal
        self.launch_velocity_m_s[env_ids] = velocity.T.to(torch.float32)
        self.episode.direction[env_ids] = launch_directions(position, velocity, self._plane_x_m, self._paddle_home_y_m)
        if cfg.randomize:
            self.episode.noise_std[env_ids] = self._uniform((k, 1), (0.0, 1.0)) * self._max_noise_std
            self.episode.ball_delay_steps[env_ids] = self._uniform(k, (0.0, cfg.max_ball_delay_s)) / self.policy_dt_s
            self.episode.joint_delay_steps[env_ids] = self._uniform(k, (0.0, cfg.max_joint_delay_s)) / self.policy_dt_s
            physics_steps = int(math.floor(cfg.max_action_delay_s / self.world.physics_dt_s + 1e-9))
            self.episode.action_delay_physics_steps[env_ids] = torch.randint(
                0, physics_steps + 1, (k,), generator=self.generator, device=self.device
            )
        else:
            self.episode.noise_std[env_ids] = 0.0
            self.episode.ball_delay_steps[env_ids] = 0.0
            self.episode.joint_delay_steps[env_ids] = 0.0
            self.episode.action_delay_physics_steps[env_ids] = 0
        self.last_action[env_ids] = 0.0
        joints = torch.cat((self.world.q_rad[:, env_ids].T, self.world.qd_rad_s[:, env_ids].T), dim=1)
        self._qd_prev[env_ids] = joints[:, spec.NUM_ACTIONS :]
        self._joint_history[:, env_ids] = joints
        self._ball_history[:, env_ids] = torch.cat((position.T, velocity.T), dim=1).to(torch.float32)
        for name in REWARD_TERMS:
            self.episode.reward_sums[name][env_ids] = 0.0

    def _physics_params(self, k: int) -> batched_world.PhysicsParams:
        params = batched_world.PhysicsParams.nominal(k, self.device)
        cfg = self.cfg
        params.velocity_drive = self._drive_value(k, cfg.velocity_drive_range)
        params.armature_kg_m2 = params.armature_kg_m2 * self._drive_value(k, cfg.armature_scale_range)
        if not cfg.randomize:
            return params
        params.table_restitution = self._uniform(k, cfg.table_restitution_range)
        params.table_tangential_factor = self._uniform(k, cfg.table_tangential_range)
        params.paddle_restitution = self._uniform(k, cfg.paddle_restitution_range)
        params.paddle_tangential_factor = self._uniform(k, cfg.paddle_tangential_range)
        params.drag_k_per_m = params.drag_k_per_m * self._uniform(k, cfg.drag_scale_range)
        params.gravity_m_s2 = self._uniform(k, cfg.gravity_range_m_s2)
        params.kp_nm_per_rad = params.kp_nm_per_rad * self._uniform(k, cfg.kp_scale_range)
        params.kd_nms_per_rad = params.kd_nms_per_rad * self._uniform(k, cfg.kd_scale_range)
        return params

    def _drive_value(self, k: int, bounds: tuple[float, float]) -> torch.Tensor:
        """A drive setting per environment: drawn when randomising over a range, else its low end. A
        single value draws nothing, so the other parameters' draws stay as they were without it."""
        low, high = bounds
        if self.cfg.randomize and high > low:
            return self._uniform(k, bounds)
        return torch.full((k,), float(low), device=self.device)

    def reset(self) -> tuple[torch.Tensor, torch.Tensor]:
        """Start a new episode in every environment; returns (actor obs, critic obs)."""
        with batched_world.torch_threads(self.cpu_threads):
            self._reset_envs(torch.arange(self.num_envs, device=self.device))
            return self._observations()

    # --- observations -----------------------------------------------------------------------------
    def _delayed(self, history: torch.Tensor, delay_steps: torch.Tensor) -> torch.Tensor:
        """history [H, N, D] (newest first) read delay_steps [N] policy steps back, linearly interpolated."""
        index = delay_steps.floor().long().clamp(0, self.HISTORY - 2)
        frac = (delay_steps - index).clamp(0.0, 1.0)[:, None]
        d = history.shape[-1]
        newer = history.gather(0, index[None, :, None].expand(1, -1, d))[0]
        older = history.gather(0, (index + 1)[None, :, None].expand(1, -1, d))[0]
        return newer + frac * (older - newer)

    def _observations(self) -> tuple[torch.Tensor, torch.Tensor]:
        ep = self.episode
        joints = self._delayed(self._joint_history, ep.joint_delay_steps)
        ball = self._delayed(self._ball_history, ep.ball_delay_steps)
        if self.cfg.randomize:
            std = torch.cat(
                (
                    ep.noise_std[:, 0:1].expand(-1, 6),
                    ep.noise_std[:, 1:2].expand(-1, 6),
                    ep.noise_std[:, 2:3].expand(-1, 3),
                    ep.noise_std[:, 3:4].expand(-1, 3),
                ),
                dim=1,
            )
            noise = std * torch.randn(std.shape, generator=self.generator, device=self.device)
            joints = joints + noise[:, :12]
            ball = ball + noise[:, 12:]
        obs = spec.build_observation(
            joints[:, :6], joints[:, 6:], ball[:, :3], ball[:, 3:], ep.goal_xy_m, self.last_action
        )
        w = self.world
        p = w.params
        physics = torch.stack(
            (
                p.gravity_m_s2,
                p.drag_k_per_m / world_spec.DRAG_K_PER_M,
                p.table_restitution,
                p.table_tangential_factor,
                p.paddle_restitution,
                p.paddle_tangential_factor,
                (p.kp_nm_per_rad / self._kp_nominal).mean(0),
                (p.kd_nms_per_rad / self._kd_nominal).mean(0),
            ),
            dim=1,
        )
        delays = torch.stack(
            (
                ep.ball_delay_steps * self.policy_dt_s,
                ep.joint_delay_steps * self.policy_dt_s,
                ep.action_delay_physics_steps.to(torch.float32) * w.physics_dt_s,
            ),
            dim=1,
        )
        privileged = torch.cat(
            (
                w.q_rad.T - self._home,
                w.qd_rad_s.T,
                w.ball_pos_m.T,
                w.ball_vel_m_s.T,
                w.paddle_pos_m.T,
                w.paddle_rot[:, 2].T,
                w.hit[:, None].float(),
                w.own_bounces[:, None].float(),
                w.time_s[:, None],
                physics,
                ep.noise_std,
                delays,
            ),
            dim=1,
        )
        return obs, torch.cat((obs, privileged), dim=1)

    # --- stepping ---------------------------------------------------------------------------------
    def step(self, actions: torch.Tensor):
        """Advance every environment by one policy period.

        actions [N, 6]: the policy's raw output (clipped and decoded by stylepong_player.spec).
        Returns (obs [N, num_obs], critic_obs [N, num_critic_obs], rewards [N], dones [N] bool, extras) as
        the rl.env contract says (ended episodes already reset; 'time_outs', 'log', 'log_weight',
        'style_state', 'style_label' (the ball's direction), 'style_phase' (the paddle has touched the
        ball), 'style_time_s' (the style clock: _style_time_s), 'style_stroke_end' (FOLLOW_THROUGH_S
        after the touch, as evaluate cuts strokes), and 'style_weight' when style_weight_after_hit is not 1).
        'log' holds success_rate, hit_rate, goal_rate, episode_length_s, ball/<verdict> (the share of each
        referee verdict) and reward/<term> (the episodes' sums of each reward term).
        The task's own extras, after the step and before any reset:
          'outcome'       per ball decided in this step: {'done', 'success', 'hit' (the paddle touched it
                          before the verdict) [N] bool, 'reason' [N] int64 index into FAILURE_REASONS}
          'paddle_hit'    [N] bool: the paddle touched the ball during this step
          'arm_state'     [N, 12] (q, qdot), the same tensor as 'style_state'
          'ball_state'    [N, 6] true ball position and velocity
          'reward_terms'  {term: [N]} this step's reward terms
        """
        with batched_world.torch_threads(self.cpu_threads):
            return self._step(actions)

    def _step(self, actions: torch.Tensor):
        w = self.world
        if actions.shape != (self.num_envs, self.num_actions):
            raise ValueError(f'actions must have shape {(self.num_envs, self.num_actions)}, got {tuple(actions.shape)}')
        if not bool(torch.isfinite(actions).all()):
            raise ValueError('actions contain NaN or inf')
        action = spec.clip_action(actions.to(self.device, torch.float32))
        hit_before = w.hit.clone()
        q_cmd = spec.decode_action(action).T
        events = w.step(q_cmd, self.episode.action_delay_physics_steps)

        q, qd = w.q_rad.T, w.qd_rad_s.T
        arm_state = torch.cat((q, qd), dim=1)
        terms = self._rewards(action, q_cmd, hit_before, events, q, qd)
        reward = sum(terms[name] for name in REWARD_TERMS)
        for name in REWARD_TERMS:
            self.episode.reward_sums[name] += terms[name]

        self._qd_prev = qd.clone()
        self.last_action = action
        self._joint_history = torch.cat((arm_state[None], self._joint_history[:-1]), dim=0)
        self._ball_history = torch.cat(
            (torch.cat((w.ball_pos_m.T, w.ball_vel_m_s.T), dim=1)[None], self._ball_history[:-1]), dim=0
        )

        dones = events.decided
        outcome = {
            'done': dones,
            'success': events.success & dones,
            'hit': w.hit & dones,
            'reason': events.reason.clamp_min(0),
        }
        timed_out = dones & (events.reason == referee.REASON_INDEX[referee.REASON_TIMEOUT])
        extras = {
            env_contract.EXTRAS_TIME_OUTS: timed_out,
            env_contract.EXTRAS_LOG: {},
            env_contract.EXTRAS_LOG_WEIGHT: 0,
            env_contract.EXTRAS_STYLE_STATE: arm_state,
            env_contract.EXTRAS_STYLE_LABEL: self.episode.direction.clone(),
            env_contract.EXTRAS_STYLE_PHASE: w.hit.long(),
            'outcome': outcome,
            'paddle_hit': events.paddle_hit,
            'arm_state': arm_state,
            'ball_state': torch.cat((w.ball_pos_m.T, w.ball_vel_m_s.T), dim=1),
            'reward_terms': terms,
        }
        self._steps_since_hit = torch.where(w.hit, self._steps_since_hit + 1, 0)
        extras[env_contract.EXTRAS_STYLE_TIME] = self._style_time_s()
        extras[env_contract.EXTRAS_STYLE_STROKE_END] = self._steps_since_hit == self._follow_through_steps
        if self.cfg.style_weight_after_hit != 1.0:
            factor = self.cfg.style_weight_after_hit
            extras[env_contract.EXTRAS_STYLE_WEIGHT] = torch.where(self._style_weighted(), factor, 1.0)
        done_ids = torch.nonzero(dones).squeeze(1)
        if done_ids.numel():
            extras[env_contract.EXTRAS_LOG] = self._episode_log(done_ids, outcome)
            extras[env_contract.EXTRAS_LOG_WEIGHT] = int(done_ids.numel())
            self._reset_envs(done_ids)
        obs, critic_obs = self._observations()
        return obs, critic_obs, reward, dones, extras

    def _style_time_s(self) -> torch.Tensor:
        """[N] the style clock (rl.env): since the paddle's touch, or, before it, minus the time the ball
        needs to reach the paddle's home plane at its speed along x now (recomputed every step, so drag and
        the bounce on the robot's half only shift it by what they have changed so far)."""
        w = self.world
        approach_m_s = (-w.ball_vel_m_s[0]).clamp_min(MIN_APPROACH_SPEED_M_S)
        before_s = -(w.ball_pos_m[0] - self._plane_x_m) / approach_m_s
        return torch.where(w.hit, self._steps_since_hit.float() * self.policy_dt_s, before_s)

    def _style_weighted(self) -> torch.Tensor:
        """[N] bool: the steps that earn style_weight_after_hit, from the hit for its duration or to the verdict."""
        struck = self._steps_since_hit > 0
        if self._style_weight_steps == 0:
            return struck
        return struck & (self._steps_since_hit <= self._style_weight_steps)

    def _rewards(self, action, q_cmd, hit_before, events: batched_world.StepEvents, q, qd) -> dict[str, torch.Tensor]:
        cfg = self.cfg
        w = self.world
        ball = w.ball_pos_m.T
        paddle = w.paddle_pos_m.T
        before_hit = ~hit_before & ~events.paddle_hit & (events.decided | w.open)
        offset = (paddle - ball)[:, self._bat_axes]
        bat = cfg.w_bat * torch.exp(-torch.linalg.vector_norm(offset, dim=1) / cfg.sigma_bat_m) * before_hit
        hit = cfg.w_hit * events.paddle_hit.float()
        goal_point = torch.cat((self.episode.goal_xy_m, torch.full_like(ball[:, :1], self._goal_z_m)), dim=1)
        returning = w.hit & (w.open | events.decided)
        goal = (
            cfg.w_goal * torch.exp(-torch.linalg.vector_norm(ball - goal_point, dim=1) / cfg.sigma_goal_m) * returning
        )
        aim = cfg.w_aim * self._aim_quality(events.paddle_hit)
        success = events.success
        landing = w.landing_xy_m.T
        land = (
            cfg.w_land
            * torch.exp(-torch.linalg.vector_norm(landing - self.episode.goal_xy_m, dim=1) / cfg.sigma_land_m)
            * success
        )
        illegal_mask = torch.zeros_like(success)
        for name in ILLEGAL_REASONS:
            illegal_mask |= events.decided & (events.reason == referee.REASON_INDEX[name])
        qdd = (qd - self._qd_prev) / self.policy_dt_s
        acc = cfg.w_acc * (torch.exp(-torch.linalg.vector_norm(qdd, dim=1) / cfg.sigma_acc_rad_s2) - 1.0)
        dof = cfg.w_dof * (torch.exp(-torch.linalg.vector_norm(q - self._home, dim=1) / cfg.sigma_dof_rad) - 1.0)
        rate = cfg.w_rate * (
            torch.exp(-torch.linalg.vector_norm(action - self.last_action, dim=1) / cfg.sigma_rate) - 1.0
        )
        command = torch.zeros_like(acc)
        if cfg.w_command:
            command = -cfg.w_command * w.commands_below_table_top(q_cmd).float()
        return {
            'bat': bat,
            'hit': hit,
            'aim': aim,
            'goal': goal,
            'land': land,
            'success': cfg.w_success * success.float(),
            'illegal': -cfg.w_illegal * illegal_mask.float(),
            'acc': acc,
            'dof': dof,
            'rate': rate,
            'action': -cfg.w_action * action.abs().amax(dim=1),
            'command': command,
        }

    def _aim_quality(self, just_hit: torch.Tensor) -> torch.Tensor:
        """How well the ball's drag-free flight from its state now heads for the goal, where it was just hit.

        exp(-|landing - goal| / sigma_aim) on the table plane, times a soft gate on the height at which it
        passes the net (a logistic of the clearance, 2 cm wide: a near miss still earns a little, so the
        gradient points over the net); 0 for a ball heading away from the net or landing before it. [N]
        """
        w = self.world
        p, v = w.ball_pos_m, w.ball_vel_m_s
        g = w.params.gravity_m_s2
        drop = (p[2] - self._goal_z_m).clamp_min(0.0)
        t_land = (v[2] + torch.sqrt(v[2] * v[2] + 2.0 * g * drop)) / g
        land_x = p[0] + v[0] * t_land
        land_y = p[1] + v[1] * t_land
        t_net = (-p[0] / v[0].clamp_min(1e-3)).clamp(min=0.0)
        z_net = p[2] + v[2] * t_net - 0.5 * g * t_net * t_net
        clearance = z_net - (world_spec.NET_TOP_HEIGHT_M + world_spec.BALL_RADIUS_M)
        over_net = torch.sigmoid(clearance / 0.02) * ((v[0] > 0.0) & (t_net < t_land))
        distance = torch.sqrt(
            (land_x - self.episode.goal_xy_m[:, 0]) ** 2 + (land_y - self.episode.goal_xy_m[:, 1]) ** 2
        )
        return torch.exp(-distance / self.cfg.sigma_aim_m) * over_net * just_hit

    def _episode_log(self, done_ids: torch.Tensor, outcome: dict[str, torch.Tensor]) -> dict[str, float]:
        """Means over the episodes that ended now: ball outcomes, verdict shares and reward-term sums."""
        success = outcome['success'][done_ids]
        in_goal = (
            torch.linalg.vector_norm(self.world.landing_xy_m.T[done_ids] - self.episode.goal_xy_m[done_ids], dim=1)
            <= self.cfg.goal_radius_m
        )
        log = {
            'success_rate': float(success.float().mean()),
            'hit_rate': float(outcome['hit'][done_ids].float().mean()),
            'goal_rate': float((in_goal & success).float().mean()),
            'episode_length_s': float(self.world.time_s[done_ids].mean()),
        }
        shares = torch.bincount(outcome['reason'][done_ids], minlength=len(FAILURE_REASONS)).float() / len(done_ids)
        log.update({f'ball/{name}': share for name, share in zip(FAILURE_REASONS, shares.tolist())})
        log.update({f'reward/{name}': float(self.episode.reward_sums[name][done_ids].mean()) for name in REWARD_TERMS})
        return log


def make_env(cfg: TaskConfig, device: str | torch.device = 'cpu', seed: int = 0) -> TableTennisEnv:
    """The environment for `cfg`; the same seed gives the same balls, goals and randomisation."""
    return TableTennisEnv(cfg, device, seed)
