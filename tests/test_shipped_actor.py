"""The shipped PPO actor still earns the figure shipped beside it.

models/ppo_eval_all.json holds `evaluate`'s per-seed success rates of models/ppo_actor.pt (seeds
1000-1009, 200 balls each, all speeds, nominal world). This runs the same command for seed 1000 and
compares: a change to the world, the task, the spec or the actor that changes what the actor does shows
up here. A few seconds.
"""

import json
import pathlib
import subprocess

MODELS = pathlib.Path(__file__).resolve().parents[1] / 'ros2_ws' / 'src' / 'stylepong_policy' / 'models'
SEED = 1000
BALLS = 200
# The evaluation is deterministic on one machine (measured: identical to the shipped figure); a different
# CPU's float rounding may turn one ball of the 200.
TOLERANCE = 1.0 / BALLS


def test_the_shipped_actor_scores_its_shipped_figure_on_seed_1000(tmp_path):
    shipped = json.loads((MODELS / 'ppo_eval_all.json').read_text())
    assert shipped['balls_per_seed'] == BALLS and shipped['speed'] == 'all' and not shipped['randomize']
    expected = shipped['per_seed'][shipped['seeds'].index(SEED)]
    out = tmp_path / 'eval.json'
    balls = f'--seeds 1 --first-seed {SEED} --balls {BALLS}'.split()
    result = subprocess.run(
        [
            'ros2',
            'run',
            'stylepong_policy',
            'evaluate',
            '--actor',
            str(MODELS / 'ppo_actor.pt'),
            *balls,
            '--json',
            str(out),
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert result.returncode == 0, result.stdout + result.stderr
    measured = json.loads(out.read_text())
    assert measured['seeds'] == [SEED] and measured['balls'] == BALLS
    print(f'seed {SEED}: success {measured["per_seed"][0]} (shipped {expected})')
    assert abs(measured['per_seed'][0] - expected) <= TOLERANCE + 1e-9, (measured['per_seed'], expected)
