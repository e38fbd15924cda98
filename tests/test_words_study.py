"""The Fetch study's plug-in (issue 25): a trial's measures from its progress.csv, pure."""

import csv

from attention_bringup.experiment.plugins.words import (
    CHANCE, episodes_of, heldout_after, trial_measures)
import pytest

COLUMNS = ('agent_step', 'episode', 'episode_step', 'session', 'heldout', 'position')


def _progress(path, episodes):
    """Write a progress.csv: each episode (steps, held out, solved at its last step)."""
    step = 0
    with open(path, 'w', newline='') as handle:
        writer = csv.writer(handle)
        writer.writerow(COLUMNS)
        for index, (steps, heldout, solved) in enumerate(episodes):
            for i in range(steps):
                step += 1
                last = i == steps - 1
                writer.writerow([step, index, i + 1, 1, int(heldout),
                                 1 if solved and last else -1])


def test_success_counts_ended_episodes_of_each_part(tmp_path):
    path = tmp_path / 'progress.csv'
    # 100 steps: held out from step 80; the late training part begins at 0.75 x 80 = 60.
    _progress(path, [(30, False, False), (29, False, True), (10, False, True),
                     (10, False, False), (10, True, True), (10, True, False),
                     (5, True, False)])  # the last: cut by the budget, unsolved
    found = trial_measures(episodes_of(path), heldout_after(100, 0.2), step_limit=10)
    assert found['episodes'] == 6  # the cut one did not end
    # Episodes of the 10-step limit ended without a pick-up; shorter ones with one.
    assert (found['late_training_picked'], found['heldout_picked']) == (0, 0)
    found = trial_measures(episodes_of(path), heldout_after(100, 0.2), step_limit=12)
    assert (found['late_training_picked'], found['heldout_picked']) == (2, 2)
    assert (found['late_training_solved'], found['late_training_episodes']) == (1, 2)
    assert (found['heldout_solved'], found['heldout_episodes']) == (1, 2)
    assert found['heldout_success'] == 0.5 and found['late_training_success'] == 0.5


def test_a_trial_without_held_out_episodes_has_no_held_out_rate(tmp_path):
    path = tmp_path / 'progress.csv'
    _progress(path, [(50, False, True)])
    found = trial_measures(episodes_of(path), 40)
    assert found['heldout_success'] is None and found['heldout_episodes'] == 0
    assert episodes_of(tmp_path / 'missing.csv') == []
    assert CHANCE == 0.25
    with pytest.raises(ValueError):
        heldout_after(100, 1.0)


def test_the_report_compares_the_arms_on_held_out_success(tmp_path):
    from attention_bringup.experiment.plugins import words
    from attention_bringup.experiment.spec import from_dict
    spec = from_dict({
        'name': 'words_test', 'plugin': 'words', 'task': 'fetch', 'budget': 100,
        'seeds': [0, 1, 2], 'out': str(tmp_path / 'out'), 'report': str(tmp_path / 'r.md'),
        'runs_dir': str(tmp_path / 'runs'), 'layout': 'by_arm',
        'arms': [{'name': 'plain', 'condition': 'vanilla'},
                 {'name': 'words', 'condition': 'language_input'}],
        'comparisons': [{'arm': 'words', 'baseline': 'plain'}],
        'settings': {'heldout_fraction': 0.25}})

    def record(seed, solved):
        return {'seed': seed, 'words': {
            'heldout_solved': solved, 'heldout_episodes': 10, 'heldout_success': solved / 10,
            'late_training_solved': solved, 'late_training_episodes': 10,
            'late_training_success': solved / 10, 'episodes': 40}}

    by_arm = {'plain': [record(s, k) for s, k in enumerate((2, 3, 2))],
              'words': [record(s, k) for s, k in enumerate((8, 9, 7))]}
    result = words.analyse(spec, by_arm, {'log': []})
    assert result['arms']['words']['heldout_pooled']['k'] == 24
    [compared] = result['comparisons']
    assert compared['difference'] == pytest.approx(0.8 - 0.7 / 3, abs=1e-9)
    assert compared['p'] < 0.01 and compared['hedges_g'] > 2
    words.write_report(spec, result, by_arm, {'log': []})
    text = (tmp_path / 'r.md').read_text()
    assert '`words` vs `plain`' in text and '24/30' in text and 'Chance' in text
    assert 'ended by a pick-up' in text
