"""
Pairing a feedback event with the steps it credits: pure functions, no threads, no locks.

The learner thread calls them (learner_loop.py) and adds what they return to the buffer and the
counters; the one thing they change is the feature cache of the history they are given.

Pairing with saliency images: the steps a feedback credits may still wait for their saliency
image. The event stays at the head of the pending queue until every such image came, an image of
a later step came on that stream (so this one never will), or ``saliency_timeout_s`` of wall time
passed (``settled``); then the steps without an image are used without the L2 term. Nothing
waits forever, and the events behind it wait no longer than that.
"""

import collections
from typing import Counter, Dict, List, NamedTuple, Optional, Tuple

import numpy as np
from tamer_node.buffer import Sample
from tamer_node.config import TamerConfig
from tamer_node.credit import effect_credit, step_credit, window_credit
from tamer_node.delay_fit import candidate_intervals, DelayFit, fitted_credit, Interval
from tamer_node.events import FeedbackEvent
from tamer_node.history import other_kind, StepHistory, StepRecord
from tamer_node.model import HModel, to_input
from tamer_node.posterior import feedback_likelihood, posterior_weights
import torch


class Paired(NamedTuple):
    """What one feedback event gives the learner."""

    samples: List[Sample]
    counts: Counter[str]
    """Counter increments (``events.LEARNER_COUNTERS``)."""
    warning: Optional[str]
    """Why an 'ok' feedback is not learned from, or None."""
    delays: Optional[Dict[int, Interval]] = None
    """With a delay fit: each credited step's delay (the fit learns from them), else None."""


def credit(event: FeedbackEvent, history: StepHistory, config: TamerConfig,
           delays: Optional[DelayFit] = None) -> Dict[int, float]:
    """Return {stamp: weight} of the steps in ``history`` that ``event`` credits."""
    return credit_and_delays(event, history, config, delays)[0]


def credit_and_delays(event: FeedbackEvent, history: StepHistory, config: TamerConfig,
                      delays: Optional[DelayFit] = None
                      ) -> Tuple[Dict[int, float], Dict[int, Interval]]:
    """Return ``credit``'s {stamp: weight}, and with a delay fit each step's delay."""
    intervals: Dict[int, Interval] = {}
    if event.credit == 'window':
        if event.now is None:
            return {}, {}
        spans = history.acted_spans(event.now)
        if delays is not None:  # the window's prior as fitted so far (delay_fit.py)
            intervals = candidate_intervals(spans, event.now, config.credit_anchor)
            steps = fitted_credit(intervals, delays)
        else:
            spread = effect_credit if config.credit_anchor == 'effect' else window_credit
            steps = spread(spans, event.now, config.window_min_s, config.window_max_s)
    else:
        record = history.get(event.stamp) if event.stamp is not None else None
        known = [event.stamp] if record is not None and record.learned_action is not None else []
        steps = step_credit(event.stamp, known)
    if config.decision_period_s > 0.0:
        steps = to_decisions(steps, history)
    return steps, intervals


def to_decisions(steps: Dict[int, float], history: StepHistory) -> Dict[int, float]:
    """
    Move each step's credit to the step that chose its action (``decision_period_s`` > 0).

    A held action is one decision, made on the state of its first step: that is the (s, a)
    the agent acts on, so that is what a verdict on any of its steps labels. A step keeps its
    own credit when its decision's first step is no longer held, or was learned on another
    action (a replay's ``action_taken``: the world did not hold the agent's decision).
    """
    decided: Dict[int, float] = collections.defaultdict(float)
    for stamp, weight in steps.items():
        record = history.get(stamp)
        first = record.decision if record is not None else None
        chose = history.get(first) if first is not None else None
        if chose is None or chose.learned_action != record.learned_action:
            first = stamp
        decided[first] += weight
    return dict(decided)


def settled(event: FeedbackEvent, history: StepHistory, config: TamerConfig,
            wants_companion: bool) -> bool:
    """
    Return whether nothing the steps ``event`` credits wait for can still come.

    That is their companion image (``wants_companion``) and, with ``await_taken``, the action
    the world took on them (a replay's ``action_taken``, which travels on its own topic and may
    come after the feedback).
    """
    if event.status != 'ok' or not (wants_companion or config.await_taken):
        return True
    steps = credit(event, history, config)
    if config.await_taken and not all(_taken(history, stamp) for stamp in steps):
        return False
    if not wants_companion:
        return True
    companion = companion_kind(config.input_image)
    return all(history.settled(stamp, companion) for stamp in steps)


def _taken(history: StepHistory, stamp: int) -> bool:
    record = history.get(stamp)
    return record is not None and record.taken is not None


def companion_kind(input_image: str) -> str:
    """Return the image a step waits for besides the one acted on ('both': its saliency)."""
    return 'saliency' if input_image == 'both' else other_kind(input_image)


def both_item(record: StepRecord, history: StepHistory, model: HModel) -> torch.Tensor:
    """
    Return a step's (2240,) state with ``input_image: both``, for the actor and the learner.

    Each image's features are computed once and cached in the history; the observation stands
    in for a saliency image that never came.
    """
    saliency = 'saliency' if record.saliency is not None else 'observation'
    return torch.cat([stored_item(record, 'observation', history, model),
                      stored_item(record, saliency, history, model)])


def stored_item(record: StepRecord, kind: str, history: StepHistory,
                model: HModel) -> Optional[torch.Tensor]:
    """
    Return what the buffer keeps of a step's ``kind`` image: the image, or its features.

    With a frozen encoder: the features the actor cached when it acted, else (the saliency
    companion, a resumed step) computed here once and cached in the history.
    """
    image = record.image(kind)
    if image is None or not model.freeze_encoder:
        return image
    features = record.features(kind)
    if features is None:
        with torch.no_grad():
            features = model.features(to_input(image))[0]
        history.put_features(kind, record.stamp, features)
    return features


@torch.no_grad()
def predict_judged(model: HModel, states: torch.Tensor, actions: torch.Tensor) -> np.ndarray:
    """Return H(s, a) of rows of images, or of cached features (a frozen encoder)."""
    values = (model(to_input(states)) if states.dtype == torch.uint8
              else model.from_features(states))
    return values.gather(1, actions.long().unsqueeze(1)).squeeze(1).numpy()


def by_prediction(samples: List[Sample], model: HModel, noise: float) -> List[Sample]:
    """Return one feedback's samples re-weighted by credit by prediction (posterior.py)."""
    predicted = predict_judged(model, torch.stack([s.state for s in samples]),
                               torch.tensor([s.action for s in samples]))
    priors = np.array([s.weight for s in samples])
    weights = posterior_weights(priors, feedback_likelihood(
        np.array([s.h for s in samples]), predicted, noise), np.zeros(len(samples)))
    return [s._replace(weight=float(w), prior=s.weight) for s, w in zip(samples, weights)]


def pair(event: FeedbackEvent, history: StepHistory, config: TamerConfig, model: HModel,
         wants_companion: bool, delays: Optional[DelayFit] = None) -> Paired:
    """Return the samples of ``event`` on the steps of ``history``, and what to count."""
    samples: List[Sample] = []
    intervals: Dict[int, Interval] = {}
    counts = collections.Counter({'feedback/processed': 1})
    warning = None
    if event.status == 'ok' and event.session != history.session:
        counts['feedback/other_session'] += 1
        warning = (f'feedback #{event.seq} (h={event.h}) is on a step of session '
                   f'{event.session}, and the steps held are of session {history.session} '
                   '(the env started over): kept in the log, not learned from')
    elif event.status == 'ok':
        kind = config.input_image
        steps, intervals = credit_and_delays(event, history, config, delays)
        for stamp, weight in sorted(steps.items()):
            record = history.get(stamp)
            acted_on = 'observation' if kind == 'both' else kind
            if record is None or record.image(acted_on) is None:
                continue  # evicted meanwhile, or never had the image acted on
            if kind == 'both':  # the saliency image is in the state: no L2 companion
                state, companion = both_item(record, history, model), None
                counts['pairing/with_saliency' if record.saliency is not None
                       else 'pairing/without_saliency'] += 1
            else:
                state = stored_item(record, kind, history, model)
                companion = stored_item(record, other_kind(kind), history, model)
                counts['pairing/with_saliency' if companion is not None
                       else 'pairing/without_saliency'] += 1
            if model.text_size:  # the words the agent read when it acted (none: zeros)
                words = record.text if record.text is not None else torch.zeros(
                    model.text_size)
                state = torch.cat([state, words])
                companion = None if companion is None else torch.cat([companion, words])
            samples.append(Sample(state, companion, record.learned_action, float(event.h),
                                  float(weight), stamp, event.seq, history.session))
        if samples and config.credit_posterior and event.credit == 'window':
            samples = by_prediction(samples, model, config.credit_noise)
        if samples:
            counts['feedback/count'] += 1
            counts['samples/added'] += len(samples)
        else:
            counts['feedback/unmatched'] += 1
            warning = (f'feedback #{event.seq} (h={event.h}) matches no step the agent acted '
                       f'on (credit {event.credit}, stamp {event.stamp}); kept in the log, not '
                       'learned from')
    elif event.status == 'duplicate':
        counts['feedback/duplicates'] += 1
    elif event.status == 'invalid':
        counts['feedback/invalid'] += 1
    else:
        counts['feedback/unmatched'] += 1
    if not wants_companion:
        counts.pop('pairing/without_saliency', None)
    return Paired(samples, counts, warning,
                  {s.stamp: intervals[s.stamp] for s in samples} if intervals else None)
