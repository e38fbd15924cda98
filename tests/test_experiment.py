"""The experiment engine: specs, planning, and a whole run with a stand-in launcher (no ROS)."""

from dataclasses import replace
import json
from pathlib import Path
import shutil
import sys

from attention_bringup.experiment import cli, engine, runner, spec as specs
from attention_bringup.experiment.spec import SpecError
import pytest
from test_study_trials import FAKE_LAUNCHER
import yaml

GOOD = {'name': 'tiny', 'plugin': 'teaching', 'task': 'montezuma', 'budget': 20,
        'seeds': [0, 1], 'out': 'out', 'report': 'report.md', 'runs_dir': 'runs',
        'layout': 'by_arm', 'launcher_args': ['--trainer', 'teacher'],
        'arms': [{'name': 'plain', 'condition': 'vanilla', 'text': 'the plain arm'},
                 {'name': 'late', 'condition': 'vanilla', 'launcher_args': ['--human-like']}],
        'comparisons': [{'arm': 'late', 'baseline': 'plain'}],
        'measures': ['steps_to_key', 'lives_lost'],
        'targets': {'plain': {'min_keys': 1}}}


@pytest.mark.parametrize('name', sorted(p.stem for p in specs.SPEC_DIR.glob('*.yaml')))
def test_every_shipped_spec_loads_with_its_plugin(name):
    spec = specs.load(name)
    assert spec.name == name and spec.arms and spec.seeds and spec.budget > 0
    plugin = engine.plugin_of(spec)
    assert callable(plugin.analyse) and callable(plugin.write_report)


@pytest.mark.parametrize('change, says', [
    ({'budget': None}, 'missing field(s) budget'),
    ({'colour': 'red'}, 'unknown field(s) colour'),
    ({'budget': 0}, 'budget must be a positive'),
    ({'seeds': [1, 1]}, 'seeds repeat'),
    ({'seeds': {'start': 3}}, 'seeds as a mapping'),
    ({'layout': 'by_condition'}, 'two arms of one condition need layout: by_arm'),
    ({'arms': [{'name': 'x', 'condition': 'telepathy'}]}, "condition 'telepathy' is not one"),
    ({'arms': [{'name': 'vanilla'}, {'name': 'vanilla'}]}, 'arm names repeat'),
    ({'arms': [{'name': 'vanilla', 'colour': 1}]}, 'unknown field(s)'),
    ({'comparisons': [{'arm': 'late', 'baseline': 'nobody'}]}, "unknown arm 'nobody'"),
    ({'parameters': {'env_node': 3}}, 'parameters must map node names'),
    ({'arms': [{'name': 'x', 'condition': 'vanilla', 'parameters': ['mode']}]},
     'arm x: parameters must map node names'),
    ({'program': 'attention_dream'}, 'program must be attention_train or attention_replay'),
])
def test_a_bad_spec_is_refused_naming_the_file_and_what_is_wrong(tmp_path, change, says):
    data = {k: v for k, v in dict(GOOD, **change).items() if v is not None}
    path = tmp_path / 'bad.yaml'
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(SpecError) as error:
        specs.load(str(path))
    assert str(path) in str(error.value) and says in str(error.value)


def test_the_command_says_what_is_wrong_with_a_spec_and_exits_2(tmp_path, capsys):
    assert cli.main([str(tmp_path / 'missing.yaml')]) == 2
    assert 'cannot read it' in capsys.readouterr().err
    assert cli.main(['no_such_spec']) == 2
    assert 'teaching' in capsys.readouterr().err  # names the shipped ones


def test_a_spec_plans_seed_by_seed_with_each_arms_options_and_folders(tmp_path):
    spec = specs.from_dict(dict(GOOD, out=str(tmp_path / 'out'), runs_dir=str(tmp_path / 'r'),
                                parameters={'env_node': {'max_steps': 500}}))
    params = engine.write_params(spec)
    assert 'max_steps: 500' in params.read_text()
    jobs, kept = engine.plan(spec, params=params)
    assert kept == [] and [(job.arm, job.seed) for job in jobs] == [
        ('plain', 0), ('late', 0), ('plain', 1), ('late', 1)]
    late = jobs[1]
    assert late.result_path == tmp_path / 'out' / 'late' / 'trials' / 'vanilla' / 'seed0.json'
    assert late.run_dir == (tmp_path / 'r' / 'late' / 'vanilla' / 'seed0').resolve()
    assert late.launcher_args == ('--task', 'montezuma', '--trainer', 'teacher', '--human-like',
                                  '--params-file', str(params.resolve()))
    narrowed = spec.select(['late'], [1], 40)
    assert narrowed.comparisons == () and spec.select(['plain', 'late']).comparisons  # (a
    # comparison with an arm not run is dropped: the analysis would have crashed on it)
    assert [(job.arm, job.seed, job.steps) for job in engine.plan(narrowed)[0]] == [
        ('late', 1, 40)]
    with pytest.raises(SpecError, match="no arm 'other'"):
        spec.select(['other'])


@pytest.fixture
def stand_in(tmp_path, monkeypatch):
    """Write a spec of 2 arms x 2 seeds whose trials the stand-in launcher runs."""
    launcher = tmp_path / 'attention_train'
    launcher.write_text(FAKE_LAUNCHER.format(python=sys.executable))
    launcher.chmod(0o755)
    monkeypatch.setattr(runner, 'launcher_path', lambda: launcher)
    for arm in ('plain', 'late'):
        (tmp_path / 'runs' / arm).mkdir(parents=True)
        (tmp_path / 'runs' / arm / 'mode').write_text('ok')
    path = tmp_path / 'tiny.yaml'
    path.write_text(yaml.safe_dump(dict(GOOD, out=str(tmp_path / 'out'),
                                        report=str(tmp_path / 'report.md'),
                                        runs_dir=str(tmp_path / 'runs'))))
    return path


def test_a_spec_runs_resumes_and_reports_through_one_engine(tmp_path, stand_in, capsys):
    assert cli.main([str(stand_in), '--parallel', '2']) == 0
    out = tmp_path / 'out'
    files = sorted(str(p.relative_to(out)) for p in out.glob('*/trials/*/*.json'))
    assert files == ['late/trials/vanilla/seed0.json', 'late/trials/vanilla/seed1.json',
                     'plain/trials/vanilla/seed0.json', 'plain/trials/vanilla/seed1.json']
    log = json.loads((out / 'study_log.json').read_text())
    assert [(e['trials_run'], e['parallel'], e['backend']) for e in log] == [(4, 2, 'local')]
    analysis = json.loads((out / 'analysis.json').read_text())
    assert {name: s['n'] for name, s in analysis['settings'].items()} == {'plain': 2, 'late': 2}
    lives = analysis['settings']['plain']['lives_lost']
    assert set(lives) == {'n', 'mean', 'sd', 'low', 'high'}  # one estimate shape
    assert list(analysis['comparisons']['late vs plain']) == ['steps_to_key', 'lives_lost']
    report = (tmp_path / 'report.md').read_text()
    assert '- `plain`: the plain arm (`attention_train --condition vanilla `)' in report
    assert '| `late` | 2 |' in report
    assert '`plain`: key in at least 1 of 10. Measured: 0 of 2' in report
    # Resumed: every trial has its result, so nothing runs and the log gains no entry.
    capsys.readouterr()
    assert cli.main([str(stand_in)]) == 0
    assert '4 trial(s) already have results: skipped' in capsys.readouterr().err
    assert len(json.loads((out / 'study_log.json').read_text())) == 1
    # One arm's crashed trial runs again only when asked.
    crashed = out / 'late' / 'trials' / 'vanilla' / 'seed1.json'
    record = json.loads(crashed.read_text())
    crashed.write_text(json.dumps(dict(record, outcome='crashed')))
    assert cli.main([str(stand_in), '--report-only']) == 0
    assert cli.main([str(stand_in), '--retry-crashed', '--arms', 'late']) == 0
    assert json.loads(crashed.read_text())['outcome'] == 'completed'
    assert len(list((crashed.parent / 'retried').glob('*.json'))) == 1
    assert json.loads((out / 'study_log.json').read_text())[-1]['trials_run'] == 1


def test_a_spec_names_a_plugin_that_exists(tmp_path):
    spec = specs.from_dict(dict(GOOD, plugin='astrology'), 'my.yaml')
    with pytest.raises(SpecError, match="my.yaml: no plug-in 'astrology'"):
        engine.plugin_of(spec)


def test_parameters_every_trial_gets_are_written_as_yaml(tmp_path):
    spec = specs.from_dict(dict(GOOD, out=str(tmp_path), parameters={
        'env_node': {'heldout_after': 7500, 'note': 'a: b'}}))
    written = yaml.safe_load(engine.write_params(spec).read_text())
    assert written == {'env_node': {'ros__parameters': {'heldout_after': 7500, 'note': 'a: b'}}}


def test_an_arms_own_parameters_go_on_top_of_every_trials(tmp_path):
    arms = [{'name': 'plain', 'condition': 'vanilla'},
            {'name': 'blurred', 'condition': 'language_input',
             'parameters': {'saliency_node': {'mode': 'language'}}}]
    spec = specs.from_dict(dict(GOOD, out=str(tmp_path / 'out'), runs_dir=str(tmp_path / 'r'),
                                arms=arms, comparisons=[],
                                parameters={'env_node': {'max_steps': 500}}))
    params = engine.write_params(spec)
    jobs, _ = engine.plan(spec, params=params)
    plain, blurred = jobs[0], jobs[1]
    assert plain.launcher_args[-2:] == ('--params-file', str(params.resolve()))
    own = tmp_path / 'out' / 'blurred_params.yaml'
    assert blurred.launcher_args[-4:] == ('--params-file', str(params.resolve()),
                                          '--params-file', str(own.resolve()))
    assert yaml.safe_load(own.read_text()) == {
        'saliency_node': {'ros__parameters': {'mode': 'language'}}}
    assert not (tmp_path / 'out' / 'plain_params.yaml').exists()


def test_a_spec_extends_another_and_changes_only_what_it_says(tmp_path):
    base = dict(GOOD, parameters={'env_node': {'size': 8}, 'tamer_node': {'explore': 0.1,
                                                                          'alpha': 0.0}})
    (tmp_path / 'base.yaml').write_text(yaml.safe_dump(base))
    (tmp_path / 'more.yaml').write_text(yaml.safe_dump({
        'extends': 'base.yaml', 'name': 'more', 'out': 'out_more',
        'parameters': {'tamer_node': {'explore': 0.0}, 'saliency_node': {'mode': 'mask'}}}))
    spec, parent = specs.load(str(tmp_path / 'more.yaml')), specs.load(str(tmp_path / 'base.yaml'))
    assert (spec.name, spec.out, parent.name, parent.out) == ('more', 'out_more', 'tiny', 'out')
    assert spec.arms == parent.arms and spec.comparisons == parent.comparisons
    assert spec.parameters == {'env_node': {'size': 8}, 'saliency_node': {'mode': 'mask'},
                               'tamer_node': {'explore': 0.0, 'alpha': 0.0}}  # node by node
    # The words study's greedy first run is the words study with greedy learners, nothing else.
    words, greedy = specs.load('words'), specs.load('words_greedy')
    assert greedy.arms == words.arms and greedy.comparisons == words.comparisons
    assert greedy.settings == words.settings and greedy.seeds == words.seeds
    assert greedy.parameters == {'tamer_node': {'explore': 0.0}} and not words.parameters
    assert greedy.out != words.out and greedy.runs_dir != words.runs_dir
    # Settings are merged name by name: a DoorKey spec keeps its base's held-out fraction.
    asks, every_step = specs.load('doorkey_human_like_asks'), specs.load('doorkey_every_step')
    assert asks.settings['heldout_fraction'] == every_step.settings['heldout_fraction']
    assert 'budget_note' in asks.settings and 'budget_note' not in every_step.settings
    # A spec that extends itself, through another or not, is refused.
    (tmp_path / 'a.yaml').write_text(yaml.safe_dump({'extends': 'b.yaml'}))
    (tmp_path / 'b.yaml').write_text(yaml.safe_dump({'extends': 'a.yaml'}))
    with pytest.raises(SpecError, match='extends itself'):
        specs.load(str(tmp_path / 'a.yaml'))


def test_a_spec_of_one_arm_reports_without_an_empty_comparisons_table(tmp_path):
    # The words_budget study's own trial records, reported into a folder of the test's.
    records = Path(__file__).parent.parent / 'docs' / 'study_words_budget'
    out, report = tmp_path / 'out', tmp_path / 'budget.md'
    shutil.copytree(records / 'language_input_human_like', out / 'language_input_human_like')
    assert cli.main(['words_budget', '--report-only', '--out', str(out),
                     '--report', str(report)]) == 0
    text = report.read_text()
    assert '| `language_input_human_like` |' in text and '40000 agent steps' in text
    assert 'Comparisons' not in text


def test_a_replay_spec_runs_attention_replay_on_its_bag_and_no_budget_option(tmp_path):
    spec = specs.load('replay').select(seeds=[3], out=str(tmp_path / 'out'),
                                       runs_dir=str(tmp_path / 'runs'))
    jobs, _ = engine.plan(spec)
    assert [job.condition for job in jobs] == list(spec.arm_names)
    command = runner.launcher_command(tmp_path / 'bin' / 'attention_train', jobs[0])
    assert command[:3] == [str(tmp_path / 'bin' / 'attention_replay'), 'runs/replay_session',
                           '--fast']
    assert '--steps' not in command and command[command.index('--seed') + 1] == '3'
    assert command[command.index('--run-dir') + 1] == str(tmp_path / 'runs' / 'vanilla' / 'seed3')


def test_a_replay_spec_is_refused_without_its_bag_or_with_another_budget(tmp_path):
    from attention_bringup.experiment.plugins import replay
    from session_bag import metadata
    spec = specs.load('replay')
    with pytest.raises(SpecError, match='neither a bag folder'):
        replay.check(spec.select(budget=5000))  # (runs/replay_session is not recorded here)
    bag = tmp_path / 'bag'
    bag.mkdir()
    metadata.write(bag, {'rosbag2_bagfile_information': {'topics_with_message_count': [
        {'topic_metadata': {'name': '/observation'}, 'message_count': 120}]}})
    with pytest.raises(SpecError, match='holds 120 steps; set budget: 120'):
        replay.check(replace(spec, launcher_args=(str(bag), '--fast')))
    replay.check(replace(spec, launcher_args=(str(bag),), budget=120))


def test_a_replay_trials_steps_are_the_replays_own(tmp_path):
    from attention_bringup.experiment import trials
    run_dir = tmp_path / 'run'
    trials.write_json(run_dir / 'summary.json', {'kind': 'replay', 'status': 'completed',
                                                 'steps': 120})
    (run_dir / 'attention_replay.log').write_text('a node said why it stopped\n')
    record = trials.build_record('language', 3, 120, run_dir, 0, 5.0)
    assert (record['steps'], record['outcome']) == (120, trials.COMPLETED)
    short = trials.build_record('language', 3, 121, run_dir, 0, 5.0)
    assert short['outcome'] == trials.CRASHED
    assert 'said why' in short['problem']['launcher_output_tail']
