"""`ros2 run stylepong_policy evaluate`: success, stroke directions, style and smoothness of an exported actor.

    evaluate --actor ppo_actor.pt [--seeds 10] [--first-seed 1000] [--balls 200] [--speed all|low|high]
             [--json out.json] [--save-strokes strokes.npz] [--dtw dataset.npz]
             [--video strokes.mp4] [--device cpu] [--randomize]

The evaluation protocol: for each seed S, S+1, ..., a batched world seeded with it serves `--balls`
balls (one per environment; each environment's first ball counts) from the speed band (all 4.0-6.6,
low 4.0-4.8, high 5.8-6.6 m/s); a ball is a success when, after the paddle hit it, its first table
contact is on the opponent's half (the referee's 'returned'). The actor acts deterministically (its
mean action) in the nominal world (no domain randomisation, no sensing noise) unless --randomize.
The balls a seed serves do not depend on the actor, so two actors meet the same balls.

Every ball is labelled forward, leftward or rightward by where it reaches the robot, and its stroke
(joint positions at 60 Hz from the launch to 0.3 s after the paddle's first contact) is kept:
stylepong_policy.evaluation.strokes says how, and what --save-strokes writes. With --dtw DATASET.npz (from
build_dataset) each direction's strokes are compared with the reference clips of that label by DTW;
stylepong_policy.evaluation.style_metrics gives the convention and the smoothness measures reported beside it.

Printed and written as JSON: success_rate (mean over seeds), success_rate_std, per_seed,
mean_successes_per_seed, hit_rate, failures (verdict -> count), commanded_into_table (the share of balls
before whose verdict a command put the arm below the table top: a stiff drive would follow it there, where
the PD's lag keeps the arm above), balls, seeds, per-direction balls and success (`directions`),
smoothness and, with --dtw, DTW per direction. Paths in it are as given on the
command line (an absolute one under the working directory is made relative to it).
In Python: `run_evaluation(actor, seeds=..., first_seed=..., balls=..., speed=..., randomize=...,
device=...)` returns the same dict.
"""

from __future__ import annotations

import argparse
import math
import os
import pathlib
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
import torch

from stylepong_common.command_line import print_and_write_json, require_counts, ros2_run_line
from stylepong_player import spec
from stylepong_player.spec import ACTION_RATE_HZ
from stylepong_policy.evaluation import style_metrics
from stylepong_policy.evaluation.strokes import (
    DIRECTIONS,
    LEFTWARD_ABOVE_M,
    NO_FRAME,
    RIGHTWARD_BELOW_M,
    Stroke,
    arrival_y_m,
    direction_of,
    paddle_home_position_m,
    save_strokes,
    stroke_end_frame,
)
from stylepong_policy.rl.export import ActorMismatchError, LoadedActor, load_actor
from stylepong_sim.referee import REASON_RETURNED
from stylepong_sim.world_spec import EVALUATION_BALLS_PER_SEED, EVALUATION_SEEDS, FIRST_EVALUATION_SEED

SUCCESS_REASON = REASON_RETURNED  # the referee's verdict for a successful return
NO_DECISION = 'episode_time_limit'  # an episode the env ended without the referee deciding the ball
# The setting of a figure, said in every result (Table IV of paper_tables labels its rows with it).
WORLDS = {
    False: 'batched world, nominal (no randomisation, no sensing noise)',
    True: 'batched world, training randomisation (physics, sensing noise, latencies; --randomize)',
}


@dataclass(frozen=True)
class Drive:
    """The arm's joint drive in the batched world (task.TaskConfig): the share of a stiff velocity motor
    (0: the cells' PD) and the rotor inertia's scale (1: world_spec's; 0: none)."""

    velocity_motor: float = 0.0
    armature_scale: float = 1.0

    def describe(self) -> str:
        """'' for the nominal drive, else the words a result's setting adds."""
        if self == Drive():
            return ''
        return f'; joint drive {self.velocity_motor:g} velocity motor, rotor inertia x{self.armature_scale:g}'


VIDEO_FPS = int(ACTION_RATE_HZ)  # one frame per policy step: real time
SPEEDS = ('all', 'low', 'high')
# |arrival y - paddle home y| bands (m) of dtw_by_lateral_offset: the demonstrated hits lie within 0.18 m.
LATERAL_OFFSET_BANDS_M = (0.0, 0.2, 0.4, 0.6, math.inf)
DTW_CALL = "dtaidistance.dtw_ndim.distance_fast(stroke, clip, inner_dist='euclidean')"


@dataclass
class SeedResult:
    """The outcome of one evaluation seed: successes, hits, failure reasons and strokes."""

    seed: int
    balls: int
    successes: int
    hits: int
    reasons: dict[str, int]
    wall_time_s: float
    strokes: list[Stroke] = field(default_factory=list)
    commanded_into_table: int = 0  # balls before whose verdict a command put the arm below the table top

    @property
    def success_rate(self) -> float:
        return self.successes / self.balls


@dataclass
class Evaluation:
    """An actor's results over the seeds, with every ball's stroke."""

    actor: str  # the actor's path as given (see portable_path)
    actor_spec_version: int | None
    speed: str
    randomize: bool
    balls_per_seed: int
    results: list[SeedResult]
    drive: Drive = Drive()

    @property
    def strokes(self) -> list[Stroke]:
        return [s for r in self.results for s in r.strokes]


def portable_path(path: str | os.PathLike) -> str:
    """A path fit for a result file: as given when relative; an absolute path under the working
    directory relative to it, any other absolute path reduced to its file name. A result read on
    another machine must not carry this machine's folders."""
    p = pathlib.Path(path)
    if not p.is_absolute():
        return p.as_posix()
    try:
        return p.relative_to(pathlib.Path.cwd()).as_posix()
    except ValueError:
        return p.name


# ---------------------------------------------------------------------------------------------------
# Running the balls


def evaluate_seed(
    actor: LoadedActor,
    seed: int,
    balls: int,
    device: torch.device | str,
    *,
    speed: str = 'all',
    randomize: bool = False,
    drive: Drive = Drive(),
) -> SeedResult:
    """Play each of `balls` environments' first ball to its verdict and keep its stroke."""
    from stylepong_policy.training import task
    from stylepong_sim.world_spec import SPEED_RANGES_M_S

    started = time.perf_counter()
    cfg = task.TaskConfig(
        num_envs=balls,
        speed_range_m_s=tuple(SPEED_RANGES_M_S[speed]),
        randomize=bool(randomize),
        velocity_drive_range=(drive.velocity_motor,) * 2,
        armature_scale_range=(drive.armature_scale,) * 2,
    )
    env = task.make_env(cfg, device, seed)
    names = list(task.FAILURE_REASONS) + [NO_DECISION]
    decided = torch.zeros(balls, dtype=torch.bool, device=env.device)
    success = torch.zeros_like(decided)
    hit = torch.zeros_like(decided)
    into_table = torch.zeros_like(decided)
    reason = torch.full((balls,), -1, dtype=torch.int64, device=env.device)
    verdict_frame = torch.full((balls,), NO_FRAME, dtype=torch.int64, device=env.device)
    hit_frame = torch.full_like(verdict_frame, NO_FRAME)
    # A generous bound on steps until every first ball is decided: three episodes' time plus a second.
    max_steps = int(3 * float(cfg.episode_length_s) * ACTION_RATE_HZ) + int(ACTION_RATE_HZ)
    with torch.inference_mode():
        obs, _ = env.reset()
        launch_velocity = env.launch_velocity_m_s.cpu().numpy().astype(np.float64)
        # Frame 0 is the launch; frame k the state after step k, before any reset (the extras').
        q_frames = [env.style_state()[:, :6].cpu()]
        ball_frames = [torch.cat((env.ball_position_m, env.launch_velocity_m_s), dim=1).cpu()]
        step = 0
        while not bool(decided.all()):
            if step >= max_steps:
                raise RuntimeError(
                    f'seed {seed}: {int((~decided).sum())} balls undecided after {step} steps; '
                    'the env never ended their episodes'
                )
            actions = actor(obs.to('cpu')).to(env.device)
            into_table |= ~decided & env.world.commands_below_table_top(spec.decode_action(actions).T)
            obs, _, _, dones, extras = env.step(actions)
            step += 1
            q_frames.append(extras['arm_state'][:, :6].cpu())
            ball_frames.append(extras['ball_state'].cpu())
            open_ = ~decided
            outcome = extras['outcome']
            hit_frame = torch.where(
                extras['paddle_hit'] & open_ & (hit_frame == NO_FRAME), torch.full_like(hit_frame, step), hit_frame
            )
            ball_done = outcome['done'] & open_
            success |= outcome['success'] & ball_done
            hit |= outcome['hit'] & ball_done
            reason = torch.where(ball_done, outcome['reason'], reason)
            # An episode that ended without a referee decision (a pure time limit) is a failure too.
            undecided_end = dones & open_ & ~ball_done
            reason = torch.where(undecided_end, torch.full_like(reason, len(names) - 1), reason)
            ended = ball_done | undecided_end
            verdict_frame = torch.where(ended, torch.full_like(verdict_frame, step), verdict_frame)
            decided |= ended
    counts = torch.bincount(reason.cpu(), minlength=len(names)).tolist()
    strokes = _strokes(
        seed,
        torch.stack(q_frames).numpy(),
        torch.stack(ball_frames).numpy(),
        launch_velocity,
        [names[i] for i in reason.tolist()],
        success.tolist(),
        hit.tolist(),
        hit_frame.tolist(),
        verdict_frame.tolist(),
    )
    return SeedResult(
        seed=seed,
        balls=balls,
        successes=int(success.sum()),
        hits=int(hit.sum()),
        reasons={n: int(c) for n, c in zip(names, counts) if c and n != SUCCESS_REASON},
        wall_time_s=time.perf_counter() - started,
        strokes=strokes,
        commanded_into_table=int(into_table.sum()),
    )


def _strokes(
    seed: int,
    q: np.ndarray,
    ball: np.ndarray,
    launch_velocity: np.ndarray,
    outcomes: list[str],
    success: list[bool],
    hit: list[bool],
    hit_frame: list[int],
    verdict_frame: list[int],
) -> list[Stroke]:
    """Cut each environment's stroke from the frames [F, N, ...] of its world."""
    plane_x, home_y, _ = paddle_home_position_m()
    result = []
    for i in range(q.shape[1]):
        end = stroke_end_frame(verdict_frame[i], hit_frame[i], ACTION_RATE_HZ)
        # Frames before the first paddle contact and before the verdict (which may be a robot contact).
        free = verdict_frame[i] if hit_frame[i] == NO_FRAME else min(hit_frame[i], verdict_frame[i])
        y = arrival_y_m(ball[:free, i, :3], ball[:free, i, 3:], free, plane_x)
        result.append(
            Stroke(
                seed=seed,
                ball=i,
                joint_positions_rad=q[: end + 1, i].copy(),
                ball_position_m=ball[: end + 1, i, :3].copy(),
                direction=direction_of(y, home_y),
                arrival_y_m=y,
                launch_velocity_m_s=launch_velocity[i].copy(),
                outcome=outcomes[i],
                success=bool(success[i]),
                hit=bool(hit[i]),
                hit_frame=int(hit_frame[i]),
                verdict_frame=int(verdict_frame[i]),
            )
        )
    return result


def evaluate_actor(
    actor: str | os.PathLike | LoadedActor,
    *,
    seeds: int = EVALUATION_SEEDS,
    first_seed: int = FIRST_EVALUATION_SEED,
    balls: int = EVALUATION_BALLS_PER_SEED,
    speed: str = 'all',
    randomize: bool = False,
    device: str | torch.device = 'cpu',
    progress: Callable[[SeedResult], None] | None = None,
    drive: Drive = Drive(),
) -> Evaluation:
    """Run the protocol (module docstring) and keep every stroke; `progress` is called after each seed."""
    if speed not in SPEEDS:
        raise ValueError(f'speed must be one of {SPEEDS}, got {speed!r}')
    if seeds < 1 or balls < 1:
        raise ValueError('seeds and balls must be at least 1')
    loaded = actor if isinstance(actor, LoadedActor) else load_actor(actor)
    given = loaded.path if isinstance(actor, LoadedActor) else actor
    results = []
    for seed in range(first_seed, first_seed + seeds):
        result = evaluate_seed(loaded, seed, balls, device, speed=speed, randomize=randomize, drive=drive)
        results.append(result)
        if progress is not None:
            progress(result)
    return Evaluation(
        actor=portable_path(given),
        actor_spec_version=loaded.metadata.get('spec_version'),
        speed=speed,
        randomize=bool(randomize),
        balls_per_seed=balls,
        results=results,
        drive=drive,
    )


# ---------------------------------------------------------------------------------------------------
# Summaries


def direction_table(strokes: Sequence[Stroke]) -> dict[str, dict]:
    """Balls, success and hit rate of each direction."""
    table = {}
    for direction in DIRECTIONS:
        chosen = [s for s in strokes if s.direction == direction]
        n = len(chosen)
        table[direction] = {
            'balls': n,
            'success_rate': sum(s.success for s in chosen) / n if n else None,
            'hit_rate': sum(s.hit for s in chosen) / n if n else None,
        }
    return table


def smoothness_table(strokes: Sequence[Stroke], rate_hz: float = ACTION_RATE_HZ) -> dict[str, dict | None]:
    """Mean smoothness measures of each direction's strokes and of all of them."""
    measured = [
        (s.direction, style_metrics.smoothness(s.joint_positions_rad, rate_hz))
        for s in strokes
        if len(s.joint_positions_rad) >= 4
    ]
    table = {d: style_metrics.mean_smoothness(m for direction, m in measured if direction == d) for d in DIRECTIONS}
    table['all'] = style_metrics.mean_smoothness(m for _, m in measured)
    return table


def references_by_direction(dataset) -> dict[str, list[tuple[int, np.ndarray]]]:
    """The reference clips (index, joint positions) of each direction's label, all speed factors."""
    return {direction: style_metrics.reference_clips(dataset, direction) for direction in DIRECTIONS}


def nearest_matches(strokes: Sequence[Stroke], references: dict[str, list]) -> list[style_metrics.DtwMatch | None]:
    """Each stroke's nearest reference clip of its own label (None where the dataset has no such clip)."""
    return [
        style_metrics.nearest_reference(s.joint_positions_rad, references[s.direction])
        if references[s.direction]
        else None
        for s in strokes
    ]


def dtw_table(
    strokes: Sequence[Stroke],
    matches: Sequence[style_metrics.DtwMatch | None],
    references: dict[str, list],
    rate_hz: float = ACTION_RATE_HZ,
) -> dict[str, dict]:
    """Per direction: every stroke against every reference clip of that label, the mean of the smallest,
    and the summed distance split by joint and by phase of the stroke (style_metrics.cost_breakdown)."""
    from stylepong_description.robot_model import JOINT_NAMES

    table = {}
    for direction in DIRECTIONS:
        clips = dict(references[direction])
        chosen = [(s, m) for s, m in zip(strokes, matches) if s.direction == direction and m is not None]
        entry = {
            'strokes': sum(s.direction == direction for s in strokes),
            'reference_clips': len(clips),
            'mean_rad': None,
            'std_rad': None,
            'mean_per_path_step_rad': None,
            'sum_by_joint_rad': None,
            'sum_by_phase_rad': None,
        }
        if chosen:
            distances = np.array([m.distance for _, m in chosen])
            parts = [
                style_metrics.cost_breakdown(s.joint_positions_rad, clips[m.clip], m.path, s.hit_frame, rate_hz)
                for s, m in chosen
            ]
            by_joint = np.sum([p.by_joint_rad for p in parts], axis=0)
            entry.update(
                mean_rad=float(distances.mean()),
                std_rad=float(distances.std()),
                mean_per_path_step_rad=float(np.mean([m.distance_per_step for _, m in chosen])),
                sum_by_joint_rad=dict(zip(JOINT_NAMES, by_joint.tolist())),
                sum_by_phase_rad={
                    phase: float(sum(p.by_phase_rad[phase] for p in parts)) for phase in style_metrics.PHASES
                },
            )
        table[direction] = entry
    return table


def dtw_by_lateral_offset(
    strokes: Sequence[Stroke], matches: Sequence[style_metrics.DtwMatch | None], paddle_home_y_m: float
) -> dict[str, dict]:
    """Mean DTW distance of the strokes grouped by how far to the side of the paddle's home the ball
    arrives (|arrival y - home y|, LATERAL_OFFSET_BANDS_M): whether strokes far from the demonstrated
    hitting points are further from the demonstrations than those near them."""
    table = {}
    for low, high in zip(LATERAL_OFFSET_BANDS_M[:-1], LATERAL_OFFSET_BANDS_M[1:]):
        distances = [
            m.distance
            for s, m in zip(strokes, matches)
            if m is not None and low <= abs(s.arrival_y_m - paddle_home_y_m) < high
        ]
        band = f'{low:g}-{high:g} m' if math.isfinite(high) else f'{low:g} m and more'
        table[band] = {'strokes': len(distances), 'mean_rad': float(np.mean(distances)) if distances else None}
    return table


def load_reference(path: str | os.PathLike):
    """A reference dataset for DTW, checked to hold joint positions in the URDF order the strokes use."""
    from stylepong_description.robot_model import JOINT_NAMES
    from stylepong_policy.training.dataset import ReferenceDataset

    dataset = ReferenceDataset.load(path)
    if tuple(dataset.joint_names) != tuple(JOINT_NAMES):
        raise ValueError(f"{path}: joints {list(dataset.joint_names)} are not the robot's {list(JOINT_NAMES)}")
    return dataset


def summarise(
    evaluation: Evaluation,
    *,
    dataset=None,
    dataset_path: str | os.PathLike | None = None,
    matches: Sequence[style_metrics.DtwMatch | None] | None = None,
) -> dict:
    """The JSON-ready results of an evaluation (DTW only when a reference dataset is given). matches: the
    strokes' nearest_matches against `dataset` when already measured (style_confusion), else measured here."""
    results = evaluation.results
    rates = [r.success_rate for r in results]
    failures: dict[str, int] = {}
    for r in results:
        for name, count in r.reasons.items():
            failures[name] = failures.get(name, 0) + count
    balls = sum(r.balls for r in results)
    strokes = evaluation.strokes
    plane_x, home_y, _ = paddle_home_position_m()
    summary = {
        'success_rate': float(np.mean(rates)),
        'success_rate_std': float(np.std(rates)),
        'per_seed': [round(x, 4) for x in rates],
        'mean_successes_per_seed': float(np.mean([r.successes for r in results])),
        'hit_rate': sum(r.hits for r in results) / balls,
        'failures': dict(sorted(failures.items(), key=lambda kv: -kv[1])),
        'balls': balls,
        'commanded_into_table': sum(r.commanded_into_table for r in results) / balls,
        'seeds': [r.seed for r in results],
        'balls_per_seed': evaluation.balls_per_seed,
        'speed': evaluation.speed,
        'randomize': evaluation.randomize,
        'world': WORLDS[evaluation.randomize] + evaluation.drive.describe(),
        'actor': evaluation.actor,
        'actor_spec_version': evaluation.actor_spec_version,
        'wall_time_s': round(sum(r.wall_time_s for r in results), 2),
        'direction_rule': {
            'plane_x_m': round(plane_x, 4),
            'paddle_home_y_m': round(home_y, 4),
            'leftward_above_m': LEFTWARD_ABOVE_M,
            'rightward_below_m': RIGHTWARD_BELOW_M,
        },
        'directions': direction_table(strokes),
        'smoothness': smoothness_table(strokes),
    }
    if dataset is not None:
        references = references_by_direction(dataset)
        if matches is None:
            matches = nearest_matches(strokes, references)
        summary['dtw'] = dtw_table(strokes, matches, references)
        summary['dtw_by_lateral_offset'] = dtw_by_lateral_offset(strokes, matches, home_y)
        summary['dtw_dataset'] = portable_path(dataset_path) if dataset_path is not None else None
        summary['dtw_call'] = DTW_CALL
    return summary


def run_evaluation(
    actor: str | os.PathLike | LoadedActor, *, dtw_dataset: str | os.PathLike | None = None, **protocol
) -> dict:
    """Evaluate an actor (a path to an exported actor, or one loaded with rl.export.load_actor) under the
    protocol's settings (evaluate_actor's keywords: seeds, first_seed, balls, speed, randomize, device, drive)
    and return the dict `evaluate` prints. Raises rl.export.ActorMismatchError for an actor that does not fit."""
    evaluation = evaluate_actor(actor, **protocol)
    dataset = load_reference(dtw_dataset) if dtw_dataset is not None else None
    return summarise(evaluation, dataset=dataset, dataset_path=dtw_dataset)


# ---------------------------------------------------------------------------------------------------
# Video


def save_evaluation_strokes(path: str | os.PathLike, evaluation: Evaluation, actor: LoadedActor) -> str:
    """Write an evaluation's strokes (strokes.save_strokes) and return the path as the summary names it."""
    save_strokes(
        path,
        evaluation.strokes,
        rate_hz=ACTION_RATE_HZ,
        joint_names=actor.metadata['joint_names'],
        actor=evaluation.actor,
        speed=evaluation.speed,
    )
    return portable_path(path)


def render_video(strokes: Sequence[Stroke], path: pathlib.Path, camera: str = 'overview', hold_s: float = 0.5) -> int:
    """Replay strokes in the cell's MuJoCo model (kinematics only: joint positions and the ball marker
    set each frame) and encode them with the cell's video recorder. Returns frames written."""
    import mujoco

    from stylepong_description.robot_model import JOINT_NAMES
    from stylepong_sim.cells import scene
    from stylepong_sim.cells.video import VideoRecorder

    model = scene.build_model()
    data = mujoco.MjData(model)
    qpos_index = [model.jnt_qposadr[model.joint(name).id] for name in JOINT_NAMES]
    ball_mocap = model.body_mocapid[model.body(scene.BALL_BODY).id]
    recorder = VideoRecorder(model, str(path), fps=VIDEO_FPS, camera=camera)
    try:
        for stroke in strokes:
            q_track, ball_track = stroke.joint_positions_rad, stroke.ball_position_m
            for t in range(len(q_track) + int(hold_s * VIDEO_FPS)):
                k = min(t, len(q_track) - 1)
                data.qpos[qpos_index] = q_track[k]
                data.mocap_pos[ball_mocap] = ball_track[k]
                mujoco.mj_forward(model, data)
                recorder.capture(data)
    finally:
        recorder.close()
    return recorder.frames


# ---------------------------------------------------------------------------------------------------
# Command line


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    """The command line of evaluate."""
    parser = argparse.ArgumentParser(prog='evaluate', description=__doc__.split('\n\n')[0])
    parser.add_argument('--actor', required=True, type=pathlib.Path, help='exported actor (.pt with its .json)')
    parser.add_argument('--seeds', type=int, default=EVALUATION_SEEDS, help='number of seeds')
    parser.add_argument(
        '--first-seed',
        type=int,
        default=FIRST_EVALUATION_SEED,
        help=f'first seed (evaluation seeds are >= {FIRST_EVALUATION_SEED})',
    )
    parser.add_argument('--balls', type=int, default=EVALUATION_BALLS_PER_SEED, help='balls per seed')
    parser.add_argument('--speed', choices=SPEEDS, default='all', help='incoming speed band')
    parser.add_argument('--json', type=pathlib.Path, help='write the results here')
    parser.add_argument('--save-strokes', type=pathlib.Path, help='write every stroke to this .npz')
    parser.add_argument('--dtw', type=pathlib.Path, metavar='DATASET', help='reference dataset (.npz) for DTW')
    parser.add_argument('--video', type=pathlib.Path, help='render a few strokes of the first seed to this MP4')
    parser.add_argument('--video-strokes', type=int, default=4, help='strokes in the video')
    parser.add_argument(
        '--camera', default='overview', help="camera of the cell's scene for the video (overview, robot_view)"
    )
    parser.add_argument('--device', default='cpu', help='torch device of the world')
    parser.add_argument('--randomize', action='store_true', help='evaluate with domain randomisation on')
    parser.add_argument(
        '--velocity-drive',
        type=float,
        default=0.0,
        metavar='SHARE',
        help="the joint drive's share of a stiff velocity motor, 0-1 (0: the cells' PD)",
    )
    parser.add_argument(
        '--armature-scale',
        type=float,
        default=1.0,
        metavar='SCALE',
        help="rotor inertia scale, 0-1 (1: the world spec's; 0: none)",
    )
    parser.add_argument('--num-threads', type=int, default=2, help='torch CPU threads')
    args = parser.parse_args(argv)
    require_counts(parser, args, ('seeds', 'balls', 'num_threads'))
    if args.first_seed < 0:
        parser.error('--first-seed must not be negative')
    if args.video_strokes < 1:
        parser.error('--video-strokes must be at least 1')
    for flag, value in (('--velocity-drive', args.velocity_drive), ('--armature-scale', args.armature_scale)):
        if not 0.0 <= value <= 1.0:
            parser.error(f'{flag} must be within [0, 1], got {value}')
    return args


def command_line(argv: Sequence[str]) -> str:
    """This evaluation as a person would type it again (paths as portable_path writes them)."""
    return ros2_run_line('stylepong_policy', 'evaluate', [portable_path(w) if os.path.isabs(w) else w for w in argv])


def main(argv: list[str] | None = None) -> int:
    """Entry point of the evaluate executable."""
    argv = sys.argv[1:] if argv is None else list(argv)
    args = parse_args(argv)
    try:
        actor = load_actor(args.actor)
    except ActorMismatchError as err:
        print(f'evaluate: {err}', file=sys.stderr)
        return 2
    device = torch.device(args.device)
    if device.type == 'cuda' and not torch.cuda.is_available():
        print(f'evaluate: device {args.device!r} requested but CUDA is not available', file=sys.stderr)
        return 2
    torch.set_num_threads(args.num_threads)
    if args.video is not None:
        from stylepong_sim.cells.scene import CAMERAS

        if args.camera not in CAMERAS:
            print(f'evaluate: unknown camera {args.camera!r}; the cell has {", ".join(CAMERAS)}', file=sys.stderr)
            return 2
    dataset = None
    if args.dtw is not None:
        try:
            dataset = load_reference(args.dtw)
        except (OSError, KeyError, ValueError) as err:
            print(f'evaluate: cannot use {args.dtw} as a reference dataset: {err}', file=sys.stderr)
            return 2
    if args.first_seed < FIRST_EVALUATION_SEED:
        print(
            f'evaluate: warning: seeds below {FIRST_EVALUATION_SEED} are training seeds; '
            f'reported figures use {FIRST_EVALUATION_SEED} and up',
            file=sys.stderr,
        )

    def report(result: SeedResult) -> None:
        print(
            f'seed {result.seed}: success {result.success_rate:.3f} ({result.successes}/{result.balls}), '
            f'hits {result.hits}, failures {result.reasons}, {result.wall_time_s:.1f} s',
            flush=True,
        )

    evaluation = evaluate_actor(
        actor,
        seeds=args.seeds,
        first_seed=args.first_seed,
        balls=args.balls,
        speed=args.speed,
        randomize=args.randomize,
        device=device,
        progress=report,
        drive=Drive(args.velocity_drive, args.armature_scale),
    )
    summary = summarise(evaluation, dataset=dataset, dataset_path=args.dtw)
    summary['command'] = command_line(argv)
    if args.save_strokes is not None:
        summary['strokes_file'] = save_evaluation_strokes(args.save_strokes, evaluation, actor)
    if args.video is not None:
        shown = evaluation.results[0].strokes[: args.video_strokes]
        frames = render_video(shown, args.video, camera=args.camera)
        summary['video'] = {
            'path': portable_path(args.video),
            'frames': frames,
            'fps': VIDEO_FPS,
            'strokes': [s.outcome for s in shown],
        }
    print_and_write_json(summary, args.json)
    return 0


if __name__ == '__main__':
    sys.exit(main())
