"""The progress CSV: columns that appear late are kept, and a resume never leaves two histories."""

import math

from stylepong_policy.rl.logger import TrainingLog, read_progress


def _log(run_dir, start_iteration=0):
    return TrainingLog(run_dir, start_iteration=start_iteration, tensorboard=False)


def test_a_column_first_seen_later_widens_the_file(tmp_path):
    log = _log(tmp_path)
    log.write({'iteration': 1, 'loss': 0.5})
    log.write({'iteration': 2, 'loss': 0.4, 'episode/success': 0.25})
    log.close()
    progress = read_progress(tmp_path / 'progress.csv')
    assert progress['iteration'] == [1.0, 2.0]
    assert math.isnan(progress['episode/success'][0])
    assert progress['episode/success'][1] == 0.25


def test_resume_drops_rows_past_the_checkpoint_and_keeps_every_column(tmp_path):
    log = _log(tmp_path)
    for iteration in range(1, 6):
        log.write({'iteration': iteration, 'loss': 1.0 / iteration, 'episode/success': iteration / 10})
    log.close()
    resumed = _log(tmp_path, start_iteration=3)
    resumed.write({'iteration': 4, 'loss': 0.3})
    resumed.write({'iteration': 5, 'loss': 0.2, 'episode/success': 0.9, 'style/reward': 0.7})
    resumed.close()
    progress = read_progress(tmp_path / 'progress.csv')
    assert progress['iteration'] == [1.0, 2.0, 3.0, 4.0, 5.0]
    assert progress['loss'][3:] == [0.3, 0.2]
    assert progress['episode/success'][:3] == [0.1, 0.2, 0.3]
    assert math.isnan(progress['episode/success'][3])
    assert progress['style/reward'][4] == 0.7 and math.isnan(progress['style/reward'][0])
