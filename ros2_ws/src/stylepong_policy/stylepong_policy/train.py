"""`ros2 run stylepong_policy train`: PPO in the batched table-tennis world, then export the actor.

    train --out RUN_DIR [--config YAML] [--iterations N] [--num-envs N] [--device cpu|cuda] [--seed S]
          [--resume [CHECKPOINT_OR_RUN_DIR]]

RUN_DIR receives config.yaml (the effective configuration), checkpoints/ (last.pt every iteration and
numbered ones every save_interval), progress.csv, tensorboard/, and at the end ppo_actor.pt with its
sidecar ppo_actor.json, summary.json and learning_curve.png. `--iterations` is the run's total: the
same command with `--resume` continues an interrupted run up to it (Ctrl-C saves and exports).
"""
from __future__ import annotations

import os

# Before torch loads OpenMP: idle OpenMP threads sleep instead of spinning. On 2 cores shared with other
# work, spinning threads made a PPO update 4-5x slower than one thread; sleeping ones cost ~nothing.
os.environ.setdefault('OMP_WAIT_POLICY', 'PASSIVE')

import argparse
import dataclasses
import json
import math
import pathlib
import platform
import signal
import sys
import time

import torch

from stylepong_policy.rl.config import FIRST_EVALUATION_SEED, TrainConfig, load_config, save_config, config_from_dict
from stylepong_policy.rl.export import current_spec_contract, export_actor
from stylepong_policy.rl.logger import CSV_NAME, plot_learning_curve
from stylepong_policy.rl.runner import (CHECKPOINT_DIR, OnPolicyRunner, find_checkpoint, read_checkpoint,
                                        seed_everything)

PACKAGE = 'stylepong_policy'
ACTOR_NAME = 'ppo_actor.pt'
SUMMARY_NAME = 'summary.json'
CURVE_NAME = 'learning_curve.png'
CONFIG_NAME = 'config.yaml'


def default_config_path() -> pathlib.Path:
    """The shipped config/ppo.yaml: from the installed share directory, else beside the sources."""
    try:
        from ament_index_python.packages import get_package_share_directory
        path = pathlib.Path(get_package_share_directory(PACKAGE)) / 'config' / 'ppo.yaml'
        if path.is_file():
            return path
    except (ImportError, LookupError, ValueError):
        pass
    return pathlib.Path(__file__).resolve().parent.parent / 'config' / 'ppo.yaml'


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog='train', description=__doc__.split('\n\n')[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--out', required=True, type=pathlib.Path, help='run directory')
    parser.add_argument('--config', type=pathlib.Path,
                        help='YAML config (default: the shipped config/ppo.yaml, or the run\'s own when resuming)')
    parser.add_argument('--iterations', type=int, help='total PPO iterations of the run')
    parser.add_argument('--num-envs', type=int, help='parallel environments')
    parser.add_argument('--device', help="torch device: 'cpu' or 'cuda' / 'cuda:N'")
    parser.add_argument('--seed', type=int, help=f'training seed, below {FIRST_EVALUATION_SEED}')
    parser.add_argument('--resume', nargs='?', const='', default=None, metavar='CHECKPOINT_OR_RUN_DIR',
                        help='continue from a checkpoint (default: the last checkpoint of --out)')
    parser.add_argument('--no-progress', action='store_true', help='no progress bar')
    parser.add_argument('--no-tensorboard', action='store_true', help='skip TensorBoard event files')
    return parser.parse_args(argv)


def resolve_config(args: argparse.Namespace) -> tuple[TrainConfig, str]:
    """Config file, else (when resuming) the run's own config, else the shipped default; then CLI overrides."""
    if args.config is not None:
        cfg, source = load_config(args.config), str(args.config)
    elif args.resume is not None:
        checkpoint = find_checkpoint(args.resume or args.out)
        cfg, source = config_from_dict(read_checkpoint(checkpoint)['config']), f'{checkpoint} (resumed run)'
    else:
        path = default_config_path()
        cfg, source = load_config(path), str(path)
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
        raise ValueError(f'training seed {cfg.runner.seed} is in the evaluation range; use a seed below '
                         f'{FIRST_EVALUATION_SEED}')
    if 'num_envs' in cfg.task and int(cfg.task['num_envs']) < 1:
        raise ValueError(f'num_envs must be at least 1, got {cfg.task["num_envs"]}')
    return cfg, source


def resolve_device(name: str) -> torch.device:
    try:
        device = torch.device(name)
    except RuntimeError as err:
        raise ValueError(f'invalid device {name!r}: {err}') from err
    if device.type == 'cuda' and not torch.cuda.is_available():
        raise ValueError(f'device {name!r} requested but this torch build/machine has no CUDA '
                         f'(torch {torch.__version__})')
    return device


def write_summary(runner: OnPolicyRunner, run_dir: pathlib.Path, config_source: str, actor_path: pathlib.Path) -> dict:
    stats = runner.last_stats
    summary = {
        'iterations': runner.iteration, 'samples': runner.env_steps,
        'wall_time_s': round(runner.wall_time_s, 1), 'wall_time_h': round(runner.wall_time_s / 3600.0, 3),
        'devices': sorted({s['device'] for s in runner.sessions}), 'sessions': runner.sessions,
        'seed': runner.cfg.runner.seed, 'num_envs': runner.env.num_envs, 'config': CONFIG_NAME,
        'config_source': config_source, 'actor': actor_path.name,
        'final_iteration': {k: (None if isinstance(v, float) and math.isnan(v) else v) for k, v in stats.items()},
        'versions': {'python': platform.python_version(), 'torch': torch.__version__},
    }
    (run_dir / SUMMARY_NAME).write_text(json.dumps(summary, indent=2) + '\n')
    return summary


def _raise_keyboard_interrupt(signum, frame):
    raise KeyboardInterrupt


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    try:
        cfg, config_source = resolve_config(args)
        device = resolve_device(cfg.runner.device)
    except (ValueError, FileNotFoundError) as err:
        print(f'train: {err}', file=sys.stderr)
        return 2
    run_dir = args.out
    checkpoint_dir = run_dir / CHECKPOINT_DIR
    if args.resume is None and checkpoint_dir.is_dir() and any(checkpoint_dir.iterdir()):
        print(f'train: {run_dir} already holds a run; pass --resume to continue it or choose another --out',
              file=sys.stderr)
        return 2
    if device.type == 'cpu':
        torch.set_num_threads(cfg.runner.num_threads)
    seed_everything(cfg.runner.seed)

    from stylepong_policy import task   # the batched world: imported late so config errors come fast
    try:
        task_cfg = task.TaskConfig(**cfg.task)
    except TypeError as err:
        print(f'train: bad task section in the config: {err}', file=sys.stderr)
        return 2
    env = task.make_env(task_cfg, device, cfg.runner.seed)
    runner = OnPolicyRunner(env, cfg, run_dir, failure_reasons=task.FAILURE_REASONS,
                            tensorboard=not args.no_tensorboard)
    if args.resume is not None:
        try:
            loaded = runner.load(args.resume or run_dir)
        except (ValueError, FileNotFoundError) as err:
            print(f'train: cannot resume: {err}', file=sys.stderr)
            return 2
        print(f'train: resumed {loaded} at iteration {runner.iteration} '
              f'({runner.env_steps} samples, {runner.wall_time_s / 3600.0:.2f} h so far)', flush=True)
    run_dir.mkdir(parents=True, exist_ok=True)
    save_config(cfg, run_dir / CONFIG_NAME)
    print(f'train: {env.num_envs} envs on {device}, config {config_source}, run dir {run_dir}, '
          f'iterations {runner.iteration} -> {cfg.runner.iterations}', flush=True)

    # SIGTERM (a session or job manager stopping us) ends training like Ctrl-C: checkpoint kept, actor exported.
    signal.signal(signal.SIGTERM, _raise_keyboard_interrupt)
    started = time.perf_counter()
    runner.learn(cfg.runner.iterations)
    if runner.iteration == 0:
        print('train: no iteration completed; nothing to export', file=sys.stderr)
        return 130 if runner.interrupted else 1

    actor_path, sidecar = export_actor(
        runner.actor_critic, run_dir / ACTOR_NAME, current_spec_contract(),
        training={'iterations': runner.iteration, 'samples': runner.env_steps, 'seed': cfg.runner.seed,
                  'wall_time_s': round(runner.wall_time_s, 1), 'config': CONFIG_NAME,
                  'devices': sorted({s['device'] for s in runner.sessions}),
                  'task': dataclasses.asdict(task_cfg)})
    write_summary(runner, run_dir, config_source, actor_path)
    if (run_dir / CSV_NAME).is_file():
        plot_learning_curve(run_dir / CSV_NAME, run_dir / CURVE_NAME,
                            title=f'PPO, seed {cfg.runner.seed}, {env.num_envs} envs')
    stats = runner.last_stats
    success = stats.get('success_rate', math.nan)
    print(f'train: iteration {runner.iteration}, {runner.env_steps} samples, '
          f'success {"n/a (no ball decided)" if math.isnan(success) else f"{success:.3f}"}, this session '
          f'{time.perf_counter() - started:.1f} s, whole run {runner.wall_time_s:.1f} s; '
          f'actor {actor_path} (+ {sidecar.name})', flush=True)
    if runner.interrupted:
        print('train: interrupted; resume with --resume', file=sys.stderr)
        return 130
    return 0


if __name__ == '__main__':
    sys.exit(main())
