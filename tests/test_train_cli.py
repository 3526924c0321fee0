"""`ros2 run stylepong_policy train` and `evaluate` end to end, as a user runs them (the checks of
docs/ACCEPTANCE.md, for train and evaluate)."""

import json
import signal
import subprocess
import time

import pytest

from stylepong_common.node_process import NodeProcess, wait_until

TRAIN_LIMIT_S = 120.0  # the bound for `train --iterations 2 --num-envs 256` (docs/ACCEPTANCE.md)


def ros2_run(executable: str, *args: str, env: dict, timeout_s: float) -> subprocess.CompletedProcess:
    return subprocess.run(
        ['ros2', 'run', 'stylepong_policy', executable, *args],
        env=env,
        capture_output=True,
        text=True,
        timeout=timeout_s,
    )


@pytest.mark.slow  # over 20 s on the 2-core machine: .ci/run runs it, `make test` skips it
def test_train_two_iterations_then_evaluate_and_resume(tmp_path, ros_env):
    run_dir = tmp_path / 'run'
    started = time.monotonic()
    train = ros2_run(
        'train',
        '--iterations',
        '2',
        '--num-envs',
        '256',
        '--out',
        str(run_dir),
        '--no-progress',
        env=ros_env,
        timeout_s=TRAIN_LIMIT_S + 60,
    )
    elapsed_s = time.monotonic() - started
    assert train.returncode == 0, train.stdout + train.stderr
    assert elapsed_s < TRAIN_LIMIT_S, f'train took {elapsed_s:.1f} s'
    for name in (
        'ppo_actor.pt',
        'ppo_actor.json',
        'config.yaml',
        'summary.json',
        'learning_curve.png',
        'progress.csv',
        'checkpoints/last.pt',
    ):
        assert (run_dir / name).is_file(), name
    summary = json.loads((run_dir / 'summary.json').read_text())
    assert summary['iterations'] == 2 and summary['samples'] == 2 * 24 * 256
    assert summary['wall_time_s'] > 0 and summary['devices'][0].startswith('cpu')

    out_json = tmp_path / 'eval.json'
    evaluate = ros2_run(
        'evaluate',
        '--actor',
        str(run_dir / 'ppo_actor.pt'),
        '--seeds',
        '2',
        '--first-seed',
        '1000',
        '--balls',
        '16',
        '--speed',
        'high',
        '--json',
        str(out_json),
        '--video',
        str(tmp_path / 'strokes.mp4'),
        '--video-strokes',
        '1',
        env=ros_env,
        timeout_s=180,
    )
    assert evaluate.returncode == 0, evaluate.stdout + evaluate.stderr
    result = json.loads(out_json.read_text())
    assert result['seeds'] == [1000, 1001] and result['balls'] == 32 and len(result['per_seed']) == 2
    assert 0.0 <= result['success_rate'] <= 1.0 and 0.0 <= result['hit_rate'] <= 1.0
    successes = round(sum(result['per_seed']) * 16)
    assert successes + sum(result['failures'].values()) == 32
    assert '"success_rate"' in evaluate.stdout
    assert result['video']['frames'] > 30 and (tmp_path / 'strokes.mp4').stat().st_size > 10_000

    # A second command continues the same run (its own config, from the last checkpoint) to 3 iterations.
    resume = ros2_run(
        'train',
        '--out',
        str(run_dir),
        '--resume',
        '--iterations',
        '3',
        '--num-envs',
        '256',
        '--no-progress',
        env=ros_env,
        timeout_s=TRAIN_LIMIT_S + 60,
    )
    assert resume.returncode == 0, resume.stdout + resume.stderr
    assert 'resumed' in resume.stdout
    summary = json.loads((run_dir / 'summary.json').read_text())
    assert summary['iterations'] == 3 and len(summary['sessions']) == 2
    rows = (run_dir / 'progress.csv').read_text().strip().splitlines()
    assert len(rows) == 1 + 3

    # Without --resume the same run directory is refused rather than overwritten.
    again = ros2_run('train', '--iterations', '1', '--num-envs', '8', '--out', str(run_dir), env=ros_env, timeout_s=60)
    assert again.returncode == 2 and '--resume' in again.stderr


def test_evaluate_refuses_an_actor_without_its_sidecar(tmp_path, ros_env):
    bogus = tmp_path / 'actor.pt'
    bogus.write_bytes(b'not a model')
    result = ros2_run('evaluate', '--actor', str(bogus), '--seeds', '1', '--balls', '4', env=ros_env, timeout_s=60)
    assert result.returncode == 2 and 'sidecar' in result.stderr


def test_train_rejects_an_evaluation_seed(tmp_path, ros_env):
    result = ros2_run('train', '--seed', '1000', '--out', str(tmp_path / 'r'), env=ros_env, timeout_s=60)
    assert result.returncode == 2 and 'evaluation range' in result.stderr


@pytest.mark.slow  # over 7 s on the 2-core machine: .ci/run runs it, `make test` skips it
def test_ctrl_c_saves_a_checkpoint_and_exports(tmp_path, ros_env):
    run_dir = tmp_path / 'run'
    train = NodeProcess(
        'stylepong_policy',
        'train',
        '--iterations',
        '1000',
        '--num-envs',
        '64',
        '--out',
        str(run_dir),
        '--no-progress',
        '--no-tensorboard',
        env=ros_env,
    ).start()
    try:
        assert wait_until(lambda: _iterations_logged(run_dir) >= 2, timeout_s=120, period_s=0.2), train.output()
        train.signal(signal.SIGINT)
        train.process.wait(60)
    finally:
        code = train.stop()
    assert code == 130, train.output()
    summary = json.loads((run_dir / 'summary.json').read_text())
    assert summary['iterations'] >= 2
    assert (run_dir / 'ppo_actor.pt').is_file() and 'resume with --resume' in train.output()


def _iterations_logged(run_dir) -> int:
    try:
        return len((run_dir / 'progress.csv').read_text().strip().splitlines()) - 1
    except OSError:
        return 0
