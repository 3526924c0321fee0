"""`ros2 run stylepong_policy evaluate`: success rate of an exported actor in the batched world.

    evaluate --actor ppo_actor.pt [--seeds 10] [--first-seed 1000] [--balls 200] [--speed all|low|high]
             [--json out.json] [--video strokes.mp4] [--device cpu] [--randomize]

The evaluation protocol of DESIGN.md: for each seed S, S+1, ..., a world seeded with it serves
`--balls` balls (one per environment, each environment's first ball counts) from the speed band
(all 4.0-6.6, low 4.0-4.8, high 5.8-6.6 m/s); a ball is a success when, after the paddle hit it, its
first table contact is on the opponent's half. The actor acts deterministically (its mean action).
Printed and written as JSON: success_rate (mean over seeds), success_rate_std, per_seed, hit_rate,
failures (reason -> count), balls (total), seeds. `--video` replays a few of the first seed's
strokes in the MuJoCo model of the cell.
"""
from __future__ import annotations

import os

# Before torch loads OpenMP: idle OpenMP threads sleep instead of spinning. On 2 cores shared with other
# work, spinning threads made a PPO update 4-5x slower than one thread; sleeping ones cost ~nothing.
os.environ.setdefault('OMP_WAIT_POLICY', 'PASSIVE')
# MuJoCo picks its GL back end when first imported (the world imports it): headless EGL for --video.
os.environ.setdefault('MUJOCO_GL', 'egl')

import argparse
import json
import pathlib
import sys
import time
from dataclasses import dataclass, field

import numpy as np
import torch

from stylepong_policy.rl.config import FIRST_EVALUATION_SEED
from stylepong_policy.rl.export import ActorMismatchError, LoadedActor, load_actor
from stylepong_policy.spec import ACTION_RATE_HZ
from stylepong_sim.referee import REASON_RETURNED

SUCCESS_REASON = REASON_RETURNED     # the referee's verdict for a successful return
NO_DECISION = 'episode_time_limit'   # an episode the env ended without the referee deciding the ball
VIDEO_FPS = int(ACTION_RATE_HZ)      # one frame per policy step: real time


@dataclass
class SeedResult:
    seed: int
    balls: int
    successes: int
    hits: int
    reasons: dict[str, int]
    wall_time_s: float

    @property
    def success_rate(self) -> float:
        return self.successes / self.balls


@dataclass
class Recording:
    """Joint positions [T, 6] and ball positions [T, 3] of a few environments, one row per policy step."""
    joint_positions_rad: list[np.ndarray] = field(default_factory=list)
    ball_positions_m: list[np.ndarray] = field(default_factory=list)
    outcomes: list[str] = field(default_factory=list)


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog='evaluate', description=__doc__.split('\n\n')[0])
    parser.add_argument('--actor', required=True, type=pathlib.Path, help='exported actor (.pt with its .json)')
    parser.add_argument('--seeds', type=int, default=10, help='number of seeds')
    parser.add_argument('--first-seed', type=int, default=FIRST_EVALUATION_SEED,
                        help=f'first seed (evaluation seeds are >= {FIRST_EVALUATION_SEED})')
    parser.add_argument('--balls', type=int, default=200, help='balls per seed')
    parser.add_argument('--speed', choices=('all', 'low', 'high'), default='all', help='incoming speed band')
    parser.add_argument('--json', type=pathlib.Path, help='write the results here')
    parser.add_argument('--video', type=pathlib.Path, help='render a few strokes of the first seed to this MP4')
    parser.add_argument('--video-strokes', type=int, default=4, help='strokes in the video')
    parser.add_argument('--camera', default='overview', help="camera of the cell's scene for the video (overview, robot_view)")
    parser.add_argument('--device', default='cpu', help='torch device of the world')
    parser.add_argument('--randomize', action='store_true', help='evaluate with domain randomisation on')
    parser.add_argument('--num-threads', type=int, default=2, help='torch CPU threads')
    args = parser.parse_args(argv)
    for name in ('seeds', 'balls', 'num_threads'):
        if getattr(args, name) < 1:
            parser.error(f'--{name.replace("_", "-")} must be at least 1')
    if args.first_seed < 0:
        parser.error('--first-seed must not be negative')
    if args.video_strokes < 1:
        parser.error('--video-strokes must be at least 1')
    return args


def evaluate_seed(actor: LoadedActor, task, task_overrides: dict, seed: int, balls: int, device: torch.device,
                  record: int = 0) -> tuple[SeedResult, Recording | None]:
    """Play each of `balls` environments' first ball to its decision; optionally record `record` of them."""
    started = time.perf_counter()
    cfg = task.TaskConfig(**{**task_overrides, 'num_envs': balls})
    env = task.make_env(cfg, device, seed)
    reasons = list(task.FAILURE_REASONS)
    decided = torch.zeros(balls, dtype=torch.bool, device=env.device)
    success = torch.zeros_like(decided)
    hit = torch.zeros_like(decided)
    reason = torch.full((balls,), -1, dtype=torch.int64, device=env.device)
    hit_so_far = torch.zeros_like(decided)
    recording = Recording() if record > 0 else None
    tracks: list[tuple[list, list]] = [([], []) for _ in range(min(record, balls))]
    # A generous bound on steps until every first ball is decided: three episodes' time plus a second.
    max_steps = int(3 * float(cfg.episode_length_s) * ACTION_RATE_HZ) + int(ACTION_RATE_HZ)
    steps = 0
    with torch.inference_mode():
        obs, _ = env.reset()
        while not bool(decided.all()):
            if steps >= max_steps:
                raise RuntimeError(f'seed {seed}: {int((~decided).sum())} balls undecided after {steps} steps; '
                                   'the env never ended their episodes')
            actions = actor(obs.to('cpu')).to(env.device)
            obs, _, _, dones, info = env.step(actions)
            steps += 1
            if recording is not None:
                _record_step(tracks, env, info, decided)
            open_ = ~decided
            hit_so_far |= info['ball_hit'] & open_
            ball_done = info['ball_done'] & open_
            success |= info['ball_success'] & ball_done
            reason = torch.where(ball_done, info['ball_reason'], reason)
            hit |= hit_so_far & ball_done
            # An episode that ended without a referee decision (a pure time limit) is a failure too.
            undecided_end = dones & open_ & ~ball_done
            reason = torch.where(undecided_end, torch.full_like(reason, len(reasons)), reason)
            decided |= ball_done | undecided_end
    names = reasons + [NO_DECISION]
    counts = torch.bincount(reason.cpu(), minlength=len(names)).tolist()
    result = SeedResult(seed=seed, balls=balls, successes=int(success.sum()), hits=int(hit.sum()),
                        reasons={n: int(c) for n, c in zip(names, counts) if c and n != SUCCESS_REASON},
                        wall_time_s=time.perf_counter() - started)
    if recording is not None:
        for i, (q, ball) in enumerate(tracks):
            recording.joint_positions_rad.append(np.array(q))
            recording.ball_positions_m.append(np.array(ball))
            recording.outcomes.append(SUCCESS_REASON if bool(success[i]) else names[int(reason[i])])
    return result, recording


def _record_step(tracks, env, info, decided) -> None:
    n = len(tracks)
    q = info['arm_state'][:n, :6].cpu().numpy()
    ball = env.ball_position_m[:n].cpu().numpy()   # the true position, for rendering only
    for i in range(n):
        if not bool(decided[i]):
            tracks[i][0].append(q[i])
            tracks[i][1].append(ball[i])


def render_video(recording: Recording, path: pathlib.Path, camera: str = 'overview', hold_s: float = 0.5) -> int:
    """Replay the recorded strokes in the cell's MuJoCo model (kinematics only: joint positions and the
    ball marker set each frame) and encode them with the cell's video recorder. Returns frames written."""
    import mujoco
    from stylepong_description.robot_model import JOINT_NAMES
    from stylepong_sim import scene
    from stylepong_sim.video import VideoRecorder

    model = scene.build_model()
    data = mujoco.MjData(model)
    qpos_index = [model.jnt_qposadr[model.joint(name).id] for name in JOINT_NAMES]
    ball_mocap = model.body_mocapid[model.body(scene.BALL_BODY).id]
    recorder = VideoRecorder(model, str(path), fps=VIDEO_FPS, camera=camera)
    try:
        for q_track, ball_track in zip(recording.joint_positions_rad, recording.ball_positions_m):
            for t in range(len(q_track) + int(hold_s * VIDEO_FPS)):
                k = min(t, len(q_track) - 1)
                data.qpos[qpos_index] = q_track[k]
                data.mocap_pos[ball_mocap] = ball_track[k]
                mujoco.mj_forward(model, data)
                recorder.capture(data)
    finally:
        recorder.close()
    return recorder.frames


def summarise(results: list[SeedResult], args: argparse.Namespace, actor: LoadedActor) -> dict:
    rates = [r.success_rate for r in results]
    failures: dict[str, int] = {}
    for r in results:
        for name, count in r.reasons.items():
            failures[name] = failures.get(name, 0) + count
    balls = sum(r.balls for r in results)
    return {
        'success_rate': float(np.mean(rates)), 'success_rate_std': float(np.std(rates)),
        'per_seed': [round(x, 4) for x in rates], 'hit_rate': sum(r.hits for r in results) / balls,
        'failures': dict(sorted(failures.items(), key=lambda kv: -kv[1])), 'balls': balls,
        'seeds': [r.seed for r in results], 'balls_per_seed': args.balls, 'speed': args.speed,
        'randomize': bool(args.randomize), 'actor': str(args.actor),
        'actor_spec_version': actor.metadata.get('spec_version'),
        'wall_time_s': round(sum(r.wall_time_s for r in results), 2),
    }


def main(argv: list[str] | None = None) -> int:
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
        from stylepong_sim.scene import CAMERAS
        if args.camera not in CAMERAS:
            print(f'evaluate: unknown camera {args.camera!r}; the cell has {", ".join(CAMERAS)}', file=sys.stderr)
            return 2
    if args.first_seed < FIRST_EVALUATION_SEED:
        print(f'evaluate: warning: seeds below {FIRST_EVALUATION_SEED} are training seeds (DESIGN.md); '
              f'reported figures use {FIRST_EVALUATION_SEED} and up', file=sys.stderr)
    from stylepong_policy import task
    from stylepong_sim.world_spec import SPEED_RANGES_M_S
    overrides = {'speed_range_m_s': tuple(SPEED_RANGES_M_S[args.speed]), 'randomize': bool(args.randomize)}
    results = []
    recording = None
    for i, seed in enumerate(range(args.first_seed, args.first_seed + args.seeds)):
        record = args.video_strokes if (args.video is not None and i == 0) else 0
        result, rec = evaluate_seed(actor, task, overrides, seed, args.balls, device, record=record)
        recording = rec if rec is not None else recording
        results.append(result)
        print(f'seed {seed}: success {result.success_rate:.3f} ({result.successes}/{result.balls}), '
              f'hits {result.hits}, failures {result.reasons}, {result.wall_time_s:.1f} s', flush=True)
    summary = summarise(results, args, actor)
    if args.video is not None and recording is not None:
        frames = render_video(recording, args.video, camera=args.camera)
        summary['video'] = {'path': str(args.video), 'frames': frames, 'fps': VIDEO_FPS,
                            'strokes': recording.outcomes}
    text = json.dumps(summary, indent=2)
    print(text)
    if args.json is not None:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(text + '\n')
    return 0


if __name__ == '__main__':
    sys.exit(main())
