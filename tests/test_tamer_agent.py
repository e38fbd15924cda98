"""TamerAgent (no rclpy): attribution, saliency pairing, concurrency, files, resume."""

import json
import threading
import time

from attention_common.feedback import PlainCopies
from attention_common.run_files import CHECKPOINT_DIR, CHECKPOINT_FILE, FEEDBACK_LOG
from attention_common.utterance import MAX_UTTERANCE_CHARS
from harness import wait_until
import numpy as np
import pytest
from tamer_node.agent import BadInput, TamerAgent
from tamer_node.config import TamerConfig
from tamer_node.credit import NS_PER_S
from tamer_node.model import Encoder, FEATURE_SIZE, INPUT_SHAPE, preprocess, to_input
from tamer_node.persistence import (
    DiskWriter, FeedbackLog, KIND_ACTION, KIND_OBSERVATION, load_checkpoint, StepJournal)
import torch

torch.set_num_threads(1)
STEP_NS = NS_PER_S // 15
RNG = np.random.default_rng(0)
FRAMES = RNG.integers(0, 256, (40, 210, 160, 3), np.uint8)


def make_agent(run_dir, **changes):
    settings = {'update_rate_hz': 50.0, 'checkpoint_period_s': 0.0, 'saliency_timeout_s': 0.3,
                'metrics_period_s': 0.5, 'pace_updates': 0.0}  # pacing: its own tests
    settings.update(changes)
    config = TamerConfig(**settings)
    torch.manual_seed(0)
    messages = []
    agent = TamerAgent(config, run_dir, encoder=Encoder(),
                       log=lambda level, text: messages.append((level, text)))
    agent.messages = messages
    agent.start()
    return agent


@pytest.fixture
def agents(tmp_path):
    made = []

    def make(run_dir=None, **changes):
        agent = make_agent(run_dir or tmp_path / 'run', **changes)
        made.append(agent)
        return agent

    yield make
    for agent in made:
        agent.close()


def stamp(i):
    return (i + 1) * STEP_NS


def play(agent, steps, first=0):
    """Show observations; return {stamp: action}."""
    return {stamp(i): agent.on_observation(stamp(i), FRAMES[i % len(FRAMES)])
            for i in range(first, first + steps)}


def processed(agent, count, timeout=10.0):
    return wait_until(lambda: agent.worker.stats()['feedback/processed'] >= count, timeout)


def log_lines(run_dir):
    return [json.loads(line) for line in (run_dir / FEEDBACK_LOG).read_text().splitlines()]


def test_stamped_feedback_labels_exactly_the_judged_step(agents):
    agent = agents()
    actions = play(agent, 6)
    agent.on_feedback(1.0, 'stamped', stamp(2))
    agent.on_feedback(-1.0, 'stamped', stamp(4))
    assert processed(agent, 2)
    samples = {s.stamp: s for s in agent.buffer.samples()}
    assert set(samples) == {stamp(2), stamp(4)}
    assert samples[stamp(2)].action == actions[stamp(2)] and samples[stamp(2)].h == 1.0
    assert samples[stamp(4)].h == -1.0 and samples[stamp(4)].weight == 1.0
    assert agent.metrics()['feedback/count'] == 2


def test_a_stamped_verdict_names_its_step_even_where_plain_ones_get_the_window(agents):
    # A person's press on a paused frame, among late plain presses: credit 'window' is how
    # plain feedback is attributed; a stamp says which step was judged, so it gets that step.
    agent = agents(credit='window')
    actions = play(agent, 90)
    agent.on_feedback(-1.0, 'stamped', stamp(89))  # the newest step: outside any window
    agent.on_feedback(1.0, 'plain')
    assert processed(agent, 2)
    stamped = [s for s in agent.buffer.samples() if s.h == -1.0]
    assert [(s.stamp, s.action, s.weight) for s in stamped] == [
        (stamp(89), actions[stamp(89)], 1.0)]
    assert len([s for s in agent.buffer.samples() if s.h == 1.0]) > 50  # the window's


def test_feedback_for_an_unknown_step_is_logged_and_counted(agents, tmp_path):
    agent = agents()
    play(agent, 3)
    agent.on_feedback(1.0, 'stamped', stamp(50))
    assert processed(agent, 1)
    assert agent.metrics()['feedback/unmatched'] == 1 and len(agent.buffer) == 0
    assert log_lines(tmp_path / 'run')[0]['stamp_ns'] == stamp(50)
    assert any(level == 'warn' for level, _ in agent.messages)


@pytest.mark.parametrize('source', ['stamped', 'pressed'])
def test_plain_feedback_is_a_copy_while_stamped_feedback_flows(agents, tmp_path, source):
    # A pressed verdict (the moment it was given) has a plain copy too with plain_copies.
    agent = agents(stamped_active_s=60.0, plain_copies=True)
    play(agent, 4)
    agent.on_feedback(1.0, source, stamp(1))
    agent.on_feedback(1.0, 'plain')
    assert processed(agent, 2)
    metrics = agent.metrics()
    assert metrics['feedback/duplicates'] == 1 and metrics['feedback/count'] == 1
    assert [e['status'] for e in log_lines(tmp_path / 'run')] == ['ok', 'duplicate']


def test_a_persons_plain_feedback_beside_a_pressed_stream_is_learned_from(agents, tmp_path):
    # The console's presses carry their moment (pressed); someone's `ros2 topic pub` at the
    # same time is plain. Each plain pairs with one verdict of the same h at most.
    agent = agents(stamped_active_s=60.0, plain_copies=True)
    play(agent, 4)
    agent.on_feedback(1.0, 'pressed', stamp(1))
    agent.on_feedback(-1.0, 'plain')  # no -1 verdict to copy: a person's
    agent.on_feedback(1.0, 'plain')  # the +1's copy
    agent.on_feedback(1.0, 'plain')  # its copy came already: a person's
    assert processed(agent, 4)
    assert [e['status'] for e in log_lines(tmp_path / 'run')] == ['ok', 'ok', 'duplicate', 'ok']
    assert agent.metrics()['feedback/duplicates'] == 1


@pytest.mark.parametrize('source', ['stamped', 'pressed'])
def test_without_copies_every_plain_verdict_beside_stamped_ones_is_learned(
        agents, tmp_path, source):
    # A teacher that marks or answers questions sends stamped and plain verdicts, and no copies
    # (feedback_node's default): each plain one is its own. They were logged 'duplicate' and
    # dropped when they came within stamped_active_s of a stamped verdict of the same h (93 %
    # of the plain verdicts of a graph run with questions).
    agent = agents(stamped_active_s=60.0)
    play(agent, 4)
    agent.on_feedback(1.0, source, stamp(1))
    agent.on_feedback(1.0, 'plain')
    agent.on_feedback(1.0, 'plain')
    assert processed(agent, 3)
    assert [e['status'] for e in log_lines(tmp_path / 'run')] == ['ok', 'ok', 'ok']
    metrics = agent.metrics()
    assert metrics['feedback/duplicates'] == 0 and metrics['feedback/count'] == 3


def test_a_plain_copy_pairs_with_one_recent_verdict_of_the_same_h():
    copies = PlainCopies(window_s=3.0)
    copies.verdict(10.0, 1.0)
    copies.verdict(10.1, -1.0)
    assert copies.is_copy(10.2, -1.0)  # pairs with the -1 (not the older +1)
    assert not copies.is_copy(10.3, -1.0)  # that one is paired: a person's
    assert not copies.is_copy(13.5, 1.0)  # the +1 is more than 3 s old: a person's
    copies.verdict(20.0, 0.5)
    assert copies.is_copy(20.5, 0.5) and not copies.is_copy(20.6, 0.5)


def test_plain_feedback_without_a_stamped_stream_is_stamped_on_arrival(agents):
    agent = agents(credit='step')
    actions = play(agent, 5)
    agent.on_feedback(-1.0, 'plain')
    assert processed(agent, 1)
    [sample] = agent.buffer.samples()
    assert sample.stamp == stamp(4) and sample.action == actions[stamp(4)]


def test_window_credit_spreads_a_person_feedback_over_the_window(agents):
    agent = agents(credit='window')
    play(agent, 90)  # 6 s at 15 Hz
    agent.on_feedback(1.0, 'plain')
    assert processed(agent, 1)
    samples = agent.buffer.samples()
    now = stamp(89)
    assert sum(s.weight for s in samples) == pytest.approx(1.0, abs=1e-6)
    assert all(now - 4 * NS_PER_S - STEP_NS <= s.stamp <= now - 0.2 * NS_PER_S
               for s in samples)
    assert len(samples) == pytest.approx(3.8 * 15, abs=2)


def test_feedback_before_any_observation_is_kept_in_the_log(agents, tmp_path):
    agent = agents()
    agent.on_feedback(1.0, 'plain')
    assert processed(agent, 1)
    assert log_lines(tmp_path / 'run')[0]['status'] == 'no_observation'
    assert agent.metrics()['feedback/unmatched'] == 1


@pytest.mark.parametrize('value', [float('nan'), float('inf'), -float('inf'), 1e9, 5.0, -50.0,
                                   1.0001])
def test_bad_feedback_values_are_logged_counted_and_not_learned(agents, tmp_path, value):
    agent = agents()
    play(agent, 2)
    agent.on_feedback(value, 'stamped', stamp(0))
    agent.on_feedback(1.0, 'stamped', stamp(1))
    assert processed(agent, 2)
    metrics = agent.metrics()
    assert metrics['feedback/invalid'] == 1 and metrics['feedback/count'] == 1
    assert [s.stamp for s in agent.buffer.samples()] == [stamp(1)]
    entry = log_lines(tmp_path / 'run')[0]
    assert entry['status'] == 'invalid'
    assert float(entry['h']) == value or (np.isnan(value) and np.isnan(float(entry['h'])))


def test_bad_images_are_counted_and_dropped(agents):
    agent = agents()
    for bad in (FRAMES[0][:, :, 0], FRAMES[0][:100], np.zeros((210, 160, 4), np.uint8)):
        with pytest.raises(BadInput):
            agent.on_observation(stamp(0), bad)
        with pytest.raises(BadInput):
            agent.on_saliency(stamp(0), bad)
    assert agent.metrics()['drop/observation'] == 3 and agent.metrics()['drop/saliency'] == 3
    assert agent.on_observation(stamp(0), FRAMES[0]) is not None


def test_a_step_sent_twice_gets_the_same_answer(agents):
    agent = agents()
    first = agent.on_observation(stamp(0), FRAMES[0])
    assert agent.on_observation(stamp(0), FRAMES[1]) == first


# Pairing with saliency images.
def test_saliency_that_comes_later_is_paired_by_stamp(agents):
    agent = agents(alpha=1e-4, saliency_timeout_s=30.0)
    play(agent, 3)
    agent.on_feedback(1.0, 'stamped', stamp(1))
    assert not processed(agent, 1, timeout=0.3)  # waits for saliency 1 (or a later one)
    agent.on_saliency(stamp(1), FRAMES[7])
    assert processed(agent, 1)
    [sample] = agent.buffer.samples()
    assert sample.companion is not None
    assert agent.metrics()['pairing/with_saliency'] == 1


def test_saliency_that_never_comes_times_out_without_l2(agents):
    agent = agents(alpha=1e-4, saliency_timeout_s=0.2)
    play(agent, 3)
    agent.on_feedback(1.0, 'stamped', stamp(1))
    assert processed(agent, 1, timeout=5.0)
    [sample] = agent.buffer.samples()
    assert sample.companion is None
    assert agent.metrics()['pairing/without_saliency'] == 1


def test_a_later_saliency_image_settles_the_pairing_at_once(agents):
    agent = agents(alpha=1e-4, saliency_timeout_s=30.0)
    play(agent, 4)
    agent.on_feedback(1.0, 'stamped', stamp(1))
    agent.on_saliency(stamp(2), FRAMES[2])  # the saliency stream skipped step 1
    assert processed(agent, 1, timeout=5.0)
    assert agent.buffer.samples()[0].companion is None


def test_alpha_zero_does_not_wait_for_saliency(agents):
    agent = agents(alpha=0.0, saliency_timeout_s=30.0)
    play(agent, 3)
    agent.on_feedback(1.0, 'stamped', stamp(1))
    assert processed(agent, 1, timeout=5.0)


def test_saliency_input_acts_on_the_saliency_image(agents):
    agent = agents(input_image='saliency', alpha=0.0)
    assert agent.on_observation(stamp(0), FRAMES[0]) is None
    action = agent.on_saliency(stamp(0), FRAMES[1])
    assert action is not None
    agent.on_feedback(1.0, 'stamped', stamp(0))
    assert processed(agent, 1)
    [sample] = agent.buffer.samples()
    record = agent.history.get(stamp(0))  # a frozen encoder: the buffer holds features
    assert torch.equal(sample.state, agent.actor.features(record.saliency))
    assert torch.equal(sample.companion, agent.actor.features(record.observation))


def test_both_inputs_act_and_learn_on_the_frame_and_its_saliency_image(agents):
    agent = agents(input_image='both', alpha=0.0)
    assert agent.on_observation(stamp(0), FRAMES[0]) is None  # it waits for the saliency image
    assert agent.on_saliency(stamp(0), FRAMES[1]) is not None
    agent.on_feedback(1.0, 'stamped', stamp(0))
    assert processed(agent, 1)
    [sample] = agent.buffer.samples()
    record = agent.history.get(stamp(0))
    assert torch.equal(sample.state, torch.cat([agent.actor.features(record.observation),
                                                agent.actor.features(record.saliency)]))
    assert sample.companion is None  # the saliency image is in H's input, not an L2 term
    # A step whose saliency image never comes is answered on its observation, standing in.
    agent.on_observation(stamp(1), FRAMES[2])
    time.sleep(agent.config.saliency_timeout_s + 0.05)
    [(answered, _)] = agent.acting.act_overdue()
    assert answered == stamp(1)
    with pytest.raises(ValueError, match='fine_tune_encoder'):
        TamerConfig(input_image='both', fine_tune_encoder=True).validate()


def test_a_text_conditioned_agent_learns_on_the_words_in_force_when_it_acted(agents):
    from tamer_node.words import bag_of_words
    agent = agents(text_conditioning='film', alpha=0.0)
    assert agent.on_utterance('pick up the red ball') == 'ok'
    play(agent, 1)
    agent.on_utterance('pick up the purple key')
    play(agent, 1, first=1)
    for i in (0, 1):
        agent.on_feedback(1.0, 'stamped', stamp(i))
    assert processed(agent, 2)
    first, second = sorted(agent.buffer.samples(), key=lambda s: s.stamp)
    assert first.state.shape == (FEATURE_SIZE + 64,)
    assert torch.equal(first.state[-64:], bag_of_words('pick up the red ball', 64))
    assert torch.equal(second.state[-64:], bag_of_words('pick up the purple key', 64))
    assert torch.equal(first.state[:FEATURE_SIZE],
                       agent.actor.features(agent.history.get(stamp(0)).observation))
    with pytest.raises(ValueError, match='fine_tune_encoder'):
        TamerConfig(text_conditioning='film', fine_tune_encoder=True).validate()


@pytest.mark.parametrize('fine_tune', [False, True])
def test_a_frozen_encoder_learns_on_the_features_the_actor_computed(agents, fine_tune):
    agent = agents(alpha=1e-4, fine_tune_encoder=fine_tune)
    play(agent, 1)
    agent.on_saliency(stamp(0), FRAMES[5])
    agent.on_feedback(-1.0, 'stamped', stamp(0))
    assert processed(agent, 1)
    [sample] = agent.buffer.samples()
    record = agent.history.get(stamp(0))
    if fine_tune:  # the encoder learns too: images, run through it at every update
        assert torch.equal(sample.state, record.observation)
        assert torch.equal(sample.companion, record.saliency)
        assert record.observation_features is None
    else:  # the actor's features, the saliency image encoded once when paired
        assert torch.equal(sample.state, record.observation_features)
        assert sample.state.shape == (FEATURE_SIZE,)
        assert torch.equal(sample.companion, agent.actor.features(record.saliency))
    assert wait_until(lambda: agent.worker.stats()['train/l2_updates'] >= 1, 10.0)


def test_a_feedback_is_never_written_behind_a_checkpoint(agents, tmp_path):
    agent = agents()
    release = threading.Event()
    agent.checkpoint_disk.submit(lambda: release.wait(30))  # a checkpoint that takes forever
    try:
        play(agent, 2)
        agent.on_feedback(1.0, 'stamped', stamp(1))
        assert wait_until(lambda: (tmp_path / 'run' / FEEDBACK_LOG).exists()
                          and len(log_lines(tmp_path / 'run')) == 1, 5.0)
    finally:
        release.set()


# Acting and training run apart.
@pytest.mark.parametrize('pace_updates', [0.0, 2.0])
def test_acting_never_waits_for_training_or_disk(agents, pace_updates):
    # Paced, a learner stuck in an update holds each answer pace_max_s at most.
    agent = agents(pace_updates=pace_updates, pace_max_s=0.02)
    release = threading.Event()
    entered = threading.Event()
    train_step = agent.learner.train_step

    def blocked_train_step(batch):
        entered.set()
        release.wait(30)
        return train_step(batch)

    agent.learner.train_step = blocked_train_step
    play(agent, 2)
    agent.on_feedback(1.0, 'stamped', stamp(0))
    assert entered.wait(10)  # the learner is now inside an update that does not end
    agent.disk.submit(lambda: release.wait(30))  # and the disk thread is stuck too
    answered = []
    actor = threading.Thread(target=lambda: answered.append(play(agent, 50, first=2)))
    actor.start()
    actor.join(10)
    release.set()
    assert answered and len(answered[0]) == 50 and None not in answered[0].values()
    assert (agent.counters['act/paced'] > 0) is (pace_updates > 0)


@pytest.mark.parametrize('pace_updates', [0.0, 2.0])
def test_a_paced_actor_never_outruns_its_learner(agents, pace_updates):
    """Stepping faster than the learner trains drops owed updates, unless the actor waits."""
    agent = agents(update_rate_hz=150.0, update_backlog_s=1.0, immediate_update=False,
                   pace_updates=pace_updates, pace_max_s=10.0)  # 10 updates owed per step
    # (pace_max_s bounds one wait: 1 s ran out on a machine busy with a study besides)
    for i in range(60):  # from the first feedback on, also before the learner has used it
        play(agent, 1, first=i)
        agent.on_feedback(1.0 if i % 2 else -1.0, 'stamped', stamp(i))
    assert processed(agent, 60)
    assert wait_until(lambda: agent.worker.updates_behind() < 1.0, 30)
    stats = agent.worker.stats()
    if pace_updates:
        assert stats['train/skipped_updates'] == 0 and agent.counters['act/paced'] > 0
        assert stats['train/minibatch_updates'] >= 10 * 57  # what 59 steps owe, minus 2
    else:
        assert stats['train/skipped_updates'] > 0 and agent.counters['act/paced'] == 0


def test_the_actor_is_paced_from_a_feedback_still_waiting_for_the_disk(agents):
    """Pacing starts when feedback arrives, not when the disk thread hands it on (CI: 29 lost)."""
    agent = agents(update_rate_hz=150.0, update_backlog_s=1.0, immediate_update=False,
                   pace_updates=2.0, pace_max_s=10.0)
    play(agent, 1)
    agent.disk.submit(lambda: time.sleep(1.5))  # a busy disk thread (a loaded machine's)
    agent.on_feedback(1.0, 'stamped', stamp(0))
    play(agent, 30, first=1)  # 2 s of steps: 300 updates owed, twice the backlog
    assert processed(agent, 1)
    assert wait_until(lambda: agent.worker.updates_behind() < 1.0, 30)
    assert agent.worker.stats()['train/skipped_updates'] == 0
    assert agent.counters['act/paced'] > 0


def test_weight_snapshots_reach_the_acting_copy(agents):
    agent = agents(update_clock='wall')  # minibatches go on while no step comes
    play(agent, 10)
    for i in range(10):
        agent.on_feedback(1.0, 'stamped', stamp(i))
    # train/updates counts an update once its snapshot is published.
    assert wait_until(lambda: agent.worker.stats()['train/updates'] >= 5, 10)
    play(agent, 1, first=10)
    assert agent.actor.version >= 5
    assert agent.actor.model.training is False and agent.learner.model.training is True
    for name, tensor in agent.actor.model.state_dict().items():
        assert tensor.data_ptr() != agent.learner.model.state_dict()[name].data_ptr()


# The minibatch schedule counts simulation time.
def caught_up(agent, last_stamp):
    """Tell whether the learner read the last step's time and finished all it owed."""
    schedule = agent.worker.schedule
    return (schedule.last_reading == last_stamp / 1e9 and schedule.owed < 1.0
            and agent.worker.stats()['train/minibatch_updates'] == schedule.taken)


def minibatches_after(agent, steps, seconds_per_step):
    """One feedback, then ``steps`` observations at a wall pace; return the minibatch count."""
    play(agent, 1)
    agent.on_feedback(1.0, 'stamped', stamp(0))
    assert processed(agent, 1)
    assert wait_until(lambda: agent.worker.schedule.started, 5)  # owed from here on
    for i in range(1, steps + 1):
        agent.on_observation(stamp(i), FRAMES[i % len(FRAMES)])
        time.sleep(seconds_per_step)
    assert wait_until(lambda: caught_up(agent, stamp(steps)), 20)
    stats = agent.worker.stats()
    assert stats['train/skipped_updates'] == 0
    return stats['train/minibatch_updates']


def test_minibatch_updates_per_sim_second_do_not_depend_on_the_wall_speed(agents, tmp_path):
    """10 s of simulation (150 steps) in ~0.1 s or in ~1.5 s of wall time: 6 Hz x 10 s each."""
    fast = agents(tmp_path / 'fast', update_rate_hz=6.0, update_backlog_s=60.0)
    slow = agents(tmp_path / 'slow', update_rate_hz=6.0, update_backlog_s=60.0)
    assert abs(minibatches_after(fast, 150, 0.0) - 60) <= 1
    assert abs(minibatches_after(slow, 150, 0.01) - 60) <= 1
    metrics = slow.metrics()
    assert metrics['train/minibatch_updates_per_step'] == pytest.approx(60 / 151, abs=0.01)
    assert metrics['train/updates_per_step'] == pytest.approx(61 / 151, abs=0.01)


def test_a_learner_that_cannot_keep_up_drops_and_counts_the_excess(agents):
    agent = agents(update_rate_hz=15.0, update_backlog_s=1.0)  # one per step, 15 may wait
    play(agent, 1)
    agent.on_feedback(1.0, 'stamped', stamp(0))
    assert processed(agent, 1)
    assert wait_until(lambda: agent.worker.schedule.started, 5)
    release = threading.Event()
    train_step = agent.learner.train_step
    agent.learner.train_step = lambda batch: (release.wait(30), train_step(batch))[1]
    play(agent, 100, first=1)  # the learner is stuck in its first minibatch meanwhile
    release.set()
    assert wait_until(lambda: caught_up(agent, stamp(100)), 20)
    stats = agent.worker.stats()
    assert stats['train/skipped_updates'] >= 100 - 16 - 1
    assert stats['train/minibatch_updates'] + stats['train/skipped_updates'] == \
        pytest.approx(100, abs=1)


def test_wall_clock_updates_go_on_without_new_steps(agents):
    agent = agents(update_clock='wall', update_rate_hz=50.0)
    play(agent, 2)
    agent.on_feedback(1.0, 'stamped', stamp(0))
    assert wait_until(lambda: agent.worker.stats()['train/minibatch_updates'] >= 5, 10)


# Files, checkpoints and resume.
def state_of(agent):
    return {
        'model': {k: v.clone() for k, v in agent.learner.model.state_dict().items()},
        'optimizer_steps': [float(s['step']) for s in
                            agent.learner.optimizer.state_dict()['state'].values()],
        'buffer': [(s.stamp, s.seq, s.action, s.h, s.weight, s.companion is not None,
                    int(s.state.sum())) for s in agent.buffer.samples()],
        'updates': agent.learner.updates,
    }


def feed(agent, steps, first=0, saliency_every=3):
    play(agent, steps, first)
    for i in range(first, first + steps):
        if i % saliency_every == 0:
            agent.on_saliency(stamp(i), FRAMES[(i + 5) % len(FRAMES)])
        agent.on_feedback(1.0 if i % 2 else -1.0, 'stamped', stamp(i))


def test_checkpoint_round_trip(tmp_path):
    run = tmp_path / 'run'
    agent = make_agent(run, alpha=1e-4, saliency_timeout_s=0.05)
    feed(agent, 20)
    assert processed(agent, 20)
    agent.close()  # last checkpoint
    before = state_of(agent)
    counters = dict(agent.worker.stats())
    checkpoint = load_checkpoint(run)
    assert checkpoint['applied_seq'] == 20
    resumed = make_agent(run, resume=True)
    try:
        after = state_of(resumed)
        for name, tensor in before['model'].items():
            assert torch.equal(tensor, after['model'][name]), name
        assert before['buffer'] == after['buffer'] and len(after['buffer']) == 20
        assert before['optimizer_steps'] == after['optimizer_steps']
        assert after['updates'] == before['updates'] > 0
        stats = resumed.worker.stats()
        for key in ('feedback/count', 'samples/added', 'pairing/with_saliency'):
            assert stats[key] == counters[key]
        assert stats['resume/replayed'] == 0
        assert resumed.metrics()['feedback/received'] == 20
    finally:
        resumed.close()


def test_the_verdict_memory_is_rebuilt_from_the_buffer_on_resume(tmp_path):
    run = tmp_path / 'run'
    agent = make_agent(run, verdict_memory=1.0)
    feed(agent, 20)
    assert processed(agent, 20)
    remembered = len(agent.worker.memory)
    agent.close()
    resumed = make_agent(run, resume=True, verdict_memory=1.0)
    try:
        assert resumed.acting.memory is resumed.worker.memory
        assert len(resumed.worker.memory) == remembered > 0
        for sample in resumed.buffer.samples():
            assert resumed.worker.memory.lookup(sample.state)[0, sample.action] > 0
    finally:
        resumed.close()


def test_resume_replays_the_logged_feedback_newer_than_the_checkpoint(tmp_path):
    """Without any checkpoint, the whole log is replayed from the step journal."""
    run = tmp_path / 'run'
    agent = make_agent(run, alpha=1e-4, saliency_timeout_s=0.05)
    feed(agent, 25)
    assert processed(agent, 25)
    agent.close()
    expected = state_of(agent)['buffer']
    (run / CHECKPOINT_DIR / CHECKPOINT_FILE).unlink()  # as if it crashed before one
    resumed = make_agent(run, resume=True)
    try:
        assert state_of(resumed)['buffer'] == expected
        stats = resumed.worker.stats()
        assert stats['resume/replayed'] == 25 and stats['feedback/count'] == 25
        # It carries on: new feedback continues the sequence.
        resumed.on_feedback(1.0, 'stamped', stamp(24))
        assert processed(resumed, 26)
        assert log_lines(run)[-1]['seq'] == 26
    finally:
        resumed.close()


def _features(agent, frame):
    return agent.learner.model.features(
        to_input(torch.from_numpy(preprocess(frame))))[0].detach()


@pytest.mark.parametrize('keep_checkpoint', [True, False], ids=['checkpoint', 'log_only'])
def test_two_resumes_never_pair_feedback_with_another_sessions_frame(tmp_path, keep_checkpoint):
    """Each start's env stamps begin again at the same values; every sample keeps its frame."""
    run = tmp_path / 'run'
    given = {}  # feedback seq -> the frame shown for the step it judged
    for session, offset in ((1, 0), (2, 17)):  # the second env shows other frames
        agent = make_agent(run, resume=session > 1, saliency_timeout_s=0.05)
        assert agent.session == session
        for i in range(20):
            frame = FRAMES[(i + offset) % len(FRAMES)]
            agent.on_observation(stamp(i), frame)
            event = agent.on_feedback(1.0, 'stamped', stamp(i))
            given[event.seq] = frame
        assert processed(agent, 20 * session)
        agent.close()
    if not keep_checkpoint:  # as if killed before any checkpoint: all replayed from the log
        (run / CHECKPOINT_DIR / CHECKPOINT_FILE).unlink()
    resumed = make_agent(run, resume=True)
    try:
        assert resumed.session == 3
        samples = resumed.buffer.samples()
        assert sorted(s.seq for s in samples) == list(range(1, 41))
        for sample in samples:
            assert sample.session == (1 if sample.seq <= 20 else 2)
            assert torch.allclose(sample.state, _features(resumed, given[sample.seq])), sample
        # The new session starts with no steps: old actions are not replayed for its stamps.
        assert len(resumed.history) == 0
        assert [e['session'] for e in log_lines(run) if e['kind'] == 'feedback'] == (
            [1] * 20 + [2] * 20)
    finally:
        resumed.close()


def test_a_far_future_observation_is_dropped_and_does_not_move_now(agents):
    agent = agents()
    play(agent, 5)
    with pytest.raises(BadInput, match='stamp'):
        agent.on_observation(2**31 * NS_PER_S, FRAMES[0])
    with pytest.raises(BadInput, match='stamp'):
        agent.on_saliency(2**31 * NS_PER_S, FRAMES[0])
    event = agent.on_feedback(1.0, 'plain')
    assert event.stamp == stamp(4) and event.status == 'ok'
    assert processed(agent, 1)
    assert [s.stamp for s in agent.buffer.samples()] == [stamp(4)]
    metrics = agent.metrics()
    assert metrics['drop/observation_stamp'] == 1 and metrics['drop/saliency_stamp'] == 1
    assert agent.on_observation(stamp(5), FRAMES[5]) is not None  # and it goes on acting


def test_an_env_that_starts_over_begins_a_new_session(agents):
    agent = agents()
    late = 1000
    play(agent, 5, first=late)
    assert agent.session == 1
    # A new env: its stamps begin near 0; the first two are taken for strays.
    for i in range(2):
        with pytest.raises(BadInput):
            agent.on_observation(stamp(0), FRAMES[0])
    assert agent.on_observation(stamp(0), FRAMES[0]) is not None
    assert agent.session == 2 and agent.metrics()['session/restarts'] == 1
    assert any('started over' in text for level, text in agent.messages if level == 'warn')
    # Feedback on a step of the old env is kept, not learned from; on the new one, learned.
    agent.on_feedback(1.0, 'stamped', stamp(late + 2))
    agent.on_feedback(-1.0, 'stamped', stamp(0))
    assert processed(agent, 2)
    assert [(s.stamp, s.session, s.h) for s in agent.buffer.samples()] == [(stamp(0), 2, -1.0)]
    assert agent.worker.stats()['feedback/other_session'] == 0  # the old step is just gone
    assert agent.worker.stats()['feedback/unmatched'] == 1


def test_periodic_checkpoints_are_atomic_and_prune_the_journal(tmp_path):
    run = tmp_path / 'run'
    agent = make_agent(run, checkpoint_period_s=0.2)
    try:
        for rounds in range(1, 4):
            feed(agent, 10, first=10 * (rounds - 1))
            assert processed(agent, 10 * rounds)

            def has_everything():
                # Each load sees a whole file: the old checkpoint or the new one, never a mix.
                checkpoint = load_checkpoint(run)
                return checkpoint is not None and checkpoint['applied_seq'] == 10 * rounds

            assert wait_until(has_everything, 20, interval=0.05)
        assert agent.worker.stats()['checkpoint/count'] >= 3
        # A new segment per checkpoint, but no empty ones are kept (but the one being written).
        # (How many hold steps depends on where checkpoints fell: on a busy machine a round's
        # ten steps span two; the buffer's first sample keeps the oldest, see the journal test.)
        segments = sorted((run / 'steps').glob('segment-*.bin'))
        assert sum(path.stat().st_size == 0 for path in segments[:-1]) == 0
        assert len(segments) <= agent.worker.stats()['checkpoint/count'] + 1
    finally:
        agent.close()
    assert not list((run / CHECKPOINT_DIR).glob('*.tmp'))


def test_a_run_dir_in_use_needs_resume(tmp_path):
    run = tmp_path / 'run'
    make_agent(run).close()
    (run / FEEDBACK_LOG).write_text('')
    with pytest.raises(FileExistsError, match='resume'):
        make_agent(run)


def test_a_cut_journal_and_log_are_read_up_to_the_cut(tmp_path):
    run = tmp_path / 'run'
    agent = make_agent(run)
    feed(agent, 5)
    assert processed(agent, 5)
    agent.close()
    log = run / FEEDBACK_LOG
    log.write_text(log.read_text() + '{"kind": "feedback", "seq": 6, "h"')
    entries, bad = FeedbackLog.read(log)
    assert len(entries) == 5 and bad == 1
    segment = sorted((run / 'steps').glob('segment-*.bin'))[0]
    whole = list(StepJournal.read(run / 'steps'))
    segment.write_bytes(segment.read_bytes()[:-100])
    assert 0 < len(list(StepJournal.read(run / 'steps'))) < len(whole)


def test_utterances_are_logged(agents, tmp_path):
    agent = agents()
    assert agent.on_utterance('Climb down the ladder.') == 'ok'
    assert agent.on_utterance('   ') == 'empty'
    assert agent.on_utterance('x' * 1_000_000) == 'too_long'
    assert agent.disk.flush()
    entries = [e for e in log_lines(tmp_path / 'run') if e['kind'] == 'utterance']
    assert entries[0]['text'] == 'Climb down the ladder.' and entries[0]['status'] == 'ok'
    assert entries[1]['status'] == 'empty'
    assert entries[2]['status'] == 'too_long' and entries[2]['chars'] == 1_000_000
    assert len(entries[2]['text']) == MAX_UTTERANCE_CHARS
    metrics = agent.metrics()
    assert metrics['utterance/empty'] == 1 and metrics['utterance/too_long'] == 1
    assert [level for level, text in agent.messages if 'utterance dropped' in text] == [
        'warn', 'warn']


def test_an_unreadable_checkpoint_stops_the_resume_with_advice(tmp_path):
    run = tmp_path / 'run'
    agent = make_agent(run)
    feed(agent, 3)
    assert processed(agent, 3)
    agent.close()
    (run / CHECKPOINT_DIR / CHECKPOINT_FILE).write_bytes(b'not a checkpoint')
    with pytest.raises(RuntimeError, match='move it away'):
        make_agent(run, resume=True)


def test_the_journal_keeps_only_segments_with_needed_steps(tmp_path):
    journal = StepJournal(tmp_path, 0)
    image = torch.full(INPUT_SHAPE, 7, dtype=torch.uint8)
    journal.append(KIND_OBSERVATION, 10, image=image)
    journal.append(KIND_ACTION, 10, 3)
    journal.rotate()
    journal.append(KIND_OBSERVATION, 20, image=image)
    journal.rotate()
    journal.rotate()  # segment 2 stays empty
    journal.append(KIND_OBSERVATION, 30, image=image)
    journal.drain()

    def segments():
        return sorted(int(p.stem.split('-')[1]) for p in tmp_path.glob('segment-*.bin'))

    assert segments() == [0, 1, 3]
    assert journal.delete_older_than((1, 20)) == 1 and segments() == [1, 3]
    assert [(r[0], r[2], int(r[4].sum())) for r in StepJournal.read(tmp_path)] == [
        (1, 20, 7 * image.numel()), (1, 30, 7 * image.numel())]
    journal.delete_older_than((1, 10 ** 12))
    assert segments() == [3]  # never the one being written
    journal.close()


def test_the_disk_thread_outlives_a_failing_error_report(tmp_path):
    """A logger that raises while a write failure is reported must not stop later writes."""
    journal = StepJournal(tmp_path, 0)
    reports = []

    def failing_report(text):
        reports.append(text)
        raise ValueError('Logger severity cannot be changed between calls.')

    disk = DiskWriter(journal, failing_report)
    disk.start()
    written = []

    def broken_job():
        raise OSError('disk full')

    disk.submit(broken_job)
    disk.submit(lambda: written.append(1))
    assert disk.flush(10.0) and written == [1]
    assert disk.errors == 1 and 'disk full' in reports[0]
    disk.stop()
    journal.close()


def test_feedback_is_learned_on_the_action_taken_not_the_agent_s_answer(agents, tmp_path):
    # attention_replay: the session's agent took its own action; the feedback judged that one.
    agent = make_agent(tmp_path / 'taken')  # closed here, then resumed
    answers = play(agent, 4)
    taken = {s: (a + 1) % agent.task.num_actions for s, a in answers.items()}
    agent.on_action_taken(stamp(1), taken[stamp(1)])  # after the answer
    agent.on_action_taken(stamp(4), 3)  # before its observation: the answer is still greedy
    answers.update(play(agent, 1, first=4))
    agent.on_feedback(1.0, 'stamped', stamp(1))
    agent.on_feedback(-1.0, 'stamped', stamp(4))
    agent.on_feedback(1.0, 'stamped', stamp(2))  # nothing taken: the agent's own answer
    assert processed(agent, 3)
    samples = {s.stamp: s.action for s in agent.buffer.samples()}
    assert samples == {stamp(1): taken[stamp(1)], stamp(4): 3, stamp(2): answers[stamp(2)]}
    assert answers[stamp(4)] is not None  # it answered for itself
    counts = agent.metrics()
    assert counts['act/taken'] == 2
    assert counts['act/taken_differs'] == 1 + int(answers[stamp(4)] != 3)
    with pytest.raises(BadInput):
        agent.on_action_taken(stamp(3), agent.task.num_actions)
    assert agent.metrics()['drop/action_taken'] == 1
    # The journal keeps what was taken, so a resumed learner learns the same (from the log and
    # the journal alone: the checkpoint is taken away).
    agent.close()
    (tmp_path / 'taken' / CHECKPOINT_DIR / CHECKPOINT_FILE).unlink()
    resumed = agents(tmp_path / 'taken', resume=True)
    assert {s.stamp: s.action for s in resumed.buffer.samples()} == samples


@pytest.mark.parametrize('await_taken', [False, True])
def test_a_feedback_that_overtakes_its_steps_action_taken_waits_for_it(agents, await_taken):
    # Topics keep no order between them: a replay's feedback may reach the learner before the
    # action_taken it sent earlier. With await_taken the feedback waits for it (up to
    # saliency_timeout_s, 3 s here); without, it is learned on the agent's own answer (alpha
    # 0: no saliency image is awaited).
    agent = agents(saliency_timeout_s=3.0, await_taken=await_taken, alpha=0.0)
    answers = play(agent, 3)
    taken = (answers[stamp(1)] + 1) % agent.task.num_actions
    agent.on_feedback(1.0, 'stamped', stamp(1))
    time.sleep(0.5)
    agent.on_action_taken(stamp(1), taken)
    assert processed(agent, 1)
    [sample] = agent.buffer.samples()
    assert sample.action == (taken if await_taken else answers[stamp(1)])


def test_a_feedback_waiting_for_an_action_taken_that_never_comes_is_learned_after_the_timeout(
        agents):
    agent = agents(saliency_timeout_s=0.5, await_taken=True, alpha=0.0)
    answers = play(agent, 3)
    started = time.monotonic()
    agent.on_feedback(1.0, 'stamped', stamp(1))
    assert processed(agent, 1)
    assert time.monotonic() - started >= 0.5
    assert [s.action for s in agent.buffer.samples()] == [answers[stamp(1)]]


def test_explore_takes_a_share_of_decisions_at_random_and_learns_on_them(agents, tmp_path):
    greedy = agents(tmp_path / 'greedy')
    acted = play(greedy, 30)
    assert len(set(acted.values())) == 1 and 'act/explored' not in greedy.metrics()
    greedy_action = acted[stamp(0)]  # (the same untrained H in both: torch.manual_seed(0))
    exploring = agents(tmp_path / 'exploring', explore=0.5)
    acted = play(exploring, 30)
    explored = exploring.metrics()['act/explored']
    assert 6 <= explored <= 24 and len(set(acted.values())) > 2
    # A judged exploring step is learned on the action it took, as any other.
    off_greedy = [t for t, action in acted.items() if action != greedy_action]
    exploring.on_feedback(1.0, 'stamped', off_greedy[0])
    assert processed(exploring, 1)
    [sample] = exploring.buffer.samples()
    assert (sample.stamp, sample.action) == (off_greedy[0], acted[off_greedy[0]])


@pytest.mark.parametrize('share', [-0.1, 1.0])
def test_explore_must_leave_some_decisions_to_h(share):
    with pytest.raises(ValueError, match='explore'):
        TamerConfig(explore=share).validate()


def test_a_new_run_starts_from_a_trained_runs_model(tmp_path):
    trained = make_agent(tmp_path / 'trained', saliency_timeout_s=0.05)
    feed(trained, 20)
    assert processed(trained, 20)
    trained.close()  # its last checkpoint
    learned = state_of(trained)['model']
    untrained = make_agent(tmp_path / 'untrained')
    untrained.close()
    assert any(not torch.equal(learned[name], tensor)
               for name, tensor in state_of(untrained)['model'].items())
    for source in (tmp_path / 'trained', tmp_path / 'trained' / CHECKPOINT_DIR / CHECKPOINT_FILE):
        run = tmp_path / f'from_{source.name}'
        agent = make_agent(run, initial_model=str(source))
        try:
            for name, tensor in agent.learner.model.state_dict().items():
                assert torch.equal(tensor, learned[name]), name
            for name, tensor in agent.actor.model.state_dict().items():  # it acts on them
                assert torch.equal(tensor, learned[name]), name
            assert agent.learner.updates == 0 and len(agent.buffer) == 0  # a run of its own
            assert (run / FEEDBACK_LOG).read_text() == ''  # nothing of the trained run's
            assert any('starts from the model' in text for _, text in agent.messages)
        finally:
            agent.close()


def test_a_model_that_cannot_be_used_stops_the_start_with_the_reason(tmp_path):
    trained = make_agent(tmp_path / 'trained')
    feed(trained, 4)
    assert processed(trained, 4)
    trained.close()
    model = str(tmp_path / 'trained')
    cases = ((str(tmp_path / 'nothing'), {}, 'no checkpoint at'),
             (model, {'input_image': 'both'}, "trained with input_image 'observation'"),
             (model, {'head_hidden': 32}, 'does not fit this learner'))
    for path, changes, reason in cases:
        with pytest.raises(ValueError, match=reason):
            make_agent(tmp_path / f'run{len(reason)}', initial_model=path, **changes)
