"""Unit tests of the launcher's pure parts: parameter files, conditions, plans, progress."""

import ast
import datetime
import json
from pathlib import Path

from attention_bringup import graph
from attention_bringup.gallery import cdr_header_stamp_ns, GalleryCollector
from attention_bringup.params import (
    dump_params, load_params_file, merge_params, node_params, ParamsFileError, parse_params)
from attention_bringup.plan import (
    build_plan, CONSOLE, Continuation, DEFAULT_STEPS, FEEDBACK_WAITS, LATE_FEEDBACK_LEARNER,
    LaunchOptions, parse_options, PERSON_ASK_BURST, PRESS_TIMES_CREDIT, REALTIME_RATE_HZ,
    TEACHING_GREEDY_MARGIN)
from attention_bringup.progress import (
    ALIVE_STEPS, format_bar, parse_value, ProgressTracker, RECENT_ROWS, RECENT_STAMPS)
from attention_bringup.report import ProgressWriter, read_rows_for_plot
from attention_common.run_files import node_log, of_session, OVERRIDES_FILE
from attention_tasks.montezuma.critical_positions import CRITICAL_POSITIONS, DEFAULT_RADIUS
from feedback_node.judging import TRAINERS
import pytest
from saliency_node.saliency import BLUR_RADIUS
from tamer_node.config import TamerConfig
from trainer_console.config import ConsoleConfig

BIN = Path('/opt/venv/bin')
LAUNCH_FILE = (Path(__file__).resolve().parents[1] / 'src' / 'attention_bringup' / 'launch'
               / 'attention.launch.py')

# What each study condition must fix (issue 7 / thesis chapter 5).
CONDITION_TABLE = {
    'vanilla': ('off', True, -1.0, 0.0, 'observation'),
    'language': ('language', True, 10.0, 1e-4, 'observation'),
    'blind_obs': ('blind_agent', False, 10.0, 0.0, 'saliency'),
    'blind_saliency': ('blind_agent', False, 10.0, 1e-4, 'observation'),
    'language_every_step': ('language', True, 0.0, 1e-4, 'observation'),
    'hidden_agent': ('hidden_agent', False, 10.0, 0.0, 'saliency'),
    'language_input': ('mask', False, 10.0, 0.0, 'both'),  # issue 25, beside the six
    'text_film': ('off', True, 10.0, 0.0, 'observation'),  # issue 25, the peer
}


# -- parameter files ------------------------------------------------------------------------

def test_parse_flattens_namespaces_and_normalises_node_names():
    parsed = parse_params("""
/env_node:
  ros__parameters:
    seed: 3
    train: {lr: 0.5, batch: {size: 16}}
""")
    assert parsed == {'env_node': {'seed': 3, 'train.lr': 0.5, 'train.batch.size': 16}}


def test_later_layer_wins_and_wildcard_is_underneath():
    first = parse_params('/**:\n  ros__parameters: {use_sim_time: true, seed: 1}\n'
                         'tamer_node:\n  ros__parameters: {alpha: 0.1}\n')
    second = parse_params('tamer_node:\n  ros__parameters: {alpha: 0.0, seed: 9}\n')
    merged = merge_params([first, second])
    assert node_params(merged, 'tamer_node') == {'use_sim_time': True, 'seed': 9, 'alpha': 0.0}
    assert node_params(merged, 'env_node') == {'use_sim_time': True, 'seed': 1}


@pytest.mark.parametrize('text, message', [
    ('env_node: [1, 2', 'not valid YAML'),
    ('- a\n- b\n', 'top level'),
    ('env_node:\n  seed: 1\n', 'ros__parameters'),
    ('env_node:\n  ros__parameters: [1]\n', 'must be a mapping'),
    ('env_node:\n  ros__parameters:\n    seed:\n', 'has no value'),
])
def test_malformed_files_are_rejected_with_a_reason(text, message):
    with pytest.raises(ParamsFileError, match=message):
        parse_params(text, 'x.yaml')


def test_missing_file_is_named(tmp_path):
    with pytest.raises(ParamsFileError, match='nope.yaml'):
        load_params_file(tmp_path / 'nope.yaml')


def test_dump_round_trips_and_quotes_yaml_booleans():
    params = {'saliency_node': {'mode': 'off', 'blur_radius': 3, 'a.b': 0.0001},
              'feedback_node': {'synthetic': False, 'utterance_interval': 10.0}}
    text = dump_params(params, header='two\nlines')
    assert text.startswith('# two\n# lines\n')
    assert parse_params(text) == params


# -- the shipped YAML files -----------------------------------------------------------------

def test_graph_yaml_names_every_node_and_no_clock_subscription():
    params = load_params_file(graph.graph_file())
    assert set(params) == set(graph.NODES)
    for node in graph.NODES:  # time comes from message stamps, not /clock
        assert params[node].get('use_sim_time', True) is False, node


@pytest.mark.parametrize('condition', graph.CONDITIONS)
def test_condition_fixes_its_parameters(condition):
    mode, require_utterance, interval, alpha, input_image = CONDITION_TABLE[condition]
    merged = merge_params(load_params_file(p) for p in graph.base_params_files(condition))
    assert node_params(merged, 'saliency_node')['mode'] == mode
    assert node_params(merged, 'saliency_node')['require_utterance'] is require_utterance
    assert node_params(merged, 'feedback_node')['utterance_interval'] == interval
    assert node_params(merged, 'tamer_node')['alpha'] == pytest.approx(alpha, abs=0)
    assert node_params(merged, 'tamer_node')['input_image'] == input_image
    # Floats stay floats, so a node that declared a double accepts them.
    assert isinstance(node_params(merged, 'feedback_node')['utterance_interval'], float)
    assert isinstance(node_params(merged, 'tamer_node')['alpha'], float)


def test_conditions_differ_pairwise():
    def fixed(condition):
        merged = merge_params(load_params_file(p) for p in graph.base_params_files(condition))
        return tuple(sorted((node, tuple(sorted(node_params(merged, node).items())))
                            for node in graph.NODES))
    assert len({fixed(c) for c in graph.CONDITIONS}) == len(graph.CONDITIONS)


def test_unknown_condition_is_refused():
    with pytest.raises(ValueError, match='unknown condition'):
        graph.condition_file('telepathy')


# -- options and plans ----------------------------------------------------------------------

def test_options_defaults_and_repeated_params_files():
    options = parse_options(['--params-file', 'a.yaml', '--params-file', 'b.yaml'])
    assert options.steps == DEFAULT_STEPS
    assert options.condition == 'language'
    assert options.params_files == ['a.yaml', 'b.yaml']
    assert options.synthetic and not options.realtime and options.seed is None


@pytest.mark.parametrize('argv', [['--steps', '0'], ['--condition', 'nope'], ['--seed', 'x']])
def test_bad_options_exit(argv):
    with pytest.raises(SystemExit):
        parse_options(argv)


def _plan(tmp_path, **kwargs):
    now = datetime.datetime(2025, 1, 2, 3, 4, 5)
    return build_plan(LaunchOptions(**kwargs), BIN, tmp_path, now=now)


def test_plan_starts_four_executables_with_files_in_order(tmp_path):
    user = tmp_path / 'mine.yaml'
    user.write_text('tamer_node:\n  ros__parameters: {alpha: 0.5}\n')
    plan = _plan(tmp_path, steps=123, condition='blind_obs', params_files=['mine.yaml'])
    assert plan.run_dir == tmp_path / 'runs' / '20250102-030405-blind_obs-seed0'
    expected_files = [graph.graph_file(), graph.condition_file('blind_obs'), user,
                      plan.run_dir / OVERRIDES_FILE]
    assert plan.params_files == expected_files
    assert [c.name for c in plan.commands] == list(graph.NODES)
    for command in plan.commands:
        assert command.argv[:2] == [str(BIN / command.name), '--ros-args']
        assert command.argv[2::2] == ['--params-file'] * len(expected_files)
        assert command.argv[3::2] == [str(p) for p in expected_files]
        assert command.log_path == plan.run_dir / 'logs' / f'{command.name}.log'
    assert plan.effective['env_node']['max_steps'] == 123
    assert plan.effective['tamer_node']['alpha'] == 0.5  # the user's file beats the condition
    assert plan.effective['tamer_node']['input_image'] == 'saliency'
    assert plan.effective['tamer_node']['run_dir'] == str(plan.run_dir)


def test_node_logs_and_archived_summaries_are_named_per_session():
    assert node_log('tamer_node') == 'logs/tamer_node.log'
    assert node_log('tamer_node', 2) == 'logs/tamer_node.session2.log'
    assert of_session('summary.json', 1) == 'summary.session1.json'
    assert of_session('summary.json', '*') == 'summary.session*.json'


def test_graph_yaml_writes_the_defaults_defined_in_code():
    params = load_params_file(graph.graph_file())
    assert params['feedback_node']['alpha_threshold'] == DEFAULT_RADIUS
    assert params['saliency_node']['blur_radius'] == BLUR_RADIUS


def test_progress_counts_critical_positions_with_the_feedback_nodes_radius(tmp_path):
    assert _plan(tmp_path).critical_radius == DEFAULT_RADIUS
    user = tmp_path / 'near.yaml'
    user.write_text('feedback_node:\n  ros__parameters: {alpha_threshold: 5.0}\n')
    assert _plan(tmp_path, params_files=['near.yaml']).critical_radius == 5.0


def test_plan_overrides_follow_the_options(tmp_path):
    plan = _plan(tmp_path, seed=7, realtime=True, synthetic=False, run_dir='out/r1')
    assert plan.run_dir == tmp_path / 'out' / 'r1'
    assert plan.overrides['env_node']['rate_hz'] == REALTIME_RATE_HZ
    assert isinstance(plan.overrides['env_node']['rate_hz'], float)
    assert plan.overrides['feedback_node']['synthetic'] is False
    assert plan.overrides['tamer_node']['credit'] == 'window'
    assert plan.overrides['tamer_node']['pace_updates'] == 0.0  # the env does not wait
    assert plan.overrides['env_node']['seed'] == 7
    for node in graph.NODES:  # every node that has a seed gets the run's seed
        if 'seed' in load_params_file(graph.graph_file()).get(node, {}):
            assert plan.effective[node]['seed'] == 7
    assert parse_params(plan.overrides_text()) == plan.overrides


def test_plan_without_options_changes_only_budget_run_dir_and_trainer(tmp_path):
    plan = _plan(tmp_path)
    # env_node waits for the graph's own listeners, as in the launch file: the launcher hears
    # env_status before the learners start, so it sees the first step without a wait of its own.
    assert plan.overrides == {'env_node': {'max_steps': DEFAULT_STEPS,
                                           'wait_status_subscribers': 2},
                              'feedback_node': {'trainer': 'teacher',
                                                'wait_feedback_subscribers': 2,
                                                'wait_utterance_subscribers': 2,
                                                **FEEDBACK_WAITS},
                              'tamer_node': {'run_dir': str(plan.run_dir),
                                             'greedy_margin': TEACHING_GREEDY_MARGIN}}


def test_the_thesis_trainer_is_one_option_away_and_human_like_is_named(tmp_path):
    thesis = _plan(tmp_path, trainer='thesis')
    assert thesis.effective['feedback_node']['trainer'] == 'thesis'
    assert 'greedy_margin' not in thesis.overrides.get('tamer_node', {})
    assert 'greedy_margin' not in _plan(tmp_path, thesis_learner=True).overrides['tamer_node']
    assert thesis.effective['feedback_node']['feedback_probability'] == 1.0
    human = _plan(tmp_path, human_like=True)
    feedback = human.effective['feedback_node']
    assert feedback['trainer'] == 'teacher'
    assert (feedback['feedback_probability'], feedback['feedback_delay_min'],
            feedback['feedback_delay_max'], feedback['feedback_noise']) == (0.33, 0.3, 1.5, 0.1)
    assert human.effective['tamer_node']['credit'] == 'window'
    assert (human.effective['tamer_node']['window_min_s'],
            human.effective['tamer_node']['window_max_s']) == (0.2, 1.6)
    options = parse_options(['--trainer', 'thesis', '--human-like'])
    assert (options.trainer, options.human_like) == ('thesis', True)
    with pytest.raises(SystemExit):
        parse_options(['--trainer', 'oracle'])


def test_the_late_learner_is_one_option_away_with_late_feedback(tmp_path):
    for options in ({'human_like': True}, {'synthetic': False}):
        tamer = _plan(tmp_path, late_learner=True, **options).effective['tamer_node']
        assert tamer['credit'] == 'window'
        assert {name: tamer[name] for name in LATE_FEEDBACK_LEARNER} == LATE_FEEDBACK_LEARNER
        plain = _plan(tmp_path, **options).effective['tamer_node']  # Deep TAMER's window
        assert not set(LATE_FEEDBACK_LEARNER) & set(plain)
    for extra in ({}, {'thesis_learner': True}):  # stamped feedback, or the thesis's learner
        tamer = _plan(tmp_path, late_learner=True, human_like=bool(extra), **extra)
        assert not set(LATE_FEEDBACK_LEARNER) & set(tamer.effective['tamer_node'])
    defaults = TamerConfig()  # each one a real parameter, whose default is the thesis's
    assert all(getattr(defaults, name) != value for name, value in LATE_FEEDBACK_LEARNER.items())
    assert parse_options(['--human-like', '--late-learner']).late_learner


def test_the_learner_asks_the_teacher_one_option_away(tmp_path):
    tamer = _plan(tmp_path, human_like=True, ask=0.15).effective['tamer_node']
    assert tamer['ask_rate'] == 0.15 and tamer['credit'] == 'window'  # the rest: the window
    assert 'ask_rate' not in _plan(tmp_path, human_like=True).effective['tamer_node']
    assert TamerConfig().ask_rate == 0.0  # never asks unless told (the thesis's learner)
    for options, problem in (({'synthetic': False}, 'add --console'),
                             ({'trainer': 'thesis'}, 'only the teacher answers'),
                             ({'ask': 1.5}, 'in \\[0, 1\\]')):
        with pytest.raises(ValueError, match=problem):
            _plan(tmp_path, **dict({'ask': 0.15}, **options))
    assert parse_options(['--human-like', '--ask', '0.2']).ask == 0.2
    assert 'ask_burst' not in tamer  # the teacher answers a burst at once


def test_a_person_answers_the_learners_questions_at_the_console(tmp_path):
    plan = _plan(tmp_path, synthetic=False, console=True, ask=0.02)
    tamer = plan.effective['tamer_node']
    assert (tamer['ask_rate'], tamer['ask_burst']) == (0.02, PERSON_ASK_BURST) == (0.02, 1.0)
    console = next(command for command in plan.commands if command.name == CONSOLE)
    assert not any('answer_questions' in arg for arg in console.argv)  # its default: shown
    assert ConsoleConfig().answer_questions
    # The teacher answers for itself: a console that watches it never pauses the env to ask.
    watched = _plan(tmp_path, console=True, ask=0.25, human_like=True)
    console = next(command for command in watched.commands if command.name == CONSOLE)
    assert 'answer_questions:=false' in console.argv


def test_the_learner_knows_plain_copies_only_when_the_trainer_sends_them(tmp_path):
    copies = tmp_path / 'copies.yaml'
    copies.write_text('feedback_node:\n  ros__parameters: {plain_copies: true}\n')
    tamer = _plan(tmp_path, params_files=['copies.yaml']).effective['tamer_node']
    assert tamer['plain_copies'] is True
    assert 'plain_copies' not in _plan(tmp_path).effective['tamer_node']
    assert TamerConfig().plain_copies is False  # every plain feedback its own


@pytest.mark.parametrize('options, readers', [
    ({}, 2), ({'synthetic': False}, 3), ({'console': True}, 3),
    ({'synthetic': False, 'console': True}, 4), ({'realtime': True}, 2)])
def test_the_env_waits_for_every_reader_of_env_status_when_the_teacher_judges(
        tmp_path, options, readers):
    # The monitor and the teacher, the recorder (a person's session) and the console: all
    # of them read env_status, so with fewer the teacher could be the one not yet matched.
    plan = _plan(tmp_path, **options)
    assert plan.effective['env_node']['wait_status_subscribers'] == readers
    # The thesis's trainer hears agent_position only: the env waits for its position reader.
    thesis = _plan(tmp_path, trainer='thesis', **options).effective['env_node']
    assert thesis.get('wait_status_subscribers', 0) == 0


def test_seed_of_the_run_dir_comes_from_the_files(tmp_path):
    user = tmp_path / 'seed.yaml'
    user.write_text('env_node:\n  ros__parameters: {seed: 42}\n')
    plan = _plan(tmp_path, params_files=[str(user)])
    assert plan.seed == 42 and plan.run_dir.name.endswith('-language-seed42')


def test_plan_with_a_missing_user_file_fails(tmp_path):
    with pytest.raises(ParamsFileError, match='absent.yaml'):
        _plan(tmp_path, params_files=['absent.yaml'])


# -- the launch file stays in step with the launcher ----------------------------------------

def _launch_constants():
    tree = ast.parse(LAUNCH_FILE.read_text())
    constants = {}
    for statement in tree.body:
        if isinstance(statement, ast.Assign) and isinstance(statement.targets[0], ast.Name):
            try:
                constants[statement.targets[0].id] = ast.literal_eval(statement.value)
            except ValueError:
                pass
    return tree, constants


def test_launch_file_names_the_same_executables_and_files():
    tree, constants = _launch_constants()
    assert constants['NODES'] == graph.NODES
    assert constants['CONDITIONS'] == graph.CONDITIONS
    assert constants['GRAPH_FILE'] == graph.GRAPH_FILE
    assert constants['CONDITIONS_DIR'] == graph.CONDITIONS_DIR
    assert constants['TASKS_DIR'] == graph.TASKS_DIR
    assert constants['DEFAULT_TASK'] == LaunchOptions().task
    assert constants['TRAINERS'] == TRAINERS
    assert constants['TEACHING_GREEDY_MARGIN'] == TEACHING_GREEDY_MARGIN
    functions = {node.name for node in tree.body if isinstance(node, ast.FunctionDef)}
    assert 'generate_launch_description' in functions
    defaults = {call.args[0].value: kw.value.value for call in ast.walk(tree)
                if isinstance(call, ast.Call) and getattr(call.func, 'id', '') ==
                'DeclareLaunchArgument' for kw in call.keywords if kw.arg == 'default_value'}
    assert defaults['condition'] == graph.DEFAULT_CONDITION
    assert defaults['trainer'] == LaunchOptions().trainer
    assert defaults['task'] == LaunchOptions().task
    for condition in graph.CONDITIONS:
        assert graph.condition_file(condition).is_file()


# -- progress -------------------------------------------------------------------------------

@pytest.mark.parametrize('text, value', [
    ('true', True), ('false', False), ('12', 12), ('-1.5', -1.5), ('abc', 'abc')])
def test_parse_value(text, value):
    assert parse_value(text) == value and type(parse_value(text)) is type(value)


def _tracker():
    # Position 0 at x < 10, position 2 at x > 100, in between otherwise.
    return ProgressTracker(position_of=lambda x, y: 0 if x < 10 else (2 if x > 100 else -1))


def _status(step, x, room=1, **values):
    return {'agent_step': step, 'x': x, 'y': 0, 'room': room, **values}


def test_tracker_rows_from_status_keep_the_furthest_and_the_latencies():
    tracker = _tracker()
    tracker.on_status(100, _status(1, 5, episode=0, action_latency_ms=-1.0), 0.1)
    tracker.on_status(200, _status(2, 150, episode=0, action_latency_ms=3.5), 0.2)
    tracker.on_status(300, _status(3, 50, episode=1, life_lost=True, action_latency_ms=1.25), 0.3)
    assert [r['agent_step'] for r in tracker.rows] == [1, 2, 3]
    assert [r['position'] for r in tracker.rows] == [0, 2, -1]
    assert [r['furthest_position'] for r in tracker.rows] == [0, 2, 2]
    assert tracker.first_step_at == {0: 1, 2: 2}
    assert tracker.lives_lost == 1 and tracker.episodes == {(1, 0), (1, 1)}
    assert tracker.latencies_ms.count == 2  # the first step answered nothing
    assert tracker.latency_ms(50) == pytest.approx(1.25, rel=0.01)
    assert tracker.latency_ms(100) == pytest.approx(3.5, rel=0.01)
    assert [r['agent_step'] for r in tracker.take_new_rows()] == [1, 2, 3]
    assert tracker.take_new_rows() == [] and tracker.row_count == 3


def test_tracker_counts_a_position_stood_on_only_when_held_and_alive_a_second_later():
    tracker = ProgressTracker(position_of=lambda x, y: 2 if x > 100 else -1,
                              standing_poses=frozenset({8}))
    step = 0

    def feed(x, pose, n=1, **values):
        nonlocal step
        for _ in range(n):
            step += 1
            tracker.on_status(step * 100, _status(step, x, pose=pose, episode=0, **values), 0.0)

    feed(150, pose=6, n=3)             # passing position 2 in mid-jump: passed, not stood on
    feed(150, pose=8, n=2)             # standing on it, ...
    feed(50, pose=22, n=3)             # ... then dying
    feed(50, pose=22, life_lost=True)
    feed(50, pose=8, n=ALIVE_STEPS + 2)
    assert tracker.furthest == 2 and tracker.furthest_stood == -1
    feed(150, pose=8)                  # standing on it, alive ALIVE_STEPS steps later
    feed(60, pose=8, n=ALIVE_STEPS)
    assert tracker.furthest_stood == 2 and tracker.first_step_stood_at == {2: step - ALIVE_STEPS}
    assert tracker.first_key_step is None
    feed(60, pose=8, has_key=True)
    feed(60, pose=8, n=2, has_key=True)
    assert tracker.first_key_step == step - 2 and tracker.keys == 1


def test_tracker_ignores_other_rooms_and_repeated_steps():
    tracker = _tracker()
    tracker.on_status(100, _status(1, 150, room=2), 0.1)  # Room 2: not Room 1's positions
    tracker.on_status(100, _status(1, 150, room=2, action_latency_ms=2.0), 0.2)  # sent again
    assert len(tracker.rows) == 1 and tracker.furthest == -1 and tracker.latency_ms(50) is None
    tracker.on_status(200, _status(2, 50, finished=True), 0.3)
    assert tracker.finished and len(tracker.rows) == 2


def test_tracker_rate():
    tracker = _tracker()
    for step in range(11):
        tracker.on_status(step, _status(step, 50), step * 0.5)
    assert tracker.rate() == pytest.approx(2.0)


def test_the_tracker_stays_bounded_however_long_the_run(tmp_path):
    tracker = _tracker()
    writer = ProgressWriter(tmp_path / 'progress.csv')
    steps = RECENT_ROWS * 3
    for step in range(1, steps + 1):
        tracker.on_status(step * 100, _status(step, 150 if step == 4000 else 5, episode=0,
                                              action_latency_ms=float(step % 100)), step / 100)
        if step % 500 == 0:
            writer.write(tracker.take_new_rows())
    writer.close()
    assert len(tracker.rows) == RECENT_ROWS and tracker.rows[-1]['agent_step'] == steps
    assert len(tracker.step_at_stamp) <= RECENT_STAMPS and tracker.first_row['agent_step'] == 1
    assert tracker.latency_ms(50) == pytest.approx(49, rel=0.02)
    assert tracker.latency_ms(99) == pytest.approx(98, rel=0.02)
    with open(tmp_path / 'progress.csv') as file:
        assert sum(1 for _ in file) == steps + 1  # every row on disk, once
    thinned = read_rows_for_plot(tmp_path / 'progress.csv', steps, most=100)
    assert 100 <= len(thinned) <= 103
    assert 4000 in [row['agent_step'] for row in thinned]  # where the furthest grew


def test_bar():
    bar = format_bar(50, 200, 10.0, 49, 3, episode=1, lives=5)
    assert '50/200 steps' in bar and 'ETA 0:15' in bar and 'feedback 49' in bar
    assert 'furthest position 3' in bar and bar.count('#') == 6


# -- gallery --------------------------------------------------------------------------------

def _serialized_image(stamp_ns):
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import Image
    msg = Image(height=1, width=1, encoding='mono8', step=1, data=b'\x07')
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp_ns, 1_000_000_000)
    return serialize_message(msg)


def test_stamp_is_read_from_the_serialized_bytes():
    assert cdr_header_stamp_ns(_serialized_image(12_345_678_901)) == 12_345_678_901
    with pytest.raises(ValueError):
        cdr_header_stamp_ns(b'\x07\x07' + bytes(10))


def test_gallery_takes_a_complete_step_after_an_utterance():
    gallery = GalleryCollector(capacity=2, patience=3)
    gallery.on_image('observation', 1, b'o1')  # before any request: not taken
    gallery.on_utterance(1, 'climb the ladder')
    gallery.on_image('observation', 2, b'o2')
    gallery.on_image('saliency', 2, b's2')
    assert not gallery.samples
    gallery.on_image('saliency_mask', 2, b'm2')
    sample = gallery.samples[0]
    assert (sample.stamp_ns, sample.utterance, sample.observation, sample.mask,
            sample.saliency) == (2, 'climb the ladder', b'o2', b'm2', b's2')
    gallery.on_utterance(3, 'climb the ladder')  # the same words again: no new sample
    assert not gallery.waiting


def test_gallery_falls_back_to_the_frame_alone():
    gallery = GalleryCollector(capacity=1, patience=2)
    gallery.on_schedule(step=40, budget=100)
    assert not gallery.waiting  # the first slot of one sample is mid-run
    gallery.on_schedule(step=50, budget=100)
    assert gallery.waiting
    for stamp in (5, 6, 7):
        gallery.on_image('observation', stamp, b'o%d' % stamp)
    assert gallery.samples[0].observation == b'o7' and gallery.samples[0].saliency is None
    assert gallery.full


def test_the_domain_is_the_users_when_chosen():
    from attention_bringup.plan import chosen_domain
    assert chosen_domain(parse_options([]), {}) is None
    assert chosen_domain(parse_options([]), {'ROS_DOMAIN_ID': '42'}) == 42
    assert chosen_domain(parse_options(['--domain', '7']), {'ROS_DOMAIN_ID': '42'}) == 7
    with pytest.raises(ValueError, match='ROS_DOMAIN_ID'):
        chosen_domain(parse_options([]), {'ROS_DOMAIN_ID': '500'})
    with pytest.raises(SystemExit):
        parse_options(['--domain', '-1'])


def test_the_summary_counts_what_the_learner_logged(tmp_path):
    from attention_bringup.report import learner_log_counts, summary_lines
    log = tmp_path / 'feedback_log.jsonl'
    lines = [{'kind': 'feedback', 'seq': 1, 'h': 1.0, 'status': 'ok'},
             {'kind': 'feedback', 'seq': 2, 'h': 5.0, 'status': 'invalid'},
             {'kind': 'feedback', 'seq': 3, 'h': -1.0, 'status': 'ok'},
             {'kind': 'feedback', 'seq': 4, 'h': 1.0, 'status': 'ok'},
             {'kind': 'utterance', 'text': 'go', 'status': 'ok'}]
    log.write_text(''.join(json.dumps(line) + '\n' for line in lines) + '{"kind": "fee')
    counts = learner_log_counts(log)
    assert counts['feedback'] == 4 and counts['ok'] == 3 and counts['invalid'] == 1
    assert counts['utterances'] == 1 and counts['mean_h'] == pytest.approx(1 / 3, abs=1e-4)
    text = summary_lines({'learner_log': counts, 'utterance_count': 9})[1]
    assert 'feedback logged by the learner 4 (3 used, 1 invalid, mean h +0.33)' in text
    assert 'utterances 1' in text  # the learner's count, not the launcher's 9
    assert 'questions' not in text  # a learner that never asks
    asked = summary_lines({'learner_log': counts, 'metrics': {'ask/asked': 12}})[1]
    assert 'mean h +0.33), questions asked 12, utterances' in asked
    assert learner_log_counts(tmp_path / 'none.jsonl') is None


# -- another task ---------------------------------------------------------------------------

def test_task_doorkey_reaches_every_node_with_its_files_and_rate(tmp_path):
    from attention_tasks.gridworld import REALTIME_HZ
    plan = _plan(tmp_path, task='doorkey', realtime=True, human_like=True, console=True,
                 seed=3)
    for node in graph.NODES:
        assert plan.effective[node]['task'] == 'doorkey'
    assert graph.task_file('doorkey') in plan.params_files  # after graph.yaml, before the
    assert plan.params_files.index(graph.task_file('doorkey')) == 1  # condition
    assert plan.effective['env_node']['warmup_steps'] == 0  # the task's file, not Room 1's 100
    assert plan.overrides['env_node']['rate_hz'] == REALTIME_HZ
    assert (plan.effective['tamer_node']['window_min_s'],
            plan.effective['tamer_node']['window_max_s']) == (0.2, 2.5)  # 1.5 s late + 1 step
    for options in ({}, {'human_like': True}, {'synthetic': False}):  # issue 23's learner
        learner = _plan(tmp_path, task='doorkey', **options).effective['tamer_node']
        assert (learner['verdict_memory'], learner['positive_excludes'],
                learner['revisit_penalty']) == (1.0, 0.3, 0.5)
    room_1 = _plan(tmp_path).effective['tamer_node']
    assert room_1.get('verdict_memory', 0.0) == room_1.get('revisit_penalty', 0.0) == 0.0
    # --press-times: late verdicts carry the moment given; credited from then, one window.
    pressed = _plan(tmp_path, task='doorkey', human_like=True, press_times=True).effective
    assert pressed['feedback_node']['press_times'] is True
    assert {k: pressed['tamer_node'][k] for k in PRESS_TIMES_CREDIT} == {
        'credit_anchor': 'effect', 'window_min_s': 0.2, 'window_max_s': 1.6}
    assert 'press_times' not in _plan(tmp_path, task='doorkey', human_like=True).overrides[
        'feedback_node']
    assert parse_options(['--human-like', '--press-times']).press_times
    with pytest.raises(ValueError, match='add --human-like'):
        _plan(tmp_path, press_times=True)
    console = next(c for c in plan.commands if c.name == 'trainer_console')
    assert 'task:=doorkey' in console.argv
    assert 'doorkey-language-seed3' in _plan(tmp_path, task='doorkey', seed=3).run_dir.name
    assert parse_options(['--task', 'doorkey']).task == 'doorkey'


def test_a_person_training_fetch_gets_its_file_and_a_trained_model(tmp_path):
    model = tmp_path / 'trained' / 'checkpoints' / 'checkpoint.pt'
    model.parent.mkdir(parents=True)
    model.write_bytes(b'')
    options = parse_options(['--task', 'fetch', '--condition', 'language_input',
                             '--no-synthetic', '--initial-model', 'trained',
                             '--stall-timeout', '30'])
    plan = build_plan(options, BIN, tmp_path)
    person = graph.person_file('fetch')
    assert plan.params_files.index(person) == 3  # after the condition, before the user's
    assert plan.effective['env_node']['pause_each_episode'] is True
    assert plan.effective['saliency_node']['utterance_ttl'] == 50.0  # a whole episode
    assert plan.overrides['tamer_node']['initial_model'] == str(tmp_path / 'trained')
    assert options.stall_timeout == 30.0
    # The teacher's runs and the other tasks are as they were.
    assert person not in _plan(tmp_path, task='fetch').params_files
    assert not graph.person_file('doorkey').exists()
    with pytest.raises(ValueError, match='--initial-model elsewhere: no such run folder'):
        build_plan(parse_options(['--initial-model', 'elsewhere']), BIN, tmp_path)
    with pytest.raises(SystemExit):
        parse_options(['--stall-timeout', '0'])


def test_foxglove_adds_the_bridge_with_its_port_and_the_task(tmp_path):
    assert not any(c.name == 'graph_viewer' for c in _plan(tmp_path, seed=3).commands)
    plan = _plan(tmp_path, task='doorkey', foxglove=True, foxglove_port=9001, seed=3)
    bridge = next(c for c in plan.commands if c.name == 'graph_viewer')
    assert bridge.argv[0].endswith('/graph_viewer')
    assert 'port:=9001' in bridge.argv and 'task:=doorkey' in bridge.argv
    mine = tmp_path / 'mine.yaml'
    mine.write_text('graph_viewer:\n  ros__parameters:\n    legacy_subprotocol: false\n')
    plan = _plan(tmp_path, foxglove=True, params_files=[str(mine)])
    bridge = next(c for c in plan.commands if c.name == 'graph_viewer')
    assert bridge.argv[bridge.argv.index('--params-file') + 1] == str(mine)  # the user's only
    assert bridge.argv.count('--params-file') == 1
    options = parse_options(['--foxglove'])
    assert options.foxglove and options.foxglove_port == 8765  # Foxglove's own default


def test_room_one_runs_keep_their_parameter_files_and_names(tmp_path):
    plan = _plan(tmp_path, seed=3)
    assert all('task' not in values for values in plan.overrides.values())
    assert len(plan.params_files) == 3  # graph.yaml, the condition, the launcher's overrides
    assert plan.run_dir.name.endswith('-language-seed3')


def test_the_thesis_trainer_is_refused_for_another_task(tmp_path):
    with pytest.raises(ValueError, match='task doorkey is taught by the teacher'):
        _plan(tmp_path, task='doorkey', trainer='thesis')
    with pytest.raises(SystemExit):
        parse_options(['--task', 'pong'])


def test_the_tracker_counts_another_tasks_milestones_and_solved_episodes():
    from attention_tasks.task import load_task
    task = load_task('doorkey')
    tracker = ProgressTracker(position_of=lambda x, y: -1,
                              milestone_of=lambda values: task.milestone_of(values, 0.0),
                              solved_of=task.solved)
    for step, (subgoals, episode) in enumerate([(0, 0), (1, 0), (2, 0), (3, 0), (0, 1)], 1):
        tracker.on_status(step * 10**9, {'agent_step': step, 'subgoals': subgoals,
                                         'at_goal': subgoals == 3, 'episode': episode,
                                         'heldout': episode == 1, 'room': 0}, 0.0)
    rows = tracker.take_new_rows()
    assert [row['position'] for row in rows] == [-1, 0, 1, 2, -1]
    assert [row['heldout'] for row in rows] == [0, 0, 0, 0, 1]
    assert tracker.furthest == 2 and tracker.first_step_at == {0: 2, 1: 3, 2: 4}
    assert tracker.solved_episodes == {(1, 0)}


def test_a_summary_measures_each_task_in_its_own_terms():
    from attention_bringup.launcher import task_measures
    from attention_tasks.task import load_task
    doorkey = load_task('doorkey')
    tracker = ProgressTracker(milestone_of=lambda values: doorkey.milestone_of(values, 0.0),
                              solved_of=doorkey.solved)
    # Episode 0 trains and is solved; held-out episode 1 is solved, held-out episode 2 is not.
    steps = [(1, 0, 0), (2, 0, 0), (3, 0, 0), (0, 1, 1), (3, 1, 1), (2, 2, 1)]
    for step, (subgoals, episode, heldout) in enumerate(steps, 1):
        tracker.on_status(step * 10**9, {'agent_step': step, 'subgoals': subgoals,
                                         'at_goal': subgoals == 3, 'episode': episode,
                                         'heldout': heldout}, 0.0)
    measures = task_measures(doorkey, tracker)
    assert measures == {
        'milestones': ['key', 'door', 'goal'],
        'milestone_steps': {'key': 1, 'door': 2, 'goal': 3},
        'furthest_milestone': 'goal', 'episodes': 3, 'episodes_solved': 2,
        'heldout_episodes': 2, 'heldout_episodes_solved': 1}  # no Room 1 names

    room = load_task('montezuma')
    tracker = ProgressTracker(milestone_of=lambda values: room.milestone_of(values, 8.0))
    x, y = CRITICAL_POSITIONS[1]
    tracker.on_status(10**9, {'agent_step': 1, 'x': x, 'y': y, 'room': 1, 'episode': 0}, 0.0)
    measures = task_measures(room, tracker)
    assert measures['milestone_steps']['critical position 1'] == 1
    assert measures['furthest_milestone'] == 'critical position 1'
    assert measures['furthest_position'] == 1 and measures['first_step_at_position'] == {'1': 1}
    assert 'heldout_episodes' not in measures and measures['first_key_step'] is None


@pytest.mark.parametrize('synthetic, record, records', [
    (True, None, False), (False, None, True), (False, False, False), (True, True, True)])
def test_a_person_s_session_is_recorded_unless_asked_not_to(tmp_path, synthetic, record,
                                                            records):
    plan = _plan(tmp_path, synthetic=synthetic, record=record)
    recorders = [c for c in plan.commands if c.name == 'session_recorder']
    assert plan.options.records is records and len(recorders) == int(records)
    env, feedback = plan.effective['env_node'], plan.effective['feedback_node']
    # The env and the trainer wait for the recorder as for the learners: no step unrecorded.
    assert env.get('wait_observation_subscribers', 2) == 2 + records
    assert env.get('wait_position_subscribers', 1) == 1 + records
    # By name too: the console's and the launcher's readers never stand in for a learner's.
    assert env['wait_observation_nodes'].split(',') == (
        ['saliency_node', 'tamer_node'] + ['session_recorder'] * records)
    assert feedback['wait_feedback_subscribers'] == 2 + records
    assert feedback['wait_utterance_subscribers'] == 2 + records
    assert feedback['wait_feedback_nodes'].split(',') == (
        ['tamer_node'] + ['session_recorder'] * records)
    assert feedback['wait_utterance_nodes'].split(',') == (
        ['saliency_node', 'tamer_node'] + ['session_recorder'] * records)
    assert feedback['wait_utterance_stamped_nodes'].split(',') == (
        ['saliency_node'] + ['session_recorder'] * records)
    # The learners' outputs (actions, receipts, credit, metrics, saliency) wait for it too.
    for node in ('saliency_node', 'tamer_node'):
        expected = 'session_recorder' if records else ''
        assert plan.effective[node].get('wait_for_recorder', '') == expected, node
    if records:
        argv = recorders[0].argv
        assert argv[0] == str(BIN / 'session_recorder')
        assert f'bag_dir:={plan.run_dir / "bag"}' in argv
        assert f'run_dir:={plan.run_dir}' in argv
        resumed = build_plan(plan.options, BIN, tmp_path,
                             now=datetime.datetime(2025, 1, 2, 3, 4, 5),
                             continuation=Continuation(2, 10))
        bag = next(c for c in resumed.commands if c.name == 'session_recorder').argv
        assert f'bag_dir:={plan.run_dir / "bag.session2"}' in bag  # a bag per session
        # A resume that never got to a step left its bag: the next one goes beside it.
        (plan.run_dir / 'bag.session2').mkdir(parents=True)
        (plan.run_dir / 'bag.session2' / 'metadata.yaml').write_text('')
        again = build_plan(plan.options, BIN, tmp_path,
                           now=datetime.datetime(2025, 1, 2, 3, 4, 5),
                           continuation=Continuation(2, 10))
        assert again.bag_dir == plan.run_dir / 'bag.session2.2'


def test_record_options_parse():
    assert parse_options([]).record is None
    assert parse_options(['--record']).record is True
    assert parse_options(['--no-synthetic', '--no-record']).records is False


def test_a_knob_changes_one_part_of_the_human_like_setting_and_the_credit_follows(tmp_path):
    # A person at the console judges most moves, late and sometimes wrong: --knob says so.
    every_move = _plan(tmp_path, task='doorkey', human_like=True,
                       knobs=['feedback_probability=1']).effective
    assert every_move['feedback_node']['feedback_probability'] == 1.0
    assert (every_move['feedback_node']['feedback_delay_max'],
            every_move['feedback_node']['feedback_noise']) == (1.5, 0.1)  # the rest as named
    sooner = _plan(tmp_path, task='doorkey', human_like=True, press_times=True,
                   knobs=['feedback_delay_min=0.1', 'feedback_delay_max=0.6']).effective
    assert sooner['feedback_node']['feedback_delay_max'] == 0.6
    assert (sooner['tamer_node']['window_min_s'], sooner['tamer_node']['window_max_s']) == (
        0.2, 0.7)  # the credit window follows the delay
    plain = _plan(tmp_path, task='doorkey', human_like=True,
                  knobs=['feedback_delay_max=0.6']).effective['tamer_node']
    assert plain['window_max_s'] == 1.6  # 0.6 s late + one 1 s step
    assert parse_options(['--human-like', '--knob', 'feedback_noise=0']).knobs == [
        'feedback_noise=0']
    for knobs, message in ((['feedback_probabilty=1'], 'one of'), (['feedback_noise=x'],
                           'not a number'), (['feedback_noise=2'], r'\[0, 1\]')):
        with pytest.raises(ValueError, match=message):
            _plan(tmp_path, human_like=True, knobs=knobs)
    with pytest.raises(ValueError, match='add --human-like'):
        _plan(tmp_path, knobs=['feedback_probability=1'])


# -- acting first (issue 26) ------------------------------------------------------------------

def test_acting_first_idles_every_process_off_the_acting_path(tmp_path):
    plain = _plan(tmp_path, condition='language', console=True, foxglove=True, record=True)
    assert not any(command.idle for command in plain.commands)  # off by default
    idle = {command.name: command.idle for command in _plan(
        tmp_path, condition='language', console=True, foxglove=True, record=True,
        acting_first=True).commands}
    assert idle == {'env_node': False, 'tamer_node': False, 'feedback_node': True,
                    'saliency_node': True, 'session_recorder': True, CONSOLE: True,
                    'graph_viewer': True}
    assert parse_options(['--acting-first']).acting_first


@pytest.mark.parametrize('condition', ['blind_obs', 'language_input'])
def test_acting_first_keeps_saliency_node_when_the_learner_acts_on_its_images(
        tmp_path, condition):
    idle = {command.name: command.idle
            for command in _plan(tmp_path, condition=condition, acting_first=True).commands}
    assert idle['saliency_node'] is False and idle['feedback_node'] is True
