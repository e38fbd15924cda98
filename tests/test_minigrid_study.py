"""The DoorKey study's measures and analysis, on progress rows written by hand (pure)."""

import csv
from dataclasses import replace
import json

from attention_bringup.experiment import engine, spec as specs
from attention_bringup.experiment.plugins.doorkey import ask_rate, heldout_after
from attention_bringup.minigrid_study import analysis, report
from attention_bringup.minigrid_study.measures import (
    episodes_of, read_rows, success_curve, trial_measures)
from attention_bringup.progress import PROGRESS_COLUMNS
import pytest
import yaml


def rows_of(episodes, heldout_from=None):
    """Progress rows: each episode a list of positions (sub-goal milestones), one per step."""
    rows, step = [], 0
    for episode, positions in enumerate(episodes):
        for episode_step, position in enumerate(positions):
            step += 1
            rows.append({'agent_step': step, 'episode': episode, 'episode_step': episode_step,
                         'position': position, 'session': 1,
                         'heldout': int(heldout_from is not None and episode >= heldout_from)})
    return rows


def test_episodes_are_cut_where_the_episode_number_changes_and_the_last_is_open():
    rows = rows_of([[-1, 0, 0, 1, 2], [-1, -1, 0], [-1, -1]], heldout_from=1)
    episodes = episodes_of(rows)
    assert [e['solved'] for e in episodes] == [True, False, False]
    assert [e['ended'] for e in episodes] == [True, True, False]
    assert (episodes[0]['key_at'], episodes[0]['door_at'], episodes[0]['goal_at']) == (1, 3, 4)
    assert [e['heldout'] for e in episodes] == [False, True, True]


def test_trial_measures_count_only_ended_episodes_and_split_held_out():
    rows = rows_of([[-1, 0, 1, 2], [-1, 0], [-1, 0, 1, 2], [-1, -1]], heldout_from=2)
    measures = trial_measures(rows, budget=len(rows))
    assert (measures['episodes'], measures['solved']) == (3, 2)
    assert (measures['training_episodes'], measures['training_solved']) == (2, 1)
    assert (measures['heldout_episodes'], measures['heldout_solved']) == (1, 1)
    assert measures['training_success'] == 0.5 and measures['heldout_success'] == 1.0
    assert measures['training_progress'] == 2.0  # 3 sub-goals and 1
    assert measures['first_step'] == {'key': 2, 'door': 3, 'goal': 4}
    assert measures['mean_steps_to']['goal'] == 3.0


def test_success_curve_bins_episodes_by_the_step_they_ended():
    episodes = [{'ended': True, 'solved': s, 'last_step': step}
                for s, step in [(False, 10), (True, 20), (True, 95), (False, 100)]]
    assert success_curve(episodes, 100, bins=2) == [0.5, 0.5]
    assert success_curve([], 100, bins=2) == [None, None]


def test_rows_are_read_back_from_a_progress_csv(tmp_path):
    path = tmp_path / 'progress.csv'
    with open(path, 'w', newline='') as handle:
        writer = csv.DictWriter(handle, PROGRESS_COLUMNS)
        writer.writeheader()
        for row in rows_of([[-1, 0, 1, 2]], heldout_from=0):
            writer.writerow({column: row.get(column, '') for column in PROGRESS_COLUMNS})
    assert read_rows(path)[-1] == {'agent_step': 4, 'episode': 0, 'episode_step': 3,
                                   'position': 2, 'heldout': 1, 'session': 1, 'action': -1}
    assert read_rows(tmp_path / 'missing.csv') == []


def record(condition, seed, episodes, heldout_from):
    rows = rows_of(episodes, heldout_from)
    return {'condition': condition, 'seed': seed, 'outcome': 'completed', 'wall_time_s': 60.0,
            'updates_per_step': 1.5, 'doorkey': trial_measures(rows, len(rows))}


def test_analysis_compares_with_vanilla_and_the_report_says_it(tmp_path):
    solved, failed = [-1, 0, 1, 2], [-1, -1, -1]
    by_condition = {
        'vanilla': [record('vanilla', s, [failed] * 4 + [solved if s == 0 else failed, failed],
                           3) for s in range(4)],
        'language': [record('language', s, [failed] * 3 + [solved, solved, failed], 3)
                     for s in range(4)],
    }
    result = analysis.analyse(by_condition, 18)
    pooled = result['conditions']['language']['heldout_success_pooled']
    assert (pooled['solved'], pooled['episodes']) == (8, 8)  # the open last episode not counted
    assert 0.6 < pooled['low'] < pooled['rate'] == 1.0
    test = result['comparisons']['heldout_success'][0]
    assert test['condition'] == 'language' and test['difference'] > 0.5
    assert test['p_holm'] == test['p']  # one comparison: Holm changes nothing
    spec = replace(specs.load('doorkey'), seeds=(0, 1, 2, 3), out='out')
    figures = report.draw_figures(result, tmp_path)
    assert all(path.exists() for path in figures.values())
    path = tmp_path / 'results.md'
    report.write_report(path, result, spec, figures, 'the command',
                        [{'wall_time_s': 600, 'parallel': 2}])
    text = path.read_text()
    assert 'the command' in text and '| language |' in text and 'significant' in text
    assert '![success_curves](success_curves.png)' in text


def test_the_protocol_says_when_the_learner_asks(tmp_path):
    """A spec run with ``--ask RATE`` says so in its protocol; one without does not."""
    records = {'vanilla': [record('vanilla', s, [[-1, 0, 1, 2]] * 3, 2) for s in range(2)]}
    said = {}
    for name in ('doorkey_human_like_asks', 'doorkey'):
        spec = replace(specs.load(name), seeds=(0, 1), out='out')
        result = analysis.analyse(records, spec.budget)
        if ask_rate(spec):  # as the plug-in's analyse records it
            result['ask_rate'] = ask_rate(spec)
        path = tmp_path / f'{name}.md'
        report.write_report(path, result, spec, {}, 'the command', [])
        said[name] = path.read_text()
    assert 'at most 0.5 questions a step' in said['doorkey_human_like_asks']
    assert 'questions a step' not in said['doorkey'].split('## Later studies')[0]


def test_the_protocol_counts_the_comparisons_and_gives_the_specs_reason_for_its_budget(
        tmp_path):
    """Holm's adjustment is over as many comparisons as there are; a spec may say its budget."""
    episodes = [[-1, 0, 1, 2]] * 3
    said = {}
    for name, conditions in (('doorkey', ('vanilla', 'language', 'blind_obs')),
                             ('doorkey_human_like_asks', ('vanilla', 'language_input'))):
        records = {c: [record(c, s, episodes, 2) for s in range(2)] for c in conditions}
        spec = replace(specs.load(name), seeds=(0, 1), out='out')
        path = tmp_path / f'{name}.md'
        report.write_report(path, analysis.analyse(records, spec.budget), spec, {}, 'the '
                            'command', [])
        said[name] = path.read_text()
    assert "Holm's adjustment over the two comparisons of a measure" in said['doorkey']
    assert report._tests_text(0) == ''  # one condition: nothing tested
    assert 'over the one comparison of a measure' in said['doorkey_human_like_asks']
    assert report.BUDGET_NOTE in said['doorkey']
    assert report.BUDGET_NOTE not in said['doorkey_human_like_asks']
    assert 'not tuned for it' in said['doorkey_human_like_asks']
    assert '**Does language help when the learner reads it?**' in said[
        'doorkey_human_like_asks']


def test_the_held_out_part_is_the_end_of_the_budget(tmp_path):
    assert heldout_after(10000, 0.25) == 7500
    with pytest.raises(ValueError):
        heldout_after(10000, 1.0)
    spec = replace(specs.load('doorkey'), out=str(tmp_path), budget=10000)
    assert 'heldout_after: 7500' in engine.write_params(spec).read_text()
    for name, memory, revisits in [  # each the learner it ran with
            ('doorkey', 0.0, 0.0), ('doorkey_every_step', 0.0, 0.0), ('doorkey_memory', 1.0, 0.0),
            ('doorkey_every_step_memory', 1.0, 0.0), ('doorkey_every_step_revisits', 1.0, 0.5),
            ('doorkey_every_move', 1.0, 0.5)]:
        learner = specs.load(name).parameters['tamer_node']
        assert (learner['verdict_memory'], learner['revisit_penalty']) == (memory, revisits)
    every_trial = engine.plan(spec, params=engine.write_params(spec))[0]
    assert every_trial and all(
        job.launcher_args[-2:] == ('--params-file', str(tmp_path / 'doorkey_study.yaml'))
        for job in every_trial)


def test_the_thesis_prediction_is_read_from_the_comparisons_when_a_condition_learned():
    def row(difference, p_holm):
        return {'difference': difference, 'p_holm': p_holm}

    none = report.prediction_when_learned({'language': row(0.15, 1.0),
                                           'language_input': row(1.16, 0.0001)})
    assert 'Not here' in none and 'did not help' in none and '+0.15' in none
    assert 'language_input, +1.16' in none
    assert 'language_input' not in report.prediction_when_learned(
        {'language': row(0.15, 1.0), 'language_input': row(0.3, 0.2)})
    assert 'the prediction holds' in report.prediction_when_learned(
        {'language': row(0.4, 0.01)})
    assert 'Not here' in report.prediction_when_learned({'language': row(-0.4, 0.01)})
    assert 'no language condition' in report.prediction_when_learned({})


def test_later_studies_are_summed_up_from_their_analysis_with_a_link(tmp_path):
    """The doorkey report ends with its follow-ups: a link, each condition's pooled held-out."""
    later = tmp_path / 'later'
    (later / 'trials').mkdir(parents=True)
    spec_file = tmp_path / 'later.yaml'
    spec_file.write_text(yaml.safe_dump({
        'extends': 'doorkey_human_like_asks', 'name': 'later', 'out': str(later),
        'report': str(later / 'report.md'), 'runs_dir': str(tmp_path / 'runs')}))
    records = {'vanilla': [record('vanilla', s, [[-1, 0, 1, 2]] * 3, 2) for s in range(2)]}
    (later / 'analysis.json').write_text(json.dumps(analysis.analyse(records, 10000)))
    path = tmp_path / 'docs' / 'results.md'
    lines = report.follow_ups([{'spec': str(spec_file), 'text': 'a later study'},
                               {'spec': 'doorkey_every_step', 'text': 'the reference'}], path)
    assert lines[0] == '## Later studies of this level'
    assert ('- [a later study](../later/report.md) (`attention_experiment later`): '
            'vanilla 2/2 = 1.00 (2 trials).') in lines
    assert any(line.startswith('- [the reference](') for line in lines)
    assert report.follow_ups([], path) == []
    # The doorkey study names its follow-ups; a study extending it may name none.
    assert [f['spec'] for f in specs.load('doorkey').settings['follow_ups']] == [
        'doorkey_every_step_revisits', 'doorkey_human_like_asks']
    assert specs.load('doorkey_memory').settings['follow_ups'] == []


def test_the_wrappers_spec_keeps_the_settings_it_does_not_set():
    """``attention_study_minigrid`` sets the held-out fraction, keeps the spec's other settings."""
    from attention_bringup.minigrid_study import cli
    spec = cli.spec_of(cli.argument_parser().parse_args(['--heldout-fraction', '0.5']))
    assert spec.settings['heldout_fraction'] == 0.5
    assert spec.settings['follow_ups'] == specs.load('doorkey').settings['follow_ups']
    reference = cli.spec_of(cli.argument_parser().parse_args(['--every-step-teacher']))
    assert reference.name == 'doorkey_every_step' and 'follow_ups' not in reference.settings
