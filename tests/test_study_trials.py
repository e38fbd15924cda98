"""
Trial result files from run folders, the runner's bookkeeping, resume and crash records.

The run folders here are written by the tests (a few rows in the launcher's progress.csv and
summary.json layout); the stand-in launcher is a small script that only exercises the runner's
process handling. The real launcher is used in test_study_end_to_end.py.
"""

import csv
import json
from pathlib import Path
import signal
import subprocess
import sys
import textwrap
import threading
import time

from attention_bringup.experiment import runner, trials
from attention_bringup.progress import PROGRESS_COLUMNS
from attention_bringup.study.analysis import censored_steps, progress_step
from attention_common.run_files import LAUNCHER_LOG
import pytest


def _write_run(run_dir: Path, positions, lives=None, episodes=None, has_key=None,
               summary=None):
    """Write a run folder with one progress.csv row per step (positions[i] at agent step i)."""
    run_dir.mkdir(parents=True, exist_ok=True)
    furthest = -1
    with open(run_dir / 'progress.csv', 'w', newline='') as handle:
        writer = csv.DictWriter(handle, fieldnames=PROGRESS_COLUMNS)
        writer.writeheader()
        for step, position in enumerate(positions):
            furthest = max(furthest, position)
            writer.writerow({
                'agent_step': step, 'position': position, 'furthest_position': furthest,
                'episode': (episodes or [0] * len(positions))[step],
                'lives': (lives or [5] * len(positions))[step],
                'has_key': (has_key or [0] * len(positions))[step]})
    if summary is not None:
        (run_dir / 'summary.json').write_text(json.dumps(summary))


def test_record_of_a_completed_run(tmp_path):
    positions = [-1, -1, 1, -1, 0, 0, 2, -1, -1, -1, -1]
    lives = [5, 5, 5, 4, 4, 4, 4, 3, 5, 5, 5]
    episodes = [0, 0, 0, 0, 0, 0, 0, 0, 1, 1, 1]
    has_key = [0, 0, 0, 0, 0, 1, 1, 0, 0, 1, 1]
    _write_run(tmp_path / 'run', positions, lives, episodes, has_key,
               summary={'status': 'completed', 'steps': 10, 'episodes': 2, 'lives_lost': 2})
    record = trials.build_record('vanilla', 3, 10, tmp_path / 'run', 0, 12.34)
    assert record['outcome'] == trials.COMPLETED and record['problem'] is None
    assert record['first_step_at_position'] == {
        '0': 4, '1': 2, '2': 6, '3': None, '4': None, '5': None}
    assert record['furthest_position'] == 2
    assert record['key_pickups'] == 2 and record['key'] is True
    assert (record['episodes'], record['lives_lost']) == (2, 2)
    assert record['steps_at_position'] == {'-1': 7, '0': 2, '1': 1, '2': 1, '3': 0, '4': 0,
                                           '5': 0}
    assert record['feedback_mean'] is None  # not in this summary
    assert len(json.dumps(record)) < 4000
    # Progress counts a later position for the earlier ones; unreached is budget + 1.
    assert progress_step(record, 0) == 2 and progress_step(record, 1) == 2
    assert progress_step(record, 3) is None and censored_steps(record, 3) == 11
    assert censored_steps(record, 2) == 6


def test_refresh_adds_the_new_fields_and_keeps_what_the_runner_knew(tmp_path):
    positions = [-1, 0, 0, 0, 1, -1, 0]
    _write_run(tmp_path / 'runs' / 'vanilla' / 'seed0', positions,
               summary={'status': 'completed', 'feedback_mean': 0.5})
    out = tmp_path / 'out'
    old = trials.build_record('vanilla', 0, 6, tmp_path / 'runs' / 'vanilla' / 'seed0', 0, 99.5,
                              started_at='2020-01-01T00:00:00', parallel=2)
    for field in ('steps_at_position', 'feedback_mean'):
        del old[field]  # a result file written before these fields existed
    old['run_dir'] = 'runs/vanilla/seed0'  # stored relative to where the study ran
    trials.write_json(trials.trial_path(out, 'vanilla', 0), old)
    gone = dict(old, seed=1, run_dir='runs/vanilla/seed1')
    trials.write_json(trials.trial_path(out, 'vanilla', 1), gone)
    refreshed, skipped = trials.refresh_records(out, ['vanilla', 'language'], tmp_path)
    assert refreshed == [trials.trial_path(out, 'vanilla', 0)]
    assert list(skipped) == [trials.trial_path(out, 'vanilla', 1)]
    record = trials.read_json(refreshed[0])
    assert record['steps_at_position'] == {'-1': 2, '0': 4, '1': 1, '2': 0, '3': 0, '4': 0,
                                           '5': 0}
    assert record['feedback_mean'] == 0.5
    assert (record['wall_time_s'], record['started_at'], record['parallel']) == (
        99.5, '2020-01-01T00:00:00', 2)
    assert record['run_dir'] == 'runs/vanilla/seed0'
    new_fields = ('steps_at_position', 'feedback_mean')
    assert {k: v for k, v in record.items() if k not in new_fields} == old
    assert trials.read_json(trials.trial_path(out, 'vanilla', 1)) == gone


def test_lives_and_episodes_come_from_the_rows_without_a_summary(tmp_path):
    rows = [{'agent_step': i, 'position': -1, 'furthest_position': -1, 'episode': e,
             'lives': lv, 'has_key': 0}
            for i, (e, lv) in enumerate([(0, 5), (0, 4), (0, 2), (1, 5), (1, 4)])]
    assert trials.lives_lost_in(rows) == 4


def test_furthest_curve_is_sampled_and_ends_with_the_data():
    rows = [{'agent_step': s, 'position': p, 'furthest_position': max(-1, p)}
            for s, p in [(0, -1), (50, 0), (120, -1), (130, 2), (250, -1)]]
    assert trials.furthest_curve(rows, 400, every=100) == [-1, 0, 2, None, None]
    assert trials.furthest_curve(rows, 250, every=100) == [-1, 0, 2, 2]


@pytest.mark.parametrize('summary, steps, code, timed_out, outcome', [
    ({'status': 'completed'}, 100, 0, False, trials.COMPLETED),
    ({'status': 'unclean_exit'}, 100, 1, False, trials.COMPLETED_UNCLEAN),
    ({'status': 'node_failed'}, 40, 1, False, trials.CRASHED),
    (None, 100, 1, False, trials.CRASHED),
    ({'status': 'completed'}, 100, 0, True, trials.TIMEOUT),
])
def test_outcomes(summary, steps, code, timed_out, outcome):
    assert trials.outcome_of(summary, steps, 100, code, timed_out) == outcome


def test_a_crashed_run_keeps_its_log_tails(tmp_path):
    run = tmp_path / 'run'
    _write_run(run, [-1, 0, 0], summary={'status': 'node_failed', 'failed_node': 'tamer_node',
                                         'exit_text': 'tamer_node exit code 1'})
    (run / 'logs').mkdir()
    (run / 'logs' / 'tamer_node.log').write_text('x' * 5000 + '\nRuntimeError: out of memory\n')
    (run / LAUNCHER_LOG).write_text('attention_train: tamer_node died\n')
    record = trials.build_record('language', 0, 100, run, 1, 5.0)
    assert record['outcome'] == trials.CRASHED and record['steps'] == 2
    problem = record['problem']
    assert problem['failed_node'] == 'tamer_node'
    assert problem['node_log_tail'].endswith('RuntimeError: out of memory\n')
    assert len(problem['node_log_tail']) <= trials.TAIL_CHARS + 3
    assert 'tamer_node died' in problem['launcher_output_tail']


def _record(condition, seed, budget, outcome='completed'):
    return {'format': trials.FORMAT, 'condition': condition, 'seed': seed, 'budget': budget,
            'outcome': outcome}


def test_plan_skips_existing_results_and_interleaves_conditions(tmp_path):
    out = tmp_path / 'out'
    trials.write_json(trials.trial_path(out, 'vanilla', 0), _record('vanilla', 0, 500))
    trials.write_json(trials.trial_path(out, 'language', 1),
                      _record('language', 1, 500, trials.CRASHED))
    pending, kept = runner.plan_trials(['vanilla', 'language'], 2, 500, out, tmp_path / 'runs')
    assert [(job.condition, job.seed) for job in pending] == [
        ('language', 0), ('vanilla', 1)]
    assert sorted(path.name for path in kept) == ['seed0.json', 'seed1.json']
    assert pending[0].run_dir == tmp_path / 'runs' / 'language' / 'seed0'


def test_the_study_keeps_the_thesis_trainer_unless_told_and_passes_the_trainer_on(tmp_path):
    from attention_bringup.study.cli import argument_parser, launcher_args, regenerate_command
    default = argument_parser().parse_args([])
    assert launcher_args(default) == ['--trainer', 'thesis']
    told = argument_parser().parse_args(['--trainer', 'teacher', '--human-like'])
    told.runs_dir = 'runs/study'
    assert launcher_args(told) == ['--trainer', 'teacher', '--human-like']
    assert regenerate_command(told, 2).endswith('--trainer teacher --human-like')
    pending, _ = runner.plan_trials(['vanilla'], 1, 500, tmp_path / 'out', tmp_path / 'runs',
                                    launcher_args=launcher_args(told), seeds=[7])
    command = runner.launcher_command(Path('attention_train'), pending[0])
    assert command[-3:] == ['--trainer', 'teacher', '--human-like']
    assert command[command.index('--seed') + 1] == '7'


def test_retry_crashed_moves_the_old_record_aside(tmp_path):
    out = tmp_path / 'out'
    path = trials.trial_path(out, 'language', 0)
    trials.write_json(path, _record('language', 0, 500, trials.CRASHED))
    pending, kept = runner.plan_trials(['language'], 1, 500, out, tmp_path / 'runs',
                                       retry_crashed=True)
    assert [(job.condition, job.seed) for job in pending] == [('language', 0)] and not kept
    assert not path.exists()
    assert [r['outcome'] for r in runner.load_retired(out, ['language'])] == [trials.CRASHED]
    assert trials.load_records(out, ['language']) == {'language': []}


def test_plan_refuses_a_results_folder_of_another_budget(tmp_path):
    out = tmp_path / 'out'
    trials.write_json(trials.trial_path(out, 'vanilla', 0), _record('vanilla', 0, 1000))
    with pytest.raises(ValueError, match='1000 steps'):
        runner.plan_trials(['vanilla'], 1, 500, out, tmp_path / 'runs')


FAKE_LAUNCHER = textwrap.dedent('''\
    #!{python}
    """Stand-in for attention_train: writes a run folder, then behaves as MODE says."""
    import csv, json, pathlib, signal, sys, time
    args = dict(zip(sys.argv[1::2], sys.argv[2::2]))
    run = pathlib.Path(args['--run-dir'])
    mode = (run.parent.parent / 'mode').read_text().strip()
    steps = int(args['--steps']) if mode == 'ok' else 3
    with open(run / 'progress.csv', 'w') as f:
        f.write('agent_step,position,furthest_position,episode,lives,has_key\\n')
        for s in range(steps + 1):
            f.write(f'{{s}},{{0 if s == 2 else -1}},{{0 if s >= 2 else -1}},0,5,0\\n')
    if mode == 'hang':
        signal.signal(signal.SIGINT, lambda *a: sys.exit(130))
        time.sleep(60)
    status = 'completed' if mode == 'ok' else 'node_failed'
    (run / 'summary.json').write_text(json.dumps({{'status': status, 'failed_node': None,
                                                  'exit_text': mode}}))
    print('stand-in launcher', mode)
    sys.exit(0 if mode == 'ok' else 1)
    ''')


@pytest.fixture
def fake_launcher(tmp_path):
    path = tmp_path / 'attention_train'
    path.write_text(FAKE_LAUNCHER.format(python=sys.executable))
    path.chmod(0o755)
    return path


def _job(tmp_path, seed=0):
    return runner.TrialJob('vanilla', seed, 20, trials.trial_path(tmp_path / 'out', 'vanilla',
                                                                  seed),
                           tmp_path / 'runs' / 'vanilla' / f'seed{seed}')


@pytest.mark.parametrize('mode, outcome', [('ok', trials.COMPLETED),
                                           ('crash', trials.CRASHED)])
def test_run_trial_writes_a_result_file_also_for_a_crash(tmp_path, fake_launcher, mode,
                                                         outcome):
    (tmp_path / 'runs').mkdir()
    (tmp_path / 'runs' / 'mode').write_text(mode)
    job = _job(tmp_path)
    stale = job.run_dir / 'summary.json'
    stale.parent.mkdir(parents=True)
    stale.write_text('{"status": "interrupted"}')  # left by an interrupted attempt
    record = runner.run_trial(job, fake_launcher, threading.Event(), timeout_s=30.0)
    assert record['outcome'] == outcome
    assert json.loads(job.result_path.read_text()) == record
    if mode == 'crash':
        assert record['exit_code'] == 1 and record['steps'] == 3
        assert 'stand-in launcher crash' in record['problem']['launcher_output_tail']


def _count_progress_rows(record, run_dir):
    """Count the rows of progress.csv: a study's own measure (module level, as on Ray)."""
    record['rows'] = len((run_dir / 'progress.csv').read_text().splitlines()) - 1
    return record


def test_a_trial_carries_its_study_measures_into_its_result_file(tmp_path, fake_launcher):
    (tmp_path / 'runs').mkdir()
    (tmp_path / 'runs' / 'mode').write_text('ok')
    jobs, _ = runner.plan_trials(['vanilla'], 1, 20, tmp_path / 'out', tmp_path / 'runs',
                                 measure=_count_progress_rows)
    record = runner.run_trial(jobs[0], fake_launcher, threading.Event(), timeout_s=30.0)
    assert record['rows'] == len(trials.read_progress(jobs[0].run_dir / 'progress.csv')) > 0
    assert json.loads(jobs[0].result_path.read_text())['rows'] == record['rows']


def test_a_stopped_trial_leaves_no_result_and_a_timed_out_one_does(tmp_path, fake_launcher):
    (tmp_path / 'runs').mkdir()
    (tmp_path / 'runs' / 'mode').write_text('hang')
    stop = threading.Event()
    stop.set()
    job = _job(tmp_path)
    assert runner.run_trial(job, fake_launcher, stop, timeout_s=30.0) is None
    assert not job.result_path.exists()
    record = runner.run_trial(job, fake_launcher, threading.Event(), timeout_s=1.0)
    assert record['outcome'] == trials.TIMEOUT and record['exit_code'] != 0
    assert json.loads(job.result_path.read_text())['outcome'] == trials.TIMEOUT


def test_run_trials_runs_each_job_once_side_by_side(tmp_path, fake_launcher):
    (tmp_path / 'runs').mkdir()
    (tmp_path / 'runs' / 'mode').write_text('ok')
    jobs = [_job(tmp_path, seed) for seed in range(3)]
    seen = []
    records = runner.run_trials(jobs, fake_launcher, 2, 30.0, threading.Event(),
                                lambda job, record, n: seen.append(job.seed))
    assert sorted(seen) == [0, 1, 2] and sorted(r['seed'] for r in records) == [0, 1, 2]
    assert all(job.result_path.exists() for job in jobs)


DRIVER = textwrap.dedent('''\
    """Run attention_study's main with the stand-in launcher in place of attention_train."""
    import sys
    from attention_bringup.experiment import runner
    from attention_bringup.study import cli
    real_run_trial = runner.run_trial
    runner.run_trial = lambda job, launcher, *args: real_run_trial(job, sys.argv[1], *args)
    sys.exit(cli.main(sys.argv[2:]))
    ''')


def test_ctrl_c_stops_the_running_trial_and_keeps_no_result(tmp_path, fake_launcher):
    out = tmp_path / 'out'
    (out / 'runs').mkdir(parents=True)
    (out / 'runs' / 'mode').write_text('hang')
    driver = tmp_path / 'driver.py'
    driver.write_text(DRIVER)
    study = subprocess.Popen(
        [sys.executable, str(driver), str(fake_launcher), '--conditions', 'vanilla',
         '--trials', '1', '--steps', '20', '--out', str(out), '--report',
         str(tmp_path / 'r.md')], stderr=subprocess.PIPE, text=True)
    progress = out / 'runs' / 'vanilla' / 'seed0' / 'progress.csv'
    deadline = time.monotonic() + 60
    while not progress.exists() and time.monotonic() < deadline and study.poll() is None:
        time.sleep(0.1)
    assert progress.exists(), 'the stand-in launcher never started'
    time.sleep(0.5)  # let it install its SIGINT handler
    study.send_signal(signal.SIGINT)
    _, err = study.communicate(timeout=60)
    assert study.returncode == 130, err
    assert 'vanilla seed 0: interrupted (no result file' in err
    assert not trials.trial_path(out, 'vanilla', 0).exists()
    log = json.loads((out / 'study_log.json').read_text())
    assert log[-1]['interrupted'] is True and log[-1]['trials_run'] == 0
