"""learn_style end to end on a tiny budget (the shipped clips in, an actor, its files and a report out), its
resume, and the rules it chooses and budgets by. The recipe is config/amp.yaml with a small batch and the
evaluations shrunk, so that every stage runs in seconds."""

import json
import pathlib
import subprocess
import sys
import time

import numpy as np
import pytest
import torch

from stylepong_policy.reports import style_report
from stylepong_policy.rl.export import load_actor, read_sidecar
from stylepong_policy.training import learn_style, skills

BAGS = pathlib.Path(__file__).resolve().parents[3] / 'bags'


def tiny_recipe(device):
    cfg, path = REAL_RECIPE(device)
    cfg.task.update(num_envs=32, compile_world=False)
    cfg.ppo.num_steps_per_env = 8
    cfg.runner.num_threads = 1
    cfg.runner.save_interval = 1
    cfg.runner.critic_warmup_iterations = 1
    cfg.amp.batch_size = 64
    cfg.amp.replay_size = 1024
    cfg.amp.updates_per_iteration = 1
    return cfg, path


REAL_RECIPE = learn_style.recipe
REAL_BUDGET = learn_style.training_budget_s


@pytest.fixture(scope='module')
def run(tmp_path_factory):
    """A whole learn_style run on the shipped clips: 3 s of training, a few balls per evaluation."""
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(learn_style, 'recipe', tiny_recipe)
        patch.setattr(learn_style, 'training_budget_s', lambda minutes, spent_s=0.0: 3.0)
        patch.setattr(learn_style, 'VALIDATION', dict(seeds=1, first_seed=900, balls=6))
        patch.setattr(learn_style, 'EVALUATION', dict(seeds=1, first_seed=1000, balls=6))
        patch.setattr(learn_style, 'EVALUATION_HIGH', dict(seeds=1, first_seed=2000, balls=6))
        out = tmp_path_factory.mktemp('learn_style') / 'run'
        torch.set_num_threads(1)
        code = learn_style.main([str(BAGS), '--out', str(out), '--minutes', '5'])
        assert code == 0
        yield out


@pytest.mark.slow  # the run: about 40 s on a quiet 2-core machine
def test_a_run_leaves_a_deployable_actor_its_network_and_a_report(run):
    actor = load_actor(run / learn_style.ACTOR_NAME)
    assert actor(torch.zeros(1, actor.num_obs)).shape == (1, actor.num_actions)
    # The player runs it as it is: the ONNX file against the contract of this workspace's spec.
    from stylepong_player.actor_contract import current_spec_contract
    from stylepong_player.player_core import load_actor as player_actor

    onnx = player_actor(run / 'actor.onnx', 'onnx', current_spec_contract())
    assert onnx(np.zeros((1, actor.num_obs), dtype=np.float32)).shape == (1, actor.num_actions)
    assert read_sidecar(run / learn_style.ACTOR_NAME)['training']['learn_style']['candidate']
    checkpoint = torch.load(run / learn_style.ACTOR_CHECKPOINT_NAME, map_location='cpu', weights_only=False)
    assert {'model', 'architecture'} <= set(checkpoint) and checkpoint['optimizer'] is None
    report = (run / style_report.REPORT_MD).read_text()
    assert 'PPO' in report and 'shipped' in report
    for name in style_report.ACTORS:
        files = style_report.eval_files(run, name)
        assert files.all_speeds_json.is_file() and files.strokes_npz.is_file()
    state = json.loads((run / learn_style.STATE_NAME).read_text())
    assert list(state['stages']) == list(learn_style.STAGES)
    assert state['stages']['choose']['chosen'] in json.loads((run / 'choose' / 'candidates.json').read_text())['chosen']


@pytest.mark.slow  # the run: about 40 s on a quiet 2-core machine
def test_the_start_is_the_librarys_nearest_skill_and_the_new_network_records_these_demonstrations(run):
    state = json.loads((run / learn_style.STATE_NAME).read_text())
    record = json.loads((run / learn_style.SKILL_DIR / learn_style.SKILLS_JSON).read_text())
    offered = skills.offered(skills.library(learn_style.models_dir()), record['fingerprint'])
    assert [row['candidate'] for row in record['skills']] == [skill.name for skill in offered]
    assert record['min_success'] == learn_style.skill_bar(learn_style.recipe(None)[0])
    chosen = learn_style.choose_candidate(record['skills'], record['min_success'])
    assert record['chosen'] == state['stages']['skill']['chosen'] == chosen['candidate']
    assert state['skill'] == chosen['path']
    checkpoint = torch.load(run / learn_style.ACTOR_CHECKPOINT_NAME, map_location='cpu', weights_only=False)
    start = torch.load(state['skill'], map_location='cpu', weights_only=False)
    assert skills.lineage_of(checkpoint) == (*skills.lineage_of(start), record['fingerprint'])
    assert 'chosen from the library' in (run / style_report.REPORT_MD).read_text()


@pytest.mark.slow  # the run: about 40 s on a quiet 2-core machine
def test_a_finished_run_is_not_overwritten_and_resumes_only_what_is_missing(run):
    assert learn_style.main([str(BAGS), '--out', str(run)]) == 2
    state = json.loads((run / learn_style.STATE_NAME).read_text())
    del state['stages']['report']
    (run / learn_style.STATE_NAME).write_text(json.dumps(state))
    (run / style_report.REPORT_MD).unlink()
    actor_written = (run / learn_style.ACTOR_NAME).stat().st_mtime_ns
    assert learn_style.main([str(BAGS), '--out', str(run), '--resume']) == 0
    assert (run / style_report.REPORT_MD).is_file()
    assert (run / learn_style.ACTOR_NAME).stat().st_mtime_ns == actor_written
    assert 'report' in json.loads((run / learn_style.STATE_NAME).read_text())['stages']


@pytest.mark.slow  # the run: about 40 s on a quiet 2-core machine
def test_a_learn_style_run_is_a_skill_to_start_from(run):
    assert learn_style.skill_checkpoint(run) == run / learn_style.ACTOR_CHECKPOINT_NAME
    assert learn_style.skill_checkpoint(run / learn_style.ACTOR_NAME) == run / learn_style.ACTOR_CHECKPOINT_NAME
    with pytest.raises(learn_style.StyleError, match='not a training checkpoint'):
        learn_style.skill_checkpoint(learn_style.models_dir() / 'ppo_actor.pt')


def test_bad_demonstrations_are_refused_in_one_line_before_training(tmp_path):
    started = time.monotonic()
    empty = tmp_path / 'empty'
    empty.mkdir()
    result = subprocess.run(
        [sys.executable, '-m', 'stylepong_policy.training.learn_style', str(empty), '--out', str(tmp_path / 'run')],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and str(empty) in lines[0], result.stderr
    assert not (tmp_path / 'run' / learn_style.TRAIN_DIR).exists()
    assert time.monotonic() - started < 30.0


def test_a_device_without_cuda_is_refused_in_one_line_before_anything_is_written(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(torch.cuda, 'is_available', lambda: False)
    out = tmp_path / 'run'
    assert learn_style.main([str(BAGS), '--out', str(out), '--device', 'cuda']) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and 'no CUDA' in lines[0], lines
    assert not out.exists()


def test_candidates_are_averages_along_the_end_of_the_run_and_the_last_checkpoint(tmp_path, monkeypatch):
    from stylepong_policy.training import select_checkpoint

    numbered = [(i, tmp_path / f'model_{i:06d}.pt') for i in range(50, 650, 50)]  # 12 checkpoints
    monkeypatch.setattr(select_checkpoint, 'numbered_checkpoints', lambda run_dir: numbered)
    candidates = dict(learn_style.candidates_of(tmp_path))
    assert candidates == {
        'average_150_200': [150, 200],
        'average_250_300': [250, 300],
        'average_350_400': [350, 400],
        'average_450_500': [450, 500],
        'average_550_600': [550, 600],
        'average_450_600': [450, 500, 550, 600],
        'checkpoint_600': [600],
    }


def test_the_choice_is_the_most_stylish_candidate_that_returns_enough_balls():
    rows = [
        {'candidate': 'a', 'success_rate': 0.95, 'mean_dtw_rad': 20.0},
        {'candidate': 'b', 'success_rate': 0.93, 'mean_dtw_rad': 15.0},
        {'candidate': 'c', 'success_rate': 0.80, 'mean_dtw_rad': 5.0},
    ]
    assert learn_style.choose_candidate(rows)['candidate'] == 'b'
    assert learn_style.choose_candidate([dict(r, success_rate=0.5) for r in rows])['candidate'] == 'a'


def test_a_start_must_leave_the_success_hold_room_above_the_choices_bar():
    cfg = learn_style.recipe(None)[0]
    bar = learn_style.skill_bar(cfg)
    assert cfg.amp.hold_success_margin > 0.0
    assert bar == pytest.approx(learn_style.MIN_SUCCESS + cfg.amp.hold_success_margin)
    skills_validated = [
        {'candidate': 'near', 'success_rate': learn_style.MIN_SUCCESS + 0.006, 'mean_dtw_rad': 35.0},
        {'candidate': 'far', 'success_rate': bar + 0.004, 'mean_dtw_rad': 45.0},
    ]
    assert learn_style.choose_candidate(skills_validated)['candidate'] == 'near'
    assert learn_style.choose_candidate(skills_validated, bar)['candidate'] == 'far'


def test_training_gets_all_but_the_reserve():
    assert REAL_BUDGET(60.0) == 60.0 * 60.0 - learn_style.RESERVE_S
    assert REAL_BUDGET(60.0, spent_s=90.0) == 60.0 * 60.0 - learn_style.RESERVE_S - 90.0
    assert REAL_BUDGET(4.0) == pytest.approx(180.0)
    assert REAL_BUDGET(0.1) == learn_style.MIN_TRAIN_S


def test_a_resumed_runs_bar_starts_at_its_training_time_and_follows_the_runs_clock(tmp_path):
    """The train bar counts the run's training time against the budget: a resumed run's starts where the
    stopped one was (its progress log's last wall time), so its ETA is the budget really left."""
    from stylepong_policy.rl.logger import CSV_NAME
    from stylepong_policy.training.learn_style_progress import StageBar

    assert learn_style.trained_s(tmp_path) == 0.0
    (tmp_path / CSV_NAME).write_text('iteration,wall_time_s\n1,2.5\n2,828.0\n')
    assert learn_style.trained_s(tmp_path) == 828.0
    with StageBar('train', 3060.0, initial=learn_style.trained_s(tmp_path)) as bar:
        assert bar.bar.n == 828.0
        bar.iteration({'iteration': 3, 'wall_time_s': 830.0, 'iteration_time_s': 2.0})
        assert bar.bar.n == 830.0
        bar.iteration({'iteration': 4, 'wall_time_s': 4000.0, 'iteration_time_s': 2.0})
        assert bar.bar.n == 3060.0  # never past the budget


def test_a_skill_given_with_from_is_the_start_without_validating_the_library(tmp_path):
    paths = learn_style.paths_of(tmp_path / 'run')
    given = learn_style.skill_stage(paths, {'skill': '/given.pt'}, 'cpu', learn_style.MIN_SUCCESS)
    assert given == {'chosen': '/given.pt', 'given': True}
    assert not paths.skill.exists()


def test_a_stopped_run_resumes_with_the_recipe_it_began_with(tmp_path):
    """A run stopped in its training and resumed after the recipe changed (here: it began without the free
    follow-through's value stream) goes on with the checkpoint's recipe, not today's, which would not fit."""
    torch.set_num_threads(1)
    paths = learn_style.paths_of(tmp_path / 'run')
    paths.run.mkdir()
    dataset = pathlib.Path(__file__).resolve().parents[4] / 'results' / 'reference_dataset.npz'
    paths.dataset.write_bytes(dataset.read_bytes())
    skill = learn_style.models_dir() / skills.SHIPPED_FILE
    before, config_path = tiny_recipe('cpu')
    before.amp.free_follow_through = False
    first = learn_style.train_stage(before, config_path, paths, skill, 1.0, 'learn_style first')
    now, _ = tiny_recipe('cpu')
    assert now.amp.free_follow_through
    resumed = learn_style.train_stage(now, config_path, paths, skill, 2.5, 'learn_style --resume')
    assert resumed['iterations'] > first['iterations']
    last = torch.load(paths.train / 'checkpoints' / 'last.pt', map_location='cpu', weights_only=False)
    assert 'value_streams' not in last['architecture'] and not last['config']['amp']['free_follow_through']
