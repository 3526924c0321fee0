"""The experiment behind the amp section's frame_features: what a discriminator that sees joint positions
and velocities (q_qdot) or positions only (q) makes of a trained actor's motion.

    ros2 run stylepong_policy amp_frame_features [--actor ros2_ws/src/stylepong_policy/models/amp_actor.pt]
                                        [--out results/amp_frame_features.md] [--lengths 4,8]

The actor (deterministic) plays --envs balls of validation seed --seed in the nominal batched world for
--steps policy steps; every window of L consecutive arm states inside one episode is a negative. For
each L and feature set, a fresh discriminator (config/amp.yaml's network, normaliser, weight decay,
gradient penalty and learning rate; batch 2048) trains --train-steps LSGAN steps against the demonstration
windows of the dataset built from ros2_ws/bags (all speed factors) on 80 % of the actor's windows, then
scores the other 20 %:
  accuracy      balanced accuracy (0.5 = chance) on the held-out windows and fresh reference windows;
  d (policy)    the median and 10/90 % quantiles of D on the held-out actor windows;
  reward 0      the share of them whose style reward (AMP's max(0, 1 - (d - 1)^2 / 4)) is 0;
  rank corr.    Spearman's rank correlation between D and minus the distance to the nearest
                demonstration window in joint positions (rad, root mean square over the window's frames):
                how well the reward orders the actor's motion by how far it is from the demonstrations,
                which is what the DTW distance of Table II measures.
Written as Markdown by this script; nothing in it is typed by hand.
"""

from __future__ import annotations

import argparse
import pathlib
import sys
import tempfile

import torch

from stylepong_common.command_line import write_lines
from stylepong_policy import paths

FEATURES = ('q_qdot', 'q')


def actor_windows(actor_path: pathlib.Path, envs: int, steps: int, seed: int, length: int) -> torch.Tensor:
    """Windows [W, L, 12] of (q, qdot) of the actor's episodes in the nominal world; none crosses two."""
    from stylepong_policy.rl.export import load_actor
    from stylepong_policy.training import task

    actor = load_actor(actor_path)
    env = task.make_env(task.TaskConfig(num_envs=envs, randomize=False), 'cpu', seed)
    obs, _ = env.reset()
    frames, ended = [env.style_state().clone()], []
    with torch.inference_mode():
        for _ in range(steps):
            obs, _, _, dones, extras = env.step(actor(obs))
            frames.append(extras['style_state'].clone())  # before the reset: still the ended episode's
            ended.append(dones)
    return episode_windows(torch.stack(frames), torch.stack(ended), length)


def episode_windows(frames: torch.Tensor, ended: torch.Tensor, length: int) -> torch.Tensor:
    """Every window [W, L, D] of `length` consecutive frames inside one episode.

    frames [T + 1, N, D]: frame 0 at the reset, frame t after step t (before that step's reset);
    ended [T, N]: whether step t + 1 ended the environment's episode.
    """
    # Frame t belongs to the episode after as many ends as the steps before it (1 .. t - 1) had.
    episode = torch.cat((torch.zeros(2, frames.shape[1], dtype=torch.long), ended[:-1].long().cumsum(0)))
    windows = []
    for end in range(length - 1, frames.shape[0]):
        span = slice(end - length + 1, end + 1)
        inside = (episode[span] == episode[end]).all(0)
        windows.append(frames[span].permute(1, 0, 2)[inside])
    return torch.cat(windows)


def nearest_demonstration_rad(windows: torch.Tensor, reference: torch.Tensor) -> torch.Tensor:
    """Per window [W, L, 12]: the distance in joint positions to the nearest reference window [R, L, 12],
    root mean square over the frames (rad)."""
    joints = windows.shape[-1] // 2
    a, b = windows[..., :joints].flatten(1), reference[..., :joints].flatten(1)
    return torch.cdist(a, b).min(1).values / windows.shape[1] ** 0.5


def rank_correlation(x: torch.Tensor, y: torch.Tensor) -> float:
    """Spearman's rank correlation (no ties expected in continuous scores)."""
    ranks = torch.stack((x.argsort().argsort(), y.argsort().argsort())).double()
    return float(torch.corrcoef(ranks)[0, 1])


def measure(dataset, windows: torch.Tensor, length: int, features: str, train_steps: int, seed: int) -> dict:
    """Train a fresh discriminator on these actor windows against the demonstrations; score held-out ones."""
    from stylepong_policy.rl.amp import MotionPrior, ReferenceMotion, feature_columns, style_reward
    from stylepong_policy.rl.config import load_config
    from stylepong_policy.training.train import default_config_path

    torch.manual_seed(seed)
    cfg = load_config(default_config_path('amp')).amp
    cfg.sequence_length, cfg.frame_features, cfg.batch_size, cfg.updates_per_iteration = length, features, 2048, 1
    reference = ReferenceMotion.from_dataset(dataset, length, None, 'cpu', features)
    prior = MotionPrior(cfg, reference, windows.shape[-1], num_envs=1, device='cpu', seed=seed)
    columns = feature_columns(features, windows.shape[-1])
    order = torch.randperm(windows.shape[0])
    split = int(0.8 * len(order))
    train, held_out = windows[order[:split]], windows[order[split:]]
    for _ in range(train_steps):
        prior.replay.size = 0
        prior.replay.insert(train[torch.randint(split, (cfg.batch_size,))][..., columns])
        prior.update()
    held_out = held_out[torch.randperm(held_out.shape[0])[:4000]]
    full_reference = ReferenceMotion.from_dataset(dataset, length)
    with torch.no_grad():
        d_reference = prior.discriminator.score(reference.sample(4000))
        d_policy = prior.discriminator.score(held_out[..., columns])
        distance = nearest_demonstration_rad(held_out, full_reference.windows(torch.arange(full_reference.num_windows)))
    quantiles = d_policy.quantile(torch.tensor([0.1, 0.5, 0.9])).tolist()
    return {
        'accuracy': 0.5 * float((d_reference > 0).float().mean() + (d_policy < 0).float().mean()),
        'd_policy': quantiles,
        'reward_zero': float((style_reward(d_policy) == 0).float().mean()),
        'rank_correlation': rank_correlation(d_policy, -distance),
        'distance_median_rad': float(distance.median()),
        'windows': int(windows.shape[0]),
    }


def main(argv: list[str] | None = None) -> int:
    """Measure each window length and feature set and write the results page."""
    parser = argparse.ArgumentParser(prog='amp_frame_features', description=__doc__.split('\n\n')[0])
    parser.add_argument('--actor', type=pathlib.Path, default=paths.MODELS / 'amp_actor.pt')
    parser.add_argument('--out', type=pathlib.Path, default=paths.RESULTS / 'amp_frame_features.md')
    parser.add_argument('--lengths', default='4,8')
    parser.add_argument('--envs', type=int, default=512)
    parser.add_argument('--steps', type=int, default=130, help='policy steps per environment (60 Hz)')
    parser.add_argument('--seed', type=int, default=900, help='validation seed of the balls (< 1000)')
    parser.add_argument('--train-steps', type=int, default=400)
    args = parser.parse_args(argv)
    if args.seed >= 1000:
        parser.error('--seed must be a validation seed below 1000')
    torch.set_num_threads(2)
    from stylepong_policy.training.dataset import ReferenceDataset
    from stylepong_policy.training.train import build_shipped_dataset

    with tempfile.TemporaryDirectory() as tmp:
        dataset = ReferenceDataset.load(build_shipped_dataset(pathlib.Path(tmp) / 'dataset.npz'))
    rows = []
    for length in [int(x) for x in args.lengths.split(',')]:
        windows = actor_windows(args.actor, args.envs, args.steps, args.seed, length)
        for features in FEATURES:
            row = measure(dataset, windows, length, features, args.train_steps, seed=0)
            rows.append((length, features, row))
            print(f'L={length} {features}: {row}', file=sys.stderr, flush=True)
    try:
        actor = args.actor.resolve().relative_to(paths.REPOSITORY).as_posix()
    except ValueError:
        actor = args.actor.name
    lines = [
        '# Discriminator inputs: joint positions and velocities, or positions only',
        '',
        f'Written by `ros2 run stylepong_policy amp_frame_features` (see its docstring). Actor `{actor}`, '
        f'deterministic, {args.envs} balls of validation seed {args.seed}, {args.steps} policy steps each, '
        f'nominal batched world; a fresh discriminator per row, {args.train_steps} LSGAN steps against the '
        'demonstration windows (dataset built from `ros2_ws/bags`, all speed factors), scored on held-out '
        'actor windows; CPU.',
        '',
        '| L (frames at 60 Hz) | features | balanced accuracy | D on the actor: 10 % / median / 90 % | '
        'style reward 0 | rank corr. of D with closeness to a demonstration | actor windows |',
        '|---|---|---|---|---|---|---|',
    ]
    for length, features, row in rows:
        q10, q50, q90 = row['d_policy']
        lines.append(
            f'| {length} | `{features}` | {row["accuracy"]:.3f} | {q10:+.2f} / {q50:+.2f} / {q90:+.2f} | '
            f'{row["reward_zero"]:.2f} | {row["rank_correlation"]:+.3f} | {row["windows"]} |'
        )
    lines += [
        '',
        'Closeness: minus the distance in joint positions to the nearest demonstration window (rad, root '
        'mean square over the frames); its median over the held-out windows was '
        + ', '.join(f'{r["distance_median_rad"]:.3f} (L = {n})' for n, f, r in rows if f == FEATURES[0])
        + ' rad.',
    ]
    write_lines(args.out, lines)
    return 0


if __name__ == '__main__':
    sys.exit(main())
