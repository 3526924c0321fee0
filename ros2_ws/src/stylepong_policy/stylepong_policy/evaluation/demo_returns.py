"""Would the demonstrated strokes return a ball? Every clip of the reference dataset, and for contrast
strokes of a trained actor that did return their balls, replayed against incoming balls.

    ros2 run stylepong_policy demo_returns [--dataset results/reference_dataset.npz] [--out results/demo_returns.md]
                                  [--actor ros2_ws/src/stylepong_policy/models/amp_actor.pt]

Each sequence of joint positions is played as the joint targets of the nominal batched world against
--balls balls of validation seed --seed (all speeds), each ball at every start time that puts the
sequence's fastest frame 20-65 policy periods (0.33-1.08 s) after the launch, where the balls arrive
(stylepong_policy.evaluation.demo_replay). The actor's strokes are its first --actor-strokes returned strokes on the
same seed, from the launch to 0.3 s after the hit (`evaluate`'s strokes). Written as Markdown by this
script; nothing in it is typed by hand.
"""

from __future__ import annotations

import argparse
import collections
import os
import pathlib
import sys
import time

from stylepong_policy import paths

HIT_STEPS = range(20, 66)


def verdict_text(verdicts: dict[str, int]) -> str:
    """'own_side 70%, out 20%, ...': the share of each verdict, largest first."""
    total = sum(verdicts.values())
    ranked = sorted(verdicts.items(), key=lambda item: -item[1])
    return ', '.join(f'{name} {count / total:.0%}' for name, count in ranked) if total else '-'


def replayed(sequences: list[tuple[str, object]], balls: int, seed: int, speed_range) -> list[tuple[str, int, object]]:
    """(name, frames, ReplayOutcome) of each named joint-position sequence."""
    from stylepong_policy.evaluation import demo_replay

    return [
        (name, len(q), demo_replay.replay_clip(q, balls, list(HIT_STEPS), seed, speed_range)) for name, q in sequences
    ]


def table(rows: list[tuple[str, int, object]], first_column: str) -> list[str]:
    """The Markdown table of replayed sequences."""
    lines = [
        f'| {first_column} | frames | balls hit | balls returned | returned / hit (ball, start) pairs '
        '| verdicts of the hits |',
        '|---|---|---|---|---|---|',
    ]
    for name, frames, outcome in rows:
        pairs = sum(outcome.hit_verdicts.values())
        lines.append(
            f'| {name} | {frames} | {outcome.hit_rate:.0%} | {outcome.return_rate:.0%} | '
            f'{outcome.hit_verdicts.get("returned", 0)} / {pairs} | {verdict_text(outcome.hit_verdicts)} |'
        )
    return lines


def total_line(label: str, rows: list[tuple[str, int, object]]) -> str:
    """One summary bullet: how many of all the (ball, start) pairs that hit returned the ball."""
    verdicts = collections.Counter()
    for _, _, outcome in rows:
        verdicts.update(outcome.hit_verdicts)
    return (
        f'- {label}: {verdicts.get("returned", 0)} of {sum(verdicts.values())} (ball, start) pairs that hit '
        f'the ball returned it; verdicts {verdict_text(dict(verdicts))}.'
    )


def repo_path(path: pathlib.Path) -> pathlib.Path:
    """The path relative to the repository when inside it (never an absolute path in the output)."""
    resolved = path.resolve()
    return resolved.relative_to(paths.REPOSITORY) if resolved.is_relative_to(paths.REPOSITORY) else path


def main(argv: list[str] | None = None) -> int:
    """Replay every clip and the actor's strokes, write the Markdown."""
    parser = argparse.ArgumentParser(prog='demo_returns', description=__doc__.split('\n\n')[0])
    parser.add_argument('--dataset', type=pathlib.Path, default=paths.RESULTS / 'reference_dataset.npz')
    parser.add_argument('--actor', type=pathlib.Path, default=paths.MODELS / 'amp_actor.pt')
    parser.add_argument('--actor-strokes', type=int, default=10)
    parser.add_argument('--balls', type=int, default=100)
    parser.add_argument('--seed', type=int, default=900)
    parser.add_argument('--out', type=pathlib.Path, default=paths.RESULTS / 'demo_returns.md')
    args = parser.parse_args(argv)
    if args.seed >= 1000:
        parser.error('an analysis runs on validation seeds (below 1000)')

    import torch

    from stylepong_policy.evaluation import evaluate
    from stylepong_policy.training.dataset import ReferenceDataset
    from stylepong_sim import world_spec

    torch.set_num_threads(1)
    started = time.perf_counter()
    speed_range = tuple(world_spec.SPEED_RANGES_M_S['all'])
    dataset = ReferenceDataset.load(args.dataset)
    demo_rows = replayed(
        [
            (f'{dataset.label[i]} x{int(dataset.speed_factor[i])} (clip {i})', dataset.clip(i).q)
            for i in range(dataset.num_clips)
        ],
        args.balls,
        args.seed,
        speed_range,
    )
    result = evaluate.evaluate_seed(evaluate.load_actor(args.actor), args.seed, args.balls, 'cpu')
    returned = [s for s in result.strokes if s.success][: args.actor_strokes]
    actor_rows = replayed(
        [(f'{s.direction}, ball {s.ball}', s.joint_positions_rad) for s in returned], args.balls, args.seed, speed_range
    )

    actor_name, dataset_name = repo_path(args.actor), repo_path(args.dataset)
    lines = [
        '# Would the demonstrated strokes return a ball?',
        '',
        f'Written by `ros2 run stylepong_policy demo_returns --dataset {dataset_name} --actor {actor_name} '
        f'--balls {args.balls} --seed {args.seed} --actor-strokes {args.actor_strokes}` '
        f'in {time.perf_counter() - started:.0f} s ({os.cpu_count()} CPU cores, 1 torch thread).',
        '',
        'Setting: nominal batched world (no randomisation, no sensing noise). Each sequence of joint positions '
        'is played, one frame per policy period, as the joint targets of the servo against '
        f'{args.balls} balls of validation seed {args.seed} (all speeds), each ball at {len(HIT_STEPS)} start '
        f"times that put the sequence's fastest frame {HIT_STEPS.start}-{HIT_STEPS.stop - 1} policy "
        'periods after the launch; a ball counts as hit or returned when one start time or more does '
        "so (`stylepong_policy.evaluation.demo_replay`). The verdicts are the referee's, over every "
        '(ball, start) pair '
        "whose paddle touched the ball (`own_side`: struck down onto the robot's own half).",
        '',
        '## Summary',
        '',
        total_line(f'The {dataset.num_clips} demonstration clips of `{dataset_name}`', demo_rows),
        total_line(f'{len(actor_rows)} strokes of `{actor_name}` that returned their own balls', actor_rows),
        '',
        '## Demonstration clips (originals and their x2/x3/x5 speed-ups)',
        '',
        *table(demo_rows, 'clip'),
        '',
        f'## Strokes of `{actor_name}` that returned their balls (validation seed {args.seed})',
        '',
        *table(actor_rows, 'stroke'),
        '',
    ]
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text('\n'.join(lines))
    print(f'wrote {args.out}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
