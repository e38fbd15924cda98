"""tamer_node's learning core (no rclpy): loss, credit, buffer, model, learning on real frames."""

import dataclasses
import threading

from attention_common.joy_actions import NUM_ACTIONS
import numpy as np
import pytest
from tamer_node.agent import DEFAULT_ENCODER
from tamer_node.buffer import collate, FeedbackBuffer, Sample
from tamer_node.config import field_docs, TamerConfig
from tamer_node.credit import NS_PER_S, spans_from_stamps, step_credit, window_credit
from tamer_node.learner import Learner
from tamer_node.model import (
    ConvAutoencoder, Encoder, FRAME_SHAPE, HModel, INPUT_SHAPE, load_encoder, preprocess,
    save_encoder, to_input)
from tamer_node.pretrain import collect_frames, saliency_like
from tamer_node.schedule import UpdateSchedule
import torch

torch.set_num_threads(1)
S = NS_PER_S


@pytest.fixture(scope='module')
def real_frames():
    """Room 1 frames from the real emulator (seeded random walk), preprocessed."""
    frames, _ = collect_frames(24, seed=3, stride=5, use_expert=False)
    return frames


def make_batch(images, companions=None, actions=None, h=None, weights=None):
    count = len(images)
    rng = np.random.default_rng(0)
    samples = []
    for i in range(count):
        samples.append(Sample(
            state=torch.as_tensor(images[i]),
            companion=None if companions is None or companions[i] is None
            else torch.as_tensor(companions[i]),
            action=int(rng.integers(NUM_ACTIONS)) if actions is None else int(actions[i]),
            h=float(rng.choice([-1.0, 1.0])) if h is None else float(h[i]),
            weight=1.0 if weights is None else float(weights[i]), stamp=i, seq=i + 1))
    return collate(samples)


def random_images(count, seed=0):
    return np.random.default_rng(seed).integers(0, 256, (count,) + INPUT_SHAPE, np.uint8)


# The loss (thesis eq. 4.3 / 4.4).
def test_alpha_zero_is_exactly_the_weighted_mse_and_skips_saliency():
    torch.manual_seed(0)
    model = HModel()
    learner = Learner(model, alpha=0.0)
    images = random_images(6)
    batch = make_batch(images, companions=list(random_images(6, seed=1)),
                       weights=[1, 0.5, 0.25, 1, 1, 0.1])
    calls = []
    model.register_forward_hook(lambda module, args, out: calls.append(args[0].shape[0]))
    loss, mse, l2 = learner.loss(batch)
    assert calls == [6]  # one pass over the frames, none over the saliency images
    with torch.no_grad():
        predicted = model(to_input(batch.states))[torch.arange(6), batch.actions]
        expected = (batch.weights * (predicted - batch.h) ** 2).sum() / batch.weights.sum()
    assert torch.equal(loss, mse)
    assert l2.item() == 0.0
    assert mse.item() == pytest.approx(expected.item(), rel=1e-6)


def test_l2_covers_all_outputs_of_the_rows_with_a_saliency_image():
    torch.manual_seed(0)
    model = HModel()
    learner = Learner(model, alpha=0.5)
    images, saliency = random_images(4), random_images(4, seed=1)
    batch = make_batch(images, companions=[saliency[0], None, saliency[2], None])
    loss, mse, l2 = learner.loss(batch)
    with torch.no_grad():
        on_frames = model(to_input(images[[0, 2]]))
        on_saliency = model(to_input(saliency[[0, 2]]))
        expected = ((on_frames - on_saliency) ** 2).sum(dim=1).mean()
    assert l2.item() == pytest.approx(expected.item(), rel=1e-5)
    assert l2.item() > 0.0
    assert loss.item() == pytest.approx(mse.item() + 0.5 * l2.item(), rel=1e-6)


def gap(model, frames, saliency):
    with torch.no_grad():
        return float((model(to_input(frames)) - model(to_input(saliency))).abs().mean())


def test_training_with_alpha_shrinks_the_frame_saliency_gap(real_frames):
    rng = np.random.default_rng(0)
    frames = np.stack([preprocess(f) for f in real_frames[:16]])
    saliency = np.stack([preprocess(saliency_like(f, rng)) for f in real_frames[:16]])
    batch = make_batch(frames, companions=list(saliency))
    torch.manual_seed(0)
    encoder = load_encoder(DEFAULT_ENCODER)
    start = HModel(encoder=encoder)
    warm_up = Learner(start, alpha=0.0)
    for _ in range(50):  # fit the feedback first, so that H is far from zero everywhere
        warm_up.train_step(batch)
    before = gap(start, frames, saliency)
    gaps = {}
    for alpha in (0.0, 1.0):
        model = HModel(encoder=load_encoder(DEFAULT_ENCODER))
        model.load_state_dict(start.state_dict())
        learner = Learner(model, learning_rate=1e-3, alpha=alpha)
        for _ in range(60):
            learner.train_step(batch)
        gaps[alpha] = gap(model, frames, saliency)
    assert before > 0.0
    assert gaps[1.0] < 0.5 * before
    assert gaps[1.0] < 0.5 * gaps[0.0]


def test_frozen_encoder_is_not_trained_and_fine_tuning_is():
    for freeze in (True, False):
        torch.manual_seed(0)
        model = HModel(freeze_encoder=freeze)
        before = [p.clone() for p in model.encoder.parameters()]
        learner = Learner(model, alpha=1e-4)
        batch = make_batch(random_images(8), companions=list(random_images(8, seed=2)))
        for _ in range(3):
            learner.train_step(batch)
        unchanged = all(torch.equal(a, b) for a, b in zip(before, model.encoder.parameters()))
        assert unchanged == freeze


# Learning on real frames.
def test_greedy_action_becomes_the_rewarded_one(real_frames):
    """+1 for action 5 and -1 for every other action on real frames: argmax H becomes 5."""
    good = 5
    torch.manual_seed(1)
    model = HModel(encoder=load_encoder(DEFAULT_ENCODER))
    learner = Learner(model, learning_rate=1e-3, alpha=0.0)
    frames = np.stack([preprocess(f) for f in real_frames])
    count = len(frames)
    buffer = FeedbackBuffer(1000)
    for i, frame in enumerate(frames):
        for action in range(NUM_ACTIONS):
            buffer.add(Sample(torch.from_numpy(frame), None, action,
                              1.0 if action == good else -1.0, 1.0, i, i))
    rng = np.random.default_rng(0)

    def greedy():
        with torch.no_grad():
            return model(to_input(frames)).argmax(dim=1)

    assert not bool((greedy() == good).all())
    for update in range(1, 301):
        learner.train_step(buffer.sample(32, rng))
        if bool((greedy() == good).all()):
            break
    assert bool((greedy() == good).all()), f'not learned in {update} updates'
    assert count > 10


@pytest.mark.slow
def test_greedy_action_learns_to_depend_on_where_the_agent_is():
    """+1 for RIGHT left of x = 80 and for LEFT right of it: H must read the agent's place."""
    expert_module = pytest.importorskip('attention_tasks.montezuma.expert')
    from attention_tasks.montezuma.env import EnvConfig, MontezumaEnv
    env = MontezumaEnv(EnvConfig(seed=2, warmup_steps=0))
    expert = expert_module.RoomOneExpert()
    step = env.reset()
    frames, places = [], []
    for i in range(400):  # down the middle ladder, to the rope, down the right ladder
        step = env.step(expert.act(step.state, expert_module.skull_x_from_ram(env.ale.getRAM())))
        if i % 8 == 0 and step.state.room == 1:
            frames.append(preprocess(step.observation))
            places.append(step.state.x)
        if step.done:
            break
    env.close()
    frames, places = np.stack(frames), np.array(places)
    wanted = np.where(places < 80, 3, 4)  # RIGHT, LEFT
    assert len(set(wanted)) == 2 and len(set(places)) > 5
    torch.manual_seed(0)
    model = HModel(encoder=load_encoder(DEFAULT_ENCODER))
    learner = Learner(model, alpha=0.0)
    buffer = FeedbackBuffer(2000)
    for i, frame in enumerate(frames):
        for action in range(NUM_ACTIONS):
            buffer.add(Sample(torch.from_numpy(frame), None, action,
                              1.0 if action == wanted[i] else -1.0, 1.0, i, i))
    rng = np.random.default_rng(0)
    for update in range(1, 1001):
        learner.train_step(buffer.sample(32, rng))
        if update % 10 == 0:
            with torch.no_grad():
                chosen = model(to_input(frames)).argmax(dim=1).numpy()
            if (chosen == wanted).all():
                break
    assert (chosen == wanted).all(), f'{(chosen == wanted).mean():.0%} right after {update}'


def train_like_a_lockstep_run(learner, features, seed=0, feedback=1400, minibatch_every=5):
    """
    Feedback as a real 1,500-step run gave it: h in {-1, 0, +1} in that run's proportions.

    Logged from `attention_train --steps 1500` (vanilla): 864 x -1, 416 x 0, 92 x +1 on 1,372
    steps, the actions mostly the same few. One immediate update per feedback and a minibatch
    of 32 every fifth (the learner's pace in lockstep).
    """
    rng = np.random.default_rng(seed)
    buffer = FeedbackBuffer(feedback, (features.shape[1],), np.float32)
    for i in range(feedback):
        frame = int(rng.integers(len(features)))
        sample = Sample(features[frame], None, int(rng.choice([0, 1, 3, 4, 11, 12])),
                        float(rng.choice([-1.0, 0.0, 1.0], p=[0.63, 0.30, 0.07])), 1.0, i, i)
        buffer.add(sample)
        learner.train_step(collate([sample]))
        if i % minibatch_every == 0:
            learner.train_step(buffer.sample(32, rng))


@pytest.fixture(scope='module')
def route_frames():
    """50 distinct Room 1 frames along the expert's route (with detours), preprocessed."""
    frames, _ = collect_frames(50, seed=4, stride=6)
    return np.stack([preprocess(f) for f in frames])


def test_head_stays_alive_and_state_dependent_under_mostly_negative_feedback(route_frames):
    """The collapse seen in real runs: every hidden unit dead, H the same on every frame."""
    config = TamerConfig()
    torch.manual_seed(0)
    model = HModel(config.head_hidden, encoder=load_encoder(DEFAULT_ENCODER))
    learner = Learner(model, config.learning_rate, alpha=0.0,
                      max_grad_norm=config.max_grad_norm)
    with torch.no_grad():
        features = model.features(to_input(route_frames))
    train_like_a_lockstep_run(learner, features)
    with torch.no_grad():
        hidden = model.hidden(features)
        outputs = model.from_features(features)
    alive = (hidden > 0).any(dim=0).float().mean().item()
    assert alive > 0.5, f'only {alive:.0%} of the hidden units are ever active'
    assert outputs.std(dim=0).mean().item() > 0.05, 'H hardly differs between frames'
    assert len(set(outputs.argmax(dim=1).tolist())) >= 2, 'one action on every frame'


def test_cached_features_give_the_same_h_as_the_image_path(route_frames):
    torch.manual_seed(0)
    model = HModel(encoder=load_encoder(DEFAULT_ENCODER))
    unset = (model.encoder.feature_mean == 0).all() and (model.encoder.feature_std == 1).all()
    assert not unset, 'the shipped encoder has no feature stats'
    images = to_input(route_frames[:8])
    with torch.no_grad():
        assert torch.allclose(model(images), model.from_features(model.features(images)),
                              atol=1e-6)


def _greedy_after_teaching(model, contexts) -> list:
    """Teach H that action 0 is right in ``contexts[0]`` and action 1 in ``contexts[1]``."""
    learner = Learner(model, 3e-3, alpha=0.0, max_grad_norm=1.0)
    states, actions, h = [], [], []
    for context, right in ((0, 0), (1, 1)):
        for action in range(4):
            states.append(contexts[context])
            actions.append(action)
            h.append(1.0 if action == right else -1.0)
    for _ in range(300):
        learner.train_step(make_batch(torch.stack(states), actions=actions, h=h))
    with torch.no_grad():
        return model.from_features(torch.stack(contexts)).argmax(dim=1).tolist()


def test_with_both_images_h_acts_on_what_the_saliency_image_names(route_frames):
    """input_image both (language_input): the same frame, two utterances, two right actions."""
    torch.manual_seed(0)
    encoder = load_encoder(DEFAULT_ENCODER)
    model = HModel(16, encoder=encoder, num_actions=4, streams=2)
    with torch.no_grad():
        frame, named_a, named_b = model.features(to_input(route_frames[[0, 5, 9]]))
    both = [torch.cat([frame, named_a]), torch.cat([frame, named_b])]
    assert _greedy_after_teaching(model, both) == [0, 1]
    torch.manual_seed(0)  # H on the frame alone: the words never reach it, one state
    first, second = _greedy_after_teaching(HModel(16, encoder=encoder, num_actions=4),
                                           [frame, frame])
    assert first == second


def test_film_h_acts_on_what_the_words_name(route_frames):
    """text_conditioning film (the peer): the same frame, two missions, two right actions."""
    from tamer_node.words import bag_of_words
    torch.manual_seed(0)
    model = HModel(16, encoder=load_encoder(DEFAULT_ENCODER), num_actions=4, text_size=64)
    with torch.no_grad():
        frame = model.features(to_input(route_frames[:1]))[0]
    contexts = [torch.cat([frame, bag_of_words(text, 64)])
                for text in ('pick up the red ball', 'pick up the purple key')]
    with torch.no_grad():  # FiLM starts as no change: the words matter only once learned
        before = model.from_features(torch.stack(contexts))
    assert torch.equal(before[0], before[1])
    assert _greedy_after_teaching(model, contexts) == [0, 1]


def test_a_bag_of_words_tells_missions_apart_and_ignores_case():
    from tamer_node.words import bag_of_words
    red = bag_of_words('pick up the red ball', 64)
    purple = bag_of_words('pick up the purple ball', 64)
    assert not torch.equal(red, purple)
    assert torch.equal(red, bag_of_words('Pick up the RED ball!', 64))
    assert torch.linalg.vector_norm(red).item() == pytest.approx(1.0)
    assert not bag_of_words('', 64).any()


# Credit assignment on hand-made timelines.
@pytest.mark.parametrize('span,feedback_at,expected', [
    ((0.0, 1.0), 1.0, 0.8 / 3.8),            # the window [-3, 0.8] covers [0, 0.8]
    ((0.0, 1.0), 5.0, 0.0),                  # window [1, 4.8]: ends exactly where it begins
    ((0.0, 1.0), 4.5, 0.5 / 3.8),            # window [0.5, 4.3]
    ((2.0, 3.0), 5.0, 1.0 / 3.8),            # entirely inside
    ((4.9, 5.0), 5.0, 0.0),                  # shown within the last 0.2 s
    ((-10.0, 10.0), 5.0, 1.0),               # covers the whole window
    ((0.9, 1.0), 5.0, 0.0),                  # ended before the window opened
])
def test_window_weight(span, feedback_at, expected):
    stamp = int(span[0] * S)
    credit = window_credit([(stamp, int(span[0] * S), int(span[1] * S))], int(feedback_at * S))
    assert credit.get(stamp, 0.0) == pytest.approx(expected)
    assert (stamp in credit) == (expected > 0)  # zero weight: no sample at all


def test_window_credit_on_a_15_hz_timeline():
    step = S // 15
    stamps = [i * step for i in range(150)]          # 10 s of steps
    now = stamps[-1]
    credit = window_credit(spans_from_stamps(stamps, now), now)
    assert sum(credit.values()) == pytest.approx(1.0, abs=1e-6)
    credited = sorted(credit)
    assert credited[0] >= now - 4 * S - step and credited[-1] <= now - 0.2 * S
    assert now not in credit and stamps[-3] not in credit     # inside the last 0.2 s
    inside = [w for s, w in credit.items() if now - 3.9 * S < s < now - 0.3 * S]
    assert inside and max(inside) == pytest.approx(min(inside))  # uniform density
    assert all(w == pytest.approx(1 / 15 / 3.8) for w in inside)


def test_step_credit_labels_exactly_the_judged_step():
    assert step_credit(20, [10, 20, 30]) == {20: 1.0}
    assert step_credit(25, [10, 20, 30]) == {}


def test_spans_follow_the_next_stamp():
    assert spans_from_stamps([30, 10, 20], 35) == [(10, 10, 20), (20, 20, 30), (30, 30, 35)]
    assert spans_from_stamps([], 5) == []


# The replay buffer.
def sample_with(seq):
    return Sample(torch.full(INPUT_SHAPE, seq % 256, dtype=torch.uint8), None, seq % 18,
                  1.0, 1.0, seq, seq)


def test_buffer_is_bounded_and_drops_the_oldest():
    buffer = FeedbackBuffer(5)
    for seq in range(12):
        buffer.add(sample_with(seq))
    assert len(buffer) == 5
    assert [s.seq for s in buffer.samples()] == [7, 8, 9, 10, 11]
    assert buffer.added == 12


def test_buffer_sampling():
    buffer = FeedbackBuffer(100)
    with pytest.raises(ValueError):
        buffer.sample(4, np.random.default_rng(0))
    for seq in range(3):
        buffer.add(sample_with(seq))
    small = buffer.sample(32, np.random.default_rng(0))
    assert small.states.shape == (3,) + INPUT_SHAPE  # never more than it holds, no repeats
    assert sorted(small.actions.tolist()) == [0, 1, 2]
    for seq in range(3, 100):
        buffer.add(sample_with(seq))
    seen = set()
    rng = np.random.default_rng(1)
    for _ in range(40):
        batch = buffer.sample(10, rng)
        assert batch.states.dtype == torch.uint8 and batch.h.dtype == torch.float32
        assert len(set(batch.states[:, 0, 0].tolist())) == 10
        seen.update(batch.states[:, 0, 0].tolist())
    assert len(seen) > 90  # uniform over the whole buffer


def test_buffer_is_safe_under_concurrent_adds_and_samples():
    buffer = FeedbackBuffer(50)
    errors = []

    def add(offset):
        for seq in range(offset, offset + 500):
            buffer.add(sample_with(seq))

    def sample():
        rng = np.random.default_rng(0)
        try:
            for _ in range(200):
                if len(buffer):
                    buffer.sample(8, rng)
        except Exception as error:  # noqa: B902 - any failure counts
            errors.append(error)

    threads = [threading.Thread(target=add, args=(i * 1000,)) for i in range(3)]
    threads.append(threading.Thread(target=sample))
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(30)
    assert not errors and len(buffer) == 50 and buffer.added == 1500


def test_collate_marks_missing_saliency_images():
    base = sample_with(1)
    batch = collate([base, base._replace(companion=torch.ones(INPUT_SHAPE, dtype=torch.uint8))])
    assert batch.has_companion.tolist() == [False, True]
    assert int(batch.companions[0].sum()) == 0


# Model and configuration.
def test_preprocess_keeps_the_saliency_blur_visible(real_frames):
    frame = real_frames[0]
    image = preprocess(frame)
    assert image.shape == INPUT_SHAPE and image.dtype == np.uint8
    blurred = preprocess(saliency_like(frame, np.random.default_rng(0)))
    assert np.abs(image.astype(int) - blurred).mean() > 2.0
    for bad in (frame[:, :, 0], frame[:100], frame.astype(np.float32)):
        with pytest.raises(ValueError):
            preprocess(bad)


def test_encoder_weights_round_trip(tmp_path):
    torch.manual_seed(0)
    autoencoder = ConvAutoencoder()
    path = tmp_path / 'encoder.pt'
    save_encoder(autoencoder.encoder, path, {'note': 'test'})
    loaded = load_encoder(path)
    x = to_input(random_images(2))
    assert torch.equal(loaded(x), autoencoder.encoder(x))
    assert autoencoder(x).shape == x.shape
    torch.save({'something': 'else'}, tmp_path / 'other.pt')
    with pytest.raises(ValueError):
        load_encoder(tmp_path / 'other.pt')


def test_shipped_encoder_loads_and_is_small():
    assert DEFAULT_ENCODER.exists(), 'run tamer_pretrain to build the shipped encoder'
    assert DEFAULT_ENCODER.stat().st_size < 2 * 1024 * 1024
    encoder = load_encoder(DEFAULT_ENCODER)
    assert isinstance(encoder, Encoder)
    blob = torch.load(DEFAULT_ENCODER, weights_only=True)
    assert blob['info']['frames'] >= 2000


def test_every_config_field_has_a_docstring_and_validates():
    docs = field_docs()
    assert set(docs) == {field.name for field in dataclasses.fields(TamerConfig)}
    assert all(docs.values())
    assert {'alpha', 'credit', 'resume', 'run_dir', 'encoder_path'} <= set(docs)
    config = TamerConfig()
    assert config.alpha == 1e-4 and config.credit == 'step'
    config.validate()
    for change in ({'credit': 'later'}, {'input_image': 'mask'}, {'alpha': -1.0},
                   {'window_min_s': 5.0}, {'batch_size': 0}, {'update_clock': 'cpu'},
                   {'update_backlog_s': -1.0}):
        with pytest.raises(ValueError):
            TamerConfig(**change).validate()


def test_frame_shape_matches_the_env():
    from attention_tasks.montezuma.env import FRAME_HEIGHT, FRAME_WIDTH
    assert FRAME_SHAPE == (FRAME_HEIGHT, FRAME_WIDTH, 3)


def test_a_non_finite_loss_is_skipped_and_the_weights_stay_intact():
    torch.manual_seed(0)
    model = HModel()
    learner = Learner(model, alpha=0.0)
    before = {k: v.clone() for k, v in model.state_dict().items()}
    batch = make_batch(random_images(4), h=[1.0, float('nan'), 0.0, 1.0])
    terms = learner.train_step(batch)
    assert terms['skipped'] == 1 and learner.updates == 0
    assert all(torch.equal(v, model.state_dict()[k]) for k, v in before.items())


def run_schedule(schedule, clock_times, learner_keeps_up=True):
    """Feed clock readings; take every owed update (or none); return the updates taken."""
    taken = 0
    for t in clock_times:
        schedule.start(t)
        schedule.advance(t)
        while learner_keeps_up and schedule.take():
            taken += 1
    return taken


@pytest.mark.parametrize('steps_per_reading', [1, 4, 37])
def test_the_schedule_owes_the_rate_per_clock_second_whatever_the_reading_pace(
        steps_per_reading):
    """15 Hz sim stamps read every step, or in bursts (a fast or slow learner), give 5/s."""
    stamps = [i * (S // 15) for i in range(15 * 60 + 1)]  # one minute of simulation
    readings = stamps[::steps_per_reading] + [stamps[-1]]
    schedule = UpdateSchedule(rate_hz=5.0, max_backlog=1000)
    taken = run_schedule(schedule, [t / S for t in readings])
    assert abs(taken - 5 * 60) <= 1 and schedule.skipped == 0


def test_the_schedule_drops_and_counts_what_exceeds_the_backlog():
    schedule = UpdateSchedule(rate_hz=10.0, max_backlog=20)
    schedule.start(0.0)
    schedule.advance(10.0)  # 100 owed, 20 may wait
    assert schedule.skipped == 80 and int(schedule.owed) == 20
    assert run_schedule(schedule, [10.0]) == 20 and not schedule.take()


def test_the_schedule_restarts_when_the_clock_goes_back_and_owes_nothing_before_start():
    schedule = UpdateSchedule(rate_hz=2.0, max_backlog=100)
    schedule.advance(50.0)
    assert not schedule.take() and schedule.due_at() == float('inf')  # not started
    schedule.start(50.0)
    schedule.advance(51.0)
    assert schedule.take() and schedule.take() and not schedule.take()
    schedule.advance(3.0)  # a new trial's stamps
    assert not schedule.take() and schedule.due_at() == pytest.approx(3.5)
    schedule.advance(4.0)
    assert schedule.take() and schedule.take() and not schedule.take()
