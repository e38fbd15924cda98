"""
Analysis, figures and report on synthetic trial result files (test inputs, not results).

Each test writes result files whose numbers it chooses, runs ``attention_study --analyze-only``
on them, and checks that the tables, tests and generated discussion follow those numbers.
"""

from pathlib import Path

from attention_bringup.experiment import trials
from attention_bringup.graph import CONDITIONS
from attention_bringup.study import analysis, cli, figures
from attention_common.run_files import STUDY_LOG
import pytest

BUDGET = 1000


def synthetic_record(condition, seed, firsts, outcome='completed', budget=BUDGET,
                     updates_per_step=1.0, at=None, h=None):
    """
    Return a result file of the real layout with the given first visits (position -> step).

    ``at`` (position -> steps there) and ``h`` add the later fields ``steps_at_position`` and
    ``feedback_mean``; without them the file is of the older kind.
    """
    first = {str(p): firsts.get(p) for p in trials.POSITIONS}
    visited = [p for p, step in firsts.items() if step is not None]
    curve = []
    for step in range(0, budget + 1, trials.CURVE_EVERY):
        reached = [p for p, s in firsts.items() if s is not None and s <= step]
        curve.append(max(reached, default=-1))
    later = {} if at is None else {
        'steps_at_position': {str(p): at.get(p, 0) for p in (-1,) + trials.POSITIONS},
        'feedback_mean': h}
    return {
        **later,
        'format': trials.FORMAT, 'condition': condition, 'seed': seed, 'budget': budget,
        'outcome': outcome, 'exit_code': 0 if outcome == 'completed' else 1,
        'launcher_status': 'completed' if outcome == 'completed' else 'node_failed',
        'steps': budget if outcome != trials.CRASHED else 10, 'wall_time_s': 60.0,
        'furthest_position': max(visited, default=-1), 'first_step_at_position': first,
        'key_pickups': int(5 in visited), 'key': 5 in visited, 'episodes': 4,
        'lives_lost': 3 + seed % 3, 'parameters': {'env_node.warmup_steps': 100},
        'learner_updates': round(updates_per_step * budget),
        'curve_every': trials.CURVE_EVERY, 'furthest_curve': curve, 'run_dir': 'synthetic',
        'problem': None if outcome == 'completed' else {
            'exit_text': 'synthetic failure', 'failed_node': 'tamer_node',
            'launcher_output_tail': '', 'node_log_tail': 'SyntheticError: test input'},
    }


def route(steps_per_position, until):
    """First visits 0..until at multiples of ``steps_per_position``."""
    return {p: steps_per_position * (p + 1) for p in range(until + 1)}


def write_study(out: Path, records):
    for record in records:
        trials.write_json(trials.trial_path(out, record['condition'], record['seed']), record)


def synthetic_study(out: Path, n=10):
    """Write a study: blind_saliency faster than the rest; hidden_agent never progresses."""
    records = []
    for seed in range(n):
        jitter = 7 * seed
        records.append(synthetic_record('vanilla', seed, route(150 + jitter, 1 + seed % 3)))
        records.append(synthetic_record('language', seed, route(152 + jitter, 1 + seed % 3)))
        records.append(synthetic_record('blind_obs', seed, route(149 + jitter, 1 + seed % 3)))
        records.append(synthetic_record('blind_saliency', seed, route(60 + jitter, 4)))
        records.append(synthetic_record('language_every_step', seed,
                                        route(155 + jitter, 1 + seed % 3)))
        records.append(synthetic_record('hidden_agent', seed, {}))
    records[1] = synthetic_record('language', 0, {0: 5}, outcome=trials.CRASHED)
    write_study(out, records)
    return records


@pytest.fixture
def no_figures(monkeypatch):
    """Skip drawing in tests that only read the report's text (drawing is slow on 2 cores)."""
    monkeypatch.setattr(figures, 'draw_all', lambda analysis, out_dir: {})


def run_analysis(tmp_path, extra=()):
    out, report = tmp_path / 'study', tmp_path / 'results.md'
    code = cli.main(['--analyze-only', '--steps', str(BUDGET), '--out', str(out),
                     '--report', str(report), *extra])
    return code, out, report


@pytest.fixture(scope='module')
def six_conditions(tmp_path_factory):
    """Analyse ``synthetic_study`` once for the tests that read its report."""
    tmp_path = tmp_path_factory.mktemp('six')
    synthetic_study(tmp_path / 'study')
    return run_analysis(tmp_path)


def test_report_has_every_section_table_and_figure(six_conditions):
    code, out, report = six_conditions
    assert code == 0
    text = report.read_text()
    for heading in ('## Protocol', '### Per condition', '### Reach rate per critical position',
                    '## Tests against vanilla', '## Figures', '## Discussion',
                    '## Trials that did not finish cleanly', '## Regenerate',
                    '## Appendix: every trial'):
        assert heading in text
    for name in ('figure_5_3', 'figure_5_4', 'all_conditions', 'reach_by_condition',
                 'furthest_position'):
        assert (out / f'{name}.png').read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
        assert f'](study/{name}.png)' in text
    assert (out / 'analysis.json').exists()
    # The crashed trial is listed with its log tail and left out of the statistics.
    assert '`language` seed 0: **crashed**' in text and 'SyntheticError: test input' in text
    assert '| `language` | 9/10 | crashed 1 |' in text
    assert 'Status: **incomplete**: 59 of 60 trials' in text
    # 5 conditions x 4 measures in the test table.
    tests = text.split('## Tests against vanilla')[1].split('## Figures')[0]
    assert sum(1 for line in tests.splitlines() if line.startswith('| `')) == 20
    assert ('.venv/bin/attention_study --trials 10 --steps 1000 --parallel 1 --out '
            f'{out} --report {report}') in text


def test_discussion_follows_the_numbers(six_conditions):
    _, _, report = six_conditions
    text = report.read_text()
    discussion = text.split('## Discussion')[1].split('## Trials that')[0]
    paragraphs = [p for p in discussion.split('\n\n') if p.startswith('*Thesis')]
    language, blind_obs, blind_saliency, every_step, hidden = paragraphs
    assert '**Agrees**: no difference between language and vanilla' in language
    assert '**Agrees** that performance was hardly affected' in blind_obs
    # blind_saliency was built faster at every position: better than both, significantly.
    assert 'blind_saliency is better than vanilla and language_every_step' in blind_saliency
    assert '**Agrees in part**' in blind_saliency
    assert '**Agrees**: no difference between language_every_step' in every_step
    assert 'Here 0 of 10 hidden_agent trials reached any critical position' in hidden
    assert hidden.rstrip().endswith('**Agrees**.')
    assert 'Confound' not in text  # every condition had one update per step


def test_a_significant_language_effect_is_reported_as_disagreement(tmp_path, no_figures):
    records = []
    for seed in range(10):
        records.append(synthetic_record('vanilla', seed, route(200 + 9 * seed, 1)))
        records.append(synthetic_record('language', seed, route(40 + 3 * seed, 4),
                                        updates_per_step=0.5))
    write_study(tmp_path / 'study', records)
    code, _, report = run_analysis(tmp_path, ['--conditions', 'vanilla', 'language'])
    assert code == 0
    text = report.read_text()
    assert '**Disagrees**: significant at 5 %' in text
    assert ('furthest position: language 4.00 vs vanilla 1.00 (better; the same value in '
            'every trial') in text
    assert 'Not assessed: too few finished trials of blind_obs' in text
    assert 'mean updates per step: vanilla 1.00, language 0.50' in text


def test_where_the_steps_go_table_and_the_reward_property(tmp_path, no_figures):
    records = [synthetic_record('vanilla', 0, {0: 10}, at={-1: 100, 0: 900}, h=0.8),
               synthetic_record('vanilla', 1, {0: 10, 1: 50}, at={-1: 500, 0: 300, 1: 200},
                                h=0.0),
               synthetic_record('vanilla', 2, {0: 10}),  # an older file: unknown, not zero
               synthetic_record('language', 0, {0: 10, 1: 20}, at={-1: 200, 1: 800}, h=0.6)]
    for record in records:
        record['parameters']['feedback_node.reward_variant'] = 'nearest'
    write_study(tmp_path / 'study', records)
    code, _, report = run_analysis(tmp_path, ['--conditions', 'vanilla', 'language',
                                              '--trials', '3'])
    assert code == 0
    text = report.read_text()
    assert '### Where the agent spends its steps' in text
    assert ('| `vanilla` | 2 | 30.0 % | 60.0 % | 10.0 % | 0.0 % | 0.0 % | 0.0 % | 0.0 % | '
            '0.40 ± 0.57 | 1/2 (pos 0: 1) |') in text
    assert '| all | 3 | 26.7 % | 40.0 % | 33.3 % |' in text
    paragraph = next(p for p in text.split('\n\n') if p.startswith('Reward property'))
    assert ('Over the 3 full trials with step counts, the agent spent on average 40.0 % of its '
            'recorded steps near position 0, 33.3 % near positions 1 to 5 and 26.7 % near '
            'none; mean h was +0.47.') in paragraph
    assert 'vanilla 60.0 % / 10.0 % / +0.40; language 0.0 % / 80.0 % / +0.60' in paragraph
    assert '(position 0 in 1, position 1 in 1)' in paragraph
    assert 'was not used in this study' in paragraph


def test_older_result_files_have_no_reward_property_paragraph(six_conditions):
    text = six_conditions[2].read_text()
    assert '| all | 0 | n/a |' in text and 'Reward property' not in text
    assert 'wall-clock' not in text


def test_floor_effect_is_named_when_vanilla_never_progresses(tmp_path, no_figures):
    records = [synthetic_record(c, seed, {0: 100 + seed} if seed % 2 else {})
               for c in ('vanilla', 'language') for seed in range(4)]
    write_study(tmp_path / 'study', records)
    _, _, report = run_analysis(tmp_path, ['--conditions', 'vanilla', 'language', '--trials',
                                           '4'])
    text = report.read_text()
    assert 'vanilla never reached positions 1 to 3 in any trial' in text
    assert 'identical constant samples' in text  # steps to 1..3: all budget + 1


def test_reach_curves_and_censoring(tmp_path):
    records = [synthetic_record('vanilla', 0, {0: 10, 2: 300}),
               synthetic_record('vanilla', 1, {0: 50}),
               synthetic_record('vanilla', 2, {}, outcome=trials.CRASHED)]
    summary = analysis.summarize_condition('vanilla', records)
    assert summary['usable'] == 2 and summary['outcomes'] == {'completed': 1 + 1,
                                                              'crashed': 1}
    assert summary['steps_to']['1']['reach']['k'] == 1  # via position 2
    assert summary['steps_to']['1']['reachers']['mean'] == 300
    assert summary['steps_to']['1']['censored']['mean'] == (300 + BUDGET + 1) / 2
    curve = analysis.reach_curve(records[:2], 0, [0, 10, 49, 50, 1000])
    assert curve['fraction'] == [0.0, 0.5, 0.5, 1.0, 1.0]
    assert curve['low'][1] < 0.5 < curve['high'][1]


def test_mixed_budgets_are_refused(tmp_path, no_figures):
    write_study(tmp_path / 'study', [synthetic_record('vanilla', 0, {}),
                                     synthetic_record('vanilla', 1, {}, budget=500)])
    code, _, _ = run_analysis(tmp_path, ['--conditions', 'vanilla'])
    assert code == 2


def test_existing_results_are_skipped_without_the_launcher(tmp_path, capsys, no_figures):
    out = tmp_path / 'study'
    write_study(out, [synthetic_record('vanilla', 0, route(100, 2))])
    code = cli.main(['--conditions', 'vanilla', '--trials', '1', '--steps', str(BUDGET),
                     '--out', str(out), '--report', str(tmp_path / 'r.md')])
    assert code == 0
    assert '1 trial(s) already have results: skipped' in capsys.readouterr().err
    assert not (out / 'runs').exists() and not (out / STUDY_LOG).exists()
    assert '| `vanilla` | 1/1 | none |' in (tmp_path / 'r.md').read_text()


@pytest.mark.parametrize('condition', CONDITIONS)
def test_every_condition_has_a_description(condition):
    from attention_bringup.study.report import CONDITION_TEXT
    assert CONDITION_TEXT[condition]


def test_hidden_agent_progress_is_compared_in_lives_and_feedback(tmp_path, no_figures):
    records = []
    for seed in range(3):
        records.append(synthetic_record('vanilla', seed, route(100, 2), at={0: 1000}, h=0.8))
        hidden = synthetic_record('hidden_agent', seed, route(100, 2), at={-1: 1000}, h=-0.1)
        hidden['lives_lost'] = 100 + seed  # vanilla: 3, 4, 5
        records.append(hidden)
    write_study(tmp_path / 'study', records)
    code, _, report = run_analysis(tmp_path, ['--conditions', 'vanilla', 'hidden_agent',
                                              '--trials', '3'])
    assert code == 0
    paragraph = next(p for p in report.read_text().split('\n\n')
                     if p.startswith('*Thesis: with the agent hidden'))
    assert '**Disagrees**' in paragraph
    assert ('it lost 101 lives per trial on average against 4 for vanilla, and its mean '
            'feedback was -0.10 against +0.80') in paragraph
