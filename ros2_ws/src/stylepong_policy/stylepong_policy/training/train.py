"""`ros2 run stylepong_policy train`: PPO, or PPO + the adversarial motion prior, in the batched
table-tennis world, then export the actor.

    train --out RUN_DIR [--method ppo|amp|amp-noaug] [--dataset NPZ] [--config YAML] [--iterations N]
          [--num-envs N] [--device cpu|cuda] [--seed S] [--resume [CHECKPOINT_OR_RUN_DIR]]

--method ppo (the default) trains on the task reward with config/ppo.yaml; amp adds the style reward of
a discriminator trained on the reference motions of --dataset (default: a dataset built into the run
directory from the shipped clips in ros2_ws/bags, originals and x2/x3/x5), with config/amp.yaml;
amp-noaug is amp on the original clips only (the paper's "AMP" row). RUN_DIR receives config.yaml (the
effective configuration), checkpoints/ (last.pt every iteration and numbered ones every save_interval),
progress.csv, tensorboard/, and at the end <method>_actor.pt with its sidecar .json, summary.json and
learning_curve.png. `--iterations` is the run's total: the same command with `--resume` continues an
interrupted run up to it (Ctrl-C saves and exports).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import pathlib
import platform
import shlex
import signal
import sys
import time

import torch

from stylepong_policy import paths
from stylepong_policy.rl.config import (
    METHODS,
    ORIGINAL_CLIPS_ONLY,
    AMPConfig,
    TrainConfig,
    config_from_dict,
    load_config,
    method_of,
    save_config,
)
from stylepong_policy.rl.export import current_spec_contract, export_actor
from stylepong_policy.rl.logger import CSV_NAME, plot_learning_curve
from stylepong_policy.rl.runner import CHECKPOINT_DIR, OnPolicyRunner, find_checkpoint, read_checkpoint, seed_everything
from stylepong_sim.world_spec import FIRST_EVALUATION_SEED

PACKAGE = 'stylepong_policy'
SUMMARY_NAME = 'summary.json'
CURVE_NAME = 'learning_curve.png'
CONFIG_NAME = 'config.yaml'
DATASET_NAME = 'dataset.npz'


def actor_name(method: str) -> str:
    """ppo_actor.pt, amp_actor.pt, amp_noaug_actor.pt."""
    return f'{method.replace("-", "_")}_actor.pt'


def default_config_path(method: str = 'ppo') -> pathlib.Path:
    """The shipped config/ppo.yaml (ppo) or config/amp.yaml (amp, amp-noaug): from the installed share
    directory, else beside the sources."""
    name = 'ppo.yaml' if method == 'ppo' else 'amp.yaml'
    try:
        from ament_index_python.packages import get_package_share_directory

        path = pathlib.Path(get_package_share_directory(PACKAGE)) / 'config' / name
        if path.is_file():
            return path
    except (ImportError, LookupError, ValueError, OSError):  # OSError: no AMENT_PREFIX_PATH
        pass
    return paths.CONFIG / name


def shipped_bags_dir() -> pathlib.Path:
    """ros2_ws/bags of the workspace these sources live in (the shipped teaching clips)."""
    return paths.SHIPPED_BAGS


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    """The command line of train."""
    parser = argparse.ArgumentParser(
        prog='train', description=__doc__.split('\n\n')[0], formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument('--out', required=True, type=pathlib.Path, help='run directory')
    parser.add_argument(
        '--method',
        choices=METHODS,
        default=None,
        help='ppo (default), amp, or amp-noaug (amp on the original clips only)',
    )
    parser.add_argument(
        '--dataset',
        type=pathlib.Path,
        help='reference motions for amp (build_dataset .npz; default: built from ros2_ws/bags)',
    )
    parser.add_argument(
        '--config',
        type=pathlib.Path,
        help='YAML config (default: the shipped config/ppo.yaml or config/amp.yaml for the method, '
        "or the run's own when resuming)",
    )
    parser.add_argument('--iterations', type=int, help='total PPO iterations of the run')
    parser.add_argument('--num-envs', type=int, help='parallel environments')
    parser.add_argument('--device', help="torch device: 'cpu' or 'cuda' / 'cuda:N'")
    parser.add_argument('--seed', type=int, help=f'training seed, below {FIRST_EVALUATION_SEED}')
    parser.add_argument(
        '--resume',
        nargs='?',
        const='',
        default=None,
        metavar='CHECKPOINT_OR_RUN_DIR',
        help='continue from a checkpoint (default: the last checkpoint of --out)',
    )
    parser.add_argument(
        '--from',
        dest='start_from',
        type=pathlib.Path,
        metavar='CHECKPOINT',
        help='start from the network of this training checkpoint (a skill to build on; the '
        'optimiser and the discriminator start afresh)',
    )
    parser.add_argument('--no-progress', action='store_true', help='no progress bar')
    parser.add_argument('--no-tensorboard', action='store_true', help='skip TensorBoard event files')
    return parser.parse_args(argv)


def resolve_config(args: argparse.Namespace) -> tuple[TrainConfig, str, str]:
    """(config, where it came from, method): a config file, else (when resuming) the run's own config, else
    the shipped default of the method; then the method and the CLI overrides."""
    if args.config is not None:
        cfg, source = load_config(args.config), str(args.config)
    elif args.resume is not None:
        checkpoint = find_checkpoint(args.resume or args.out)
        cfg, source = config_from_dict(read_checkpoint(checkpoint)['config']), f'{checkpoint} (resumed run)'
    else:
        path = default_config_path(args.method or 'ppo')
        cfg, source = load_config(path), str(path)
    method = args.method or method_of(cfg)
    if method == 'ppo':
        if args.dataset is not None:
            raise ValueError('--dataset is for --method amp or amp-noaug')
        cfg.amp = None
    else:
        cfg.amp = cfg.amp or AMPConfig()
        if method == 'amp-noaug':
            cfg.amp.speed_factors = list(ORIGINAL_CLIPS_ONLY)
        if args.dataset is not None:
            cfg.amp.dataset = str(args.dataset)
    if args.iterations is not None:
        cfg.runner.iterations = args.iterations
    if args.num_envs is not None:
        cfg.task['num_envs'] = args.num_envs
    if args.device is not None:
        cfg.runner.device = args.device
    if args.seed is not None:
        cfg.runner.seed = args.seed
    if args.no_progress:
        cfg.runner.progress_bar = False
    cfg.validate()
    if cfg.runner.seed >= FIRST_EVALUATION_SEED:
        raise ValueError(
            f'training seed {cfg.runner.seed} is in the evaluation range; use a seed below {FIRST_EVALUATION_SEED}'
        )
    if 'num_envs' in cfg.task and int(cfg.task['num_envs']) < 1:
        raise ValueError(f'num_envs must be at least 1, got {cfg.task["num_envs"]}')
    return cfg, source, method


def reference_dataset_path(cfg: AMPConfig, run_dir: pathlib.Path) -> pathlib.Path:
    """The amp config's dataset, or one built into the run directory from the shipped clips (once: a
    resumed run keeps the dataset it started with)."""
    if cfg.dataset:
        path = pathlib.Path(cfg.dataset)
        if not path.is_file():
            raise FileNotFoundError(f'reference dataset {path} does not exist')
        return path
    path = run_dir / DATASET_NAME
    if not path.is_file():
        print(f'train: building the reference motions from {shipped_bags_dir()} into {path}', flush=True)
        build_shipped_dataset(path)
    return path


def build_shipped_dataset(path: pathlib.Path) -> pathlib.Path:
    """build_dataset over the shipped clips (ros2_ws/bags) into `path`; FileNotFoundError if it fails."""
    from stylepong_policy.training import build_dataset

    bags = shipped_bags_dir()
    if build_dataset.build([bags], path) != 0 or not path.is_file():
        raise FileNotFoundError(f'could not build a reference dataset from {bags}; pass --dataset')
    return path


def follow_through_s(amp, env) -> float | None:
    """The stroke's length after its touch for the pose prior (amp.pose_follows_through), or None."""
    if not amp.pose_follows_through:
        return None
    length_s = getattr(env, 'style_follow_through_s', None)
    if length_s is None:
        raise ValueError("amp.pose_follows_through: the env must give its 'style_follow_through_s'")
    return float(length_s)


def make_motion_prior(cfg: TrainConfig, env, run_dir: pathlib.Path, device: torch.device):
    """The discriminator and its reference windows for an amp config."""
    from stylepong_policy.rl.amp import MotionPrior, ReferenceMotion
    from stylepong_policy.rl.pose_prior import PosePrior
    from stylepong_policy.rl.stroke_prior import StrokePrior
    from stylepong_policy.training.dataset import ReferenceDataset

    path = reference_dataset_path(cfg.amp, run_dir)
    dataset = ReferenceDataset.load(path)
    label_names = tuple(getattr(env, 'style_labels', ())) if cfg.amp.condition_on_label else ()
    reference = ReferenceMotion.from_dataset(
        dataset,
        cfg.amp.sequence_length,
        cfg.amp.speed_factors,
        device,
        cfg.amp.frame_features,
        label_names,
        cfg.amp.condition_on_phase,
    )
    print(
        f'train: reference motions {path}: {reference.num_windows} windows of {cfg.amp.sequence_length} frames '
        f'({cfg.amp.frame_features}) '
        f'from clips with speed factors {cfg.amp.speed_factors or "all"}'
        + (f', conditioned on the labels {list(label_names)}' if label_names else '')
        + (', and on the phase (before / after the hit)' if cfg.amp.condition_on_phase else ''),
        flush=True,
    )
    pose_prior = (
        PosePrior.from_dataset(dataset, label_names, cfg.amp.pose_sigma_rad, device, follow_through_s(cfg.amp, env))
        if cfg.amp.w_pose > 0.0
        else None
    )
    stroke_prior = (
        StrokePrior.from_dataset(dataset, label_names, cfg.amp.stroke_sigma_rad, env.num_envs)
        if cfg.amp.w_stroke > 0.0
        else None
    )
    return MotionPrior(
        cfg.amp,
        reference,
        env.num_style_features,
        env.num_envs,
        device,
        seed=cfg.runner.seed,
        pose_prior=pose_prior,
        stroke_prior=stroke_prior,
    ), path


def resolve_device(name: str) -> torch.device:
    """The torch device of a name; ValueError if it is invalid or CUDA is unavailable."""
    try:
        device = torch.device(name)
    except RuntimeError as err:
        raise ValueError(f'invalid device {name!r}: {err}') from err
    if device.type == 'cuda' and not torch.cuda.is_available():
        raise ValueError(
            f'device {name!r} requested but this torch build/machine has no CUDA (torch {torch.__version__})'
        )
    return device


def write_summary(
    runner: OnPolicyRunner,
    run_dir: pathlib.Path,
    config_source: str,
    actor_path: pathlib.Path,
    method: str,
    dataset_path: pathlib.Path | None,
) -> dict:
    """Write the run's summary.json and return it."""
    stats = runner.last_stats
    summary = {
        'method': method,
        'dataset': str(dataset_path) if dataset_path is not None else None,
        'iterations': runner.iteration,
        'samples': runner.env_steps,
        'wall_time_s': round(runner.wall_time_s, 1),
        'wall_time_h': round(runner.wall_time_s / 3600.0, 3),
        'devices': sorted({s['device'] for s in runner.sessions}),
        'sessions': runner.sessions,
        'seed': runner.cfg.runner.seed,
        'num_envs': runner.env.num_envs,
        'config': CONFIG_NAME,
        'config_source': config_source,
        'actor': actor_path.name,
        'final_iteration': {k: (None if isinstance(v, float) and math.isnan(v) else v) for k, v in stats.items()},
        'versions': {'python': platform.python_version(), 'torch': torch.__version__},
    }
    (run_dir / SUMMARY_NAME).write_text(json.dumps(summary, indent=2) + '\n')
    return summary


def _raise_keyboard_interrupt(signum, frame):
    raise KeyboardInterrupt


class TrainError(Exception):
    """A run that cannot start (bad config, dataset, checkpoint or run directory): one line for the user."""


@dataclasses.dataclass
class TrainResult:
    """What train_run leaves: the runner (its iteration, statistics, interruption), the exported actor."""

    runner: OnPolicyRunner
    actor_path: pathlib.Path | None  # None: no iteration completed, nothing exported
    session_s: float  # this session's wall time


def train_run(
    cfg: TrainConfig,
    run_dir: pathlib.Path,
    method: str,
    *,
    config_source: str,
    resume: str | pathlib.Path | None = None,
    start_from: pathlib.Path | None = None,
    tensorboard: bool = True,
    until_wall_time_s: float | None = None,
    on_iteration=None,
    command: str = '',
) -> TrainResult:
    """Train `cfg` into run_dir (a new run, one resumed from `resume` ('' : run_dir's last checkpoint), or one
    starting from the network of `start_from`), up to cfg.runner.iterations or until the run's training time
    reaches until_wall_time_s; then export the actor, summary and curve. Ctrl-C / SIGTERM stop it with the
    last checkpoint kept (result.runner.interrupted). TrainError for what the user must fix."""
    device = resolve_device(cfg.runner.device)
    checkpoint_dir = run_dir / CHECKPOINT_DIR
    if resume is None and checkpoint_dir.is_dir() and any(checkpoint_dir.iterdir()):
        raise TrainError(f'{run_dir} already holds a run; pass --resume to continue it or choose another --out')
    if device.type == 'cpu':
        torch.set_num_threads(cfg.runner.num_threads)
    seed_everything(cfg.runner.seed)

    from stylepong_policy.training import task  # the batched world: imported late so config errors come fast

    try:
        task_cfg = task.TaskConfig(**cfg.task)
    except TypeError as err:
        raise TrainError(f'bad task section in the config: {err}') from err
    env = task.make_env(task_cfg, device, cfg.runner.seed)
    motion_prior = dataset_path = None
    if cfg.amp is not None:
        run_dir.mkdir(parents=True, exist_ok=True)
        try:
            motion_prior, dataset_path = make_motion_prior(cfg, env, run_dir, device)
        except (ValueError, FileNotFoundError, KeyError) as err:
            raise TrainError(str(err)) from err
    runner = OnPolicyRunner(env, cfg, run_dir, tensorboard=tensorboard, motion_prior=motion_prior)
    if resume is not None:
        try:
            loaded = runner.load(resume or run_dir)
        except (ValueError, FileNotFoundError) as err:
            raise TrainError(f'cannot resume: {err}') from err
        print(
            f'train: resumed {loaded} at iteration {runner.iteration} '
            f'({runner.env_steps} samples, {runner.wall_time_s / 3600.0:.2f} h so far)',
            flush=True,
        )
    elif start_from is not None:
        try:
            print(f'train: starting from the network of {runner.start_from(start_from)}', flush=True)
        except (ValueError, FileNotFoundError) as err:
            raise TrainError(f'cannot start from {start_from}: {err}') from err
    run_dir.mkdir(parents=True, exist_ok=True)
    save_config(cfg, run_dir / CONFIG_NAME)
    print(
        f'train: {env.num_envs} envs on {device}, config {config_source}, run dir {run_dir}, '
        f'iterations {runner.iteration} -> {cfg.runner.iterations}',
        flush=True,
    )

    # SIGTERM (a session or job manager stopping us) ends training like Ctrl-C: checkpoint kept, actor exported.
    signal.signal(signal.SIGTERM, _raise_keyboard_interrupt)
    started = time.perf_counter()
    runner.learn(
        cfg.runner.iterations,
        session_info={'command': command},
        until_wall_time_s=until_wall_time_s,
        on_iteration=on_iteration,
    )
    if runner.iteration == 0:
        return TrainResult(runner, None, time.perf_counter() - started)
    actor_path, _ = export_actor(
        runner.actor_critic,
        run_dir / actor_name(method),
        current_spec_contract(),
        training={
            'method': method,
            'iterations': runner.iteration,
            'samples': runner.env_steps,
            'seed': cfg.runner.seed,
            'wall_time_s': round(runner.wall_time_s, 1),
            'config': CONFIG_NAME,
            'devices': sorted({s['device'] for s in runner.sessions}),
            'task': dataclasses.asdict(task_cfg),
        },
    )
    write_summary(runner, run_dir, config_source, actor_path, method, dataset_path)
    if (run_dir / CSV_NAME).is_file():
        plot_learning_curve(
            run_dir / CSV_NAME,
            run_dir / CURVE_NAME,
            title=f'{method.upper()}, seed {cfg.runner.seed}, {env.num_envs} envs',
        )
    return TrainResult(runner, actor_path, time.perf_counter() - started)


def main(argv: list[str] | None = None) -> int:
    """Entry point of the train executable."""
    args = parse_args(argv)
    try:
        cfg, config_source, method = resolve_config(args)
        # Each session of a (resumed, multi-stage) run records the command that ran it, as typed.
        command = shlex.join(['train'] + (sys.argv[1:] if argv is None else list(argv)))
        result = train_run(
            cfg,
            args.out,
            method,
            config_source=config_source,
            resume=args.resume,
            start_from=args.start_from,
            tensorboard=not args.no_tensorboard,
            command=command,
        )
    except (TrainError, ValueError, FileNotFoundError) as err:
        print(f'train: {err}', file=sys.stderr)
        return 2
    runner = result.runner
    if result.actor_path is None:
        print('train: no iteration completed; nothing to export', file=sys.stderr)
        return 130 if runner.interrupted else 1
    success = runner.last_stats.get('success_rate', math.nan)
    print(
        f'train: iteration {runner.iteration}, {runner.env_steps} samples, '
        f'success {"n/a (no ball decided)" if math.isnan(success) else f"{success:.3f}"}, this session '
        f'{result.session_s:.1f} s, whole run {runner.wall_time_s:.1f} s; '
        f'actor {result.actor_path} (+ {result.actor_path.with_suffix(".json").name})',
        flush=True,
    )
    if runner.interrupted:
        print('train: interrupted; resume with --resume', file=sys.stderr)
        return 130
    return 0


if __name__ == '__main__':
    sys.exit(main())
