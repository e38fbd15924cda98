"""Every hyperparameter of the learner in one dataclass; each field is a ROS parameter too."""

from dataclasses import dataclass
from typing import Dict

from attention_common.feedback import COPY_WINDOW_S
from attention_common.parameters import field_docs as _field_docs
from attention_common.recorder_gate import RECORDER_WAIT_S
from attention_common.stamps import MAX_STAMP_JUMP_S
from attention_tasks.task import DEFAULT_TASK, load_task

CREDIT_MODES = ('step', 'window')
CREDIT_LOSSES = ('each', 'mixture')
CREDIT_ANCHORS = ('span', 'effect')
INPUT_IMAGES = ('observation', 'saliency', 'both')
"""'both': H sees the step's frame and its saliency image side by side (language_input)."""
TEXT_CONDITIONINGS = ('off', 'film')
WAITS_FOR_SALIENCY = ('saliency', 'both')
"""The inputs that need a step's saliency image before the agent acts on it."""
UPDATE_CLOCKS = ('sim', 'wall')
SYNC_MODES = ('off', 'grouped', 'every')


@dataclass
class TamerConfig:
    """Deep TAMER with the saliency L2 term (thesis eq. 4.3/4.4); names equal ROS parameters."""

    task: str = DEFAULT_TASK
    """The task: its frame size, its actions (H has one output each) and its pretrained
    encoder ('montezuma' or 'doorkey'; see attention_tasks)."""
    alpha: float = 1e-4
    """Weight of the saliency L2 term in loss = MSE + alpha * L2; 0 is vanilla Deep TAMER."""
    credit: str = 'step'
    """How plain and pressed feedback is credited: 'step', to the newest step (s_T, a_T);
    'window', Deep TAMER's credit window. Stamped feedback names the step it judges and is
    credited to it either way (a trainer's stamp, a person's press on a paused frame)."""
    window_min_s: float = 0.2
    """Credit window: the shortest delay (simulation s) between an action and feedback on it."""
    window_max_s: float = 4.0
    """Credit window: the longest delay (simulation s) between an action and feedback on it."""
    credit_anchor: str = 'span'
    """What moment of a step the window's delay runs from: 'span', any moment while the step
    was shown, equally likely (Deep TAMER: a world that moves while the action lasts); 'effect',
    the moment the step's result was shown, the next observation (a world that changes in
    discrete steps, as MiniGrid's 1 s steps: a person judges the move when they see it made).
    With 'effect' a verdict falls on one or two 1 s steps where 'span' spreads it on three."""
    credit_loss: str = 'each'
    """How a feedback's credited steps are fitted: 'each' regresses every one to h, weighted by
    its credit (Deep TAMER); 'mixture' regresses their credit-weighted mean of H to h (one
    of them was judged; learner.mixture_mse), and a minibatch is batch_size whole feedbacks."""
    credit_posterior: bool = False
    """Window credit by prediction (posterior.py): each step's share of a late feedback is its
    window weight times how likely H finds that verdict there (the latent delay's posterior);
    False: the plain window (Deep TAMER)."""
    credit_noise: float = 0.02
    """Credit by prediction: the probability that a verdict has the wrong sign (in [0, 0.5));
    it bounds how far H's predictions move credit (0.02: at most 49 to 1; 0.1, the human-like
    teacher's true rate, moved credit less: agreement with the expert 0.5 against 0.6-0.7 in
    the last steps of 10,000, in one process, 2 tuning seeds)."""
    credit_delay_fit: bool = False
    """Fit the trainer's delay online (delay_fit.py, needs credit_posterior): the window's flat
    prior on [window_min_s, window_max_s] becomes a histogram learned by EM from where credit
    by prediction puts each verdict, so a wide window for a trainer of unknown delay narrows to
    theirs. False: the flat window (Deep TAMER)."""
    credit_delay_bin_s: float = 0.1
    """Delay fit: the width of the histogram's bins (simulation s)."""
    credit_delay_prior: float = 20.0
    """Delay fit: the flat prior's weight, in verdicts (spread evenly over the bins)."""
    credit_refit_updates: int = 10
    """Credit by prediction: re-weigh every sample of the buffer with the current H after this
    many updates (0 = only when a feedback is paired)."""
    positive_excludes: float = 0.0
    """Weight of the -1 a verdict of +1 implies for every other action of its state (a label
    on the policy: what the trainer wanted, so mostly not the others; learner.excluded_mse).
    0: each verdict teaches only the action judged (the thesis's and Deep TAMER's)."""
    verdict_memory: float = 0.0
    """Weight of the verdicts remembered for each exact state, blended into H when acting
    (memory.py: pseudo-counts, so an action judged bad in this very state is not taken again
    before the untried ones). 0: H alone (the thesis's)."""
    revisit_penalty: float = 0.0
    """How much lower an action's H (clipped to [-1, 1]) counts, per time it was taken in this
    exact state within the last ``revisit_steps`` acted steps (revisits.py: back in a state it
    just left, the agent tries another action, so a loop opens). 0: H alone (the thesis's)."""
    revisit_steps: int = 100
    """The acted steps ``revisit_penalty`` remembers (DoorKey: one episode's length)."""
    kept_per_batch: int = 0
    """Rows of each minibatch drawn from a ring of their own that holds only step-credited
    samples (stamped verdicts, answers to questions; ``KEPT_CAPACITY`` of them): a window's many
    rows push them out of the main ring within a few thousand steps, and this keeps every one
    rehearsed. 0: one ring (the thesis's). Not with the ``mixture`` credit loss."""
    ask_rate: float = 0.0
    """Questions per acted step, at most, on average (questions.py): the agent asks the trainer
    (topic ``question``) about a step where H's best action is less than ``ask_margin`` ahead
    of the next; the answer comes stamped with that step. 0: never asks (the thesis's)."""
    ask_budget: int = 0
    """Questions in all, at most, this session (0: no end): the same questions as a lower
    rate, asked at ``ask_rate`` from the start, while the agent knows least."""
    ask_margin: float = 0.5
    """Below this gap between H's two best actions (within [-1, 1]) the agent is unsure."""
    ask_burst: float = 5.0
    """Questions saved up, at most, while the agent was sure (the token bucket's size)."""
    learning_rate: float = 3e-4
    """Adam step size of the learner (1e-3 with mostly -1 feedback killed the head's units)."""
    max_grad_norm: float = 1.0
    """Clip each update's gradient to this global norm (0 = no clipping)."""
    batch_size: int = 32
    """Samples per minibatch update from the replay buffer."""
    buffer_capacity: int = 10000
    """Labelled samples the feedback replay buffer keeps (oldest dropped first)."""
    update_rate_hz: float = 6.0
    """Minibatch updates from the buffer per second of update_clock (0 = immediate only)."""
    update_clock: str = 'sim'
    """'sim': update_rate_hz per second of simulation time (observation stamps), the same
    number per agent step whatever the wall speed; 'wall': per wall-clock second."""
    update_backlog_s: float = 5.0
    """update_clock 'sim': the learner may owe this many sim seconds of minibatch updates; older
    owed updates are dropped and counted (train/skipped_updates). 'wall' never catches up."""
    immediate_update: bool = True
    """Also take one update on the samples of each new feedback as soon as it is paired."""
    saliency_timeout_s: float = 0.5
    """Wall seconds a labelled sample waits for its step's saliency image before L2-less use."""
    history_steps: int = 512
    """Recent steps (image, action, time span) kept for attributing feedback to them."""
    plain_copies: bool = False
    """true: the trainer also sends every stamped (or pressed) verdict as plain feedback
    (feedback_node ``plain_copies``), so a plain feedback that pairs with one of the same h at
    most ``stamped_active_s`` before it is such a copy, logged 'duplicate' and not learned.
    false (feedback_node's default too): every plain feedback is its own and is learned, even
    right beside stamped ones (a teacher that marks or answers questions, a person who presses
    both while paused and while the game runs)."""
    stamped_active_s: float = COPY_WINDOW_S
    """Wall seconds after a stamped (or pressed) verdict during which one plain feedback of the
    same h counts as its copy, with ``plain_copies``
    (``attention_common.feedback.PlainCopies``)."""
    max_stamp_jump_s: float = MAX_STAMP_JUMP_S
    """Simulation seconds: an image stamped further than this from the newest observation is
    dropped with a warning (3 such observations in a row that continue each other: the env
    started over, and a new session of the run begins)."""
    checkpoint_period_s: float = 60.0
    """Longest wall time between atomic checkpoints in <run_dir>/checkpoints: the first comes
    after the first update, then 1, 2, 4, ... s apart up to this (0 = only at exit)."""
    metrics_period_s: float = 1.0
    """Wall seconds between metrics messages (and rows of metrics.csv)."""
    values_rate_hz: float = 30.0
    """Most action_values messages a wall second, with bursts of a few (a viewer shows no more:
    real time's 15 steps a second pass whole, a lockstep run's 150-200 are thinned at the source
    so watching costs the acting path less; 0 = every step)."""
    fine_tune_encoder: bool = False
    """Train the pretrained encoder too (Deep TAMER keeps it frozen)."""
    input_image: str = 'observation'
    """Image the agent acts and learns on: 'observation', the step's 'saliency' image, or
    'both' (the features of each, side by side: the words the saliency image grounds reach H
    when it acts, as in the language_input condition; needs the frozen encoder)."""
    text_conditioning: str = 'off'
    """'film': H's hidden layer is scaled and shifted by the words of the utterance in force
    (the newest heard), as BabyAI's text-conditioned agents read their instruction (FiLM);
    'off': H never reads words (the thesis's learners, language_input)."""
    text_size: int = 64
    """Buckets of the hashed bag of words (words.py) with text_conditioning film."""
    head_hidden: int = 64
    """Hidden units of H's fully connected head."""
    share_action_parts: bool = False
    """Each action's output adds weights shared with the actions that have the same joystick
    part (horizontal, vertical, button; model.PartsHead): a verdict on UPRIGHT also teaches
    RIGHT and UP a little. False: 18 independent outputs (the thesis's)."""
    decision_period_s: float = 0.0
    """Simulation seconds one decision lasts at least: the greedy action is chosen on a step and
    held on the next observations until this much time has passed (0 = a decision every step,
    the thesis's). 0.2 acts at 5 Hz, as TAMER agents did for a person to judge: 3 steps of Room
    1 (15 Hz), every step of DoorKey (1 Hz). Late credit then goes to the steps that chose."""
    decision_switch_margin: float = 0.0
    """With decision_period_s > 0: a held decision ends early when another action's H (within
    the feedback range [-1, 1]) is above the held one's by more than this, so long decisions
    (purer late credit) need not walk the agent into what it has learned is bad (0 = always
    held for the whole period)."""
    greedy_margin: float = 0.0
    """0: the thesis's greedy policy (argmax, ties to the lowest action). Above 0: H clipped
    to [-1, 1], actions within this margin of the best are tied, ties broken at random
    (attention_train sets 0.1 with the teacher; see acting.ActingModel)."""
    explore: float = 0.0
    """Share of new decisions taken at random instead of greedily (0: the thesis's greedy
    policy). The trainer judges them like any other; without them a greedy learner never tries,
    where it is right, an action it was taught is bad elsewhere (Fetch: the pick-up in front of
    the target, after many wrong pick-ups: 0 of 99 held-out rooms solved, 437 of 454 with 0.1;
    docs/words/). Counted in act/explored."""
    await_taken: bool = False
    """A feedback waits (at most ``saliency_timeout_s``) until every step it credits has its
    ``action_taken``: attention_replay sets it, as that action travels on its own topic and
    could come after the feedback, which would then be learned on the agent's own answer."""
    keep_tied_action: bool = False
    """With greedy_margin > 0: a tie that includes the previous step's action keeps it, so the
    agent changes what it does only when H prefers another action (runs of one action are
    what late feedback can be attributed to)."""
    pace_updates: float = 2.0
    """The actor waits before it acts while the learner owes more than this many minibatch
    updates (0 = never): a lockstep graph that steps faster than its learner trains would
    otherwise drop owed updates, and the study's conditions would not learn equally. In real
    time (15 steps/s) the learner keeps up and the actor never waits."""
    pace_max_s: float = 0.25
    """Longest wall time one such wait lasts."""
    learner_nice: int = 10
    """Niceness the learner thread adds to its own (Linux, 0-19): on a busy machine acting, the
    graph's critical path, gets the CPU first and the learner takes what is left (0: equal)."""
    seed: int = 0
    """Seeds the head's initial weights and minibatch sampling."""
    encoder_path: str = ''
    """Pretrained encoder weights ('' = the task's, shipped in tamer_node/weights/: encoder.pt
    for Room 1, encoder_doorkey.pt for DoorKey)."""
    run_dir: str = ''
    """Folder for metrics.csv, feedback_log.jsonl, checkpoints/ ('' = a new dated folder)."""
    resume: bool = False
    """Continue the run in run_dir from its last checkpoint and its feedback log."""
    initial_model: str = ''
    """H's weights at start from a trained run: its checkpoint file or its run folder ('' =
    untrained). The run itself is new (its own logs, buffer and counters); a resume of it
    continues from its own checkpoint. The model must fit this learner (task, input_image,
    text_conditioning, head_hidden, share_action_parts)."""
    sync: str = 'grouped'
    """When a feedback_log.jsonl line is made durable (fdatasync) before its receipt
    (feedback_logged) goes out: 'grouped' (one fdatasync for the lines logged together, as
    soon as the disk thread has nothing more queued or the oldest waited 0.1 s), 'every' (one
    per line), 'off' (flushed to the OS only: survives a kill -9, not a power cut)."""
    wait_for_recorder: str = ''
    """Start-up: the node name of a session recorder (the launcher's session_recorder when it
    records; '' = none). No action, receipt, credit or metrics goes out until that node is
    matched on each of those topics, so the bag misses none; they wait, in order."""
    wait_for_recorder_s: float = RECORDER_WAIT_S
    """Longest start-up wait for that recorder, in wall seconds; then publish anyway, with a
    warning naming the topics it had not matched."""

    def validate(self) -> None:
        """Raise ValueError naming the first field with an impossible value."""
        load_task(self.task)  # UnknownTask (a ValueError) names the installed ones
        if self.credit not in CREDIT_MODES:
            raise ValueError(f'credit must be one of {CREDIT_MODES}, got {self.credit!r}')
        if self.credit_anchor not in CREDIT_ANCHORS:
            raise ValueError(
                f'credit_anchor must be one of {CREDIT_ANCHORS}, got {self.credit_anchor!r}')
        if self.credit_loss not in CREDIT_LOSSES:
            raise ValueError(
                f'credit_loss must be one of {CREDIT_LOSSES}, got {self.credit_loss!r}')
        if self.sync not in SYNC_MODES:
            raise ValueError(f'sync must be one of {SYNC_MODES}, got {self.sync!r}')
        if self.kept_per_batch and self.credit_loss != 'each':
            raise ValueError('kept_per_batch draws single rows: it needs credit_loss each, got '
                             f'{self.credit_loss!r}')
        if self.update_clock not in UPDATE_CLOCKS:
            raise ValueError(
                f'update_clock must be one of {UPDATE_CLOCKS}, got {self.update_clock!r}')
        if self.input_image not in INPUT_IMAGES:
            raise ValueError(
                f'input_image must be one of {INPUT_IMAGES}, got {self.input_image!r}')
        if self.text_conditioning not in TEXT_CONDITIONINGS:
            raise ValueError(f'text_conditioning must be one of {TEXT_CONDITIONINGS}, got '
                             f'{self.text_conditioning!r}')
        if self.text_conditioning != 'off' and self.fine_tune_encoder:
            raise ValueError("text_conditioning 'film' works on the frozen encoder's features; "
                             'fine_tune_encoder must be false')
        if self.credit_delay_fit and not self.credit_posterior:
            raise ValueError('credit_delay_fit learns from credit by prediction: set '
                             'credit_posterior true too')
        if self.credit_delay_fit and self.decision_period_s > 0.0:
            raise ValueError('credit_delay_fit fits the delay of single steps: it cannot be '
                             'used with decision_period_s > 0')
        if self.input_image == 'both' and self.fine_tune_encoder:
            raise ValueError("input_image 'both' works on the frozen encoder's features; "
                             'fine_tune_encoder must be false')
        if not 0.0 <= self.window_min_s < self.window_max_s:
            raise ValueError('the credit window needs 0 <= window_min_s < window_max_s, got '
                             f'{self.window_min_s}, {self.window_max_s}')
        checks = {
            'alpha': self.alpha >= 0.0,
            'learning_rate': self.learning_rate > 0.0,
            'max_grad_norm': self.max_grad_norm >= 0.0,
            'batch_size': self.batch_size >= 1,
            'buffer_capacity': self.buffer_capacity >= 1,
            'update_rate_hz': self.update_rate_hz >= 0.0,
            'update_backlog_s': self.update_backlog_s >= 0.0,
            'saliency_timeout_s': self.saliency_timeout_s >= 0.0,
            'history_steps': self.history_steps >= 2,
            'stamped_active_s': self.stamped_active_s >= 0.0,
            'max_stamp_jump_s': self.max_stamp_jump_s > 0.0,
            'checkpoint_period_s': self.checkpoint_period_s >= 0.0,
            'metrics_period_s': self.metrics_period_s > 0.0,
            'values_rate_hz': self.values_rate_hz >= 0.0,
            'text_size': self.text_size >= 1,
            'head_hidden': self.head_hidden >= 1,
            'greedy_margin': 0.0 <= self.greedy_margin <= 2.0,
            'explore': 0.0 <= self.explore < 1.0,
            'positive_excludes': self.positive_excludes >= 0.0,
            'verdict_memory': self.verdict_memory >= 0.0,
            'revisit_penalty': self.revisit_penalty >= 0.0,
            'revisit_steps': self.revisit_steps >= 1,
            'ask_rate': 0.0 <= self.ask_rate <= 1.0,
            'kept_per_batch': 0 <= self.kept_per_batch < self.batch_size,
            'ask_margin': self.ask_margin > 0.0,
            'ask_burst': self.ask_burst >= 1.0,
            'ask_budget': self.ask_budget >= 0,
            'decision_period_s': self.decision_period_s >= 0.0,
            'decision_switch_margin': self.decision_switch_margin >= 0.0,
            'credit_noise': 0.0 <= self.credit_noise < 0.5,
            'credit_refit_updates': self.credit_refit_updates >= 0,
            'credit_delay_bin_s': self.credit_delay_bin_s > 0.0,
            'credit_delay_prior': self.credit_delay_prior > 0.0,
            'learner_nice': 0 <= self.learner_nice <= 19,
            'pace_updates': self.pace_updates >= 0.0,
            'pace_max_s': self.pace_max_s >= 0.0,
            'wait_for_recorder_s': self.wait_for_recorder_s >= 0.0,
        }
        for name, ok in checks.items():
            if not ok:
                raise ValueError(f'{name} = {getattr(self, name)!r} is out of range')


def field_docs(cls=TamerConfig) -> Dict[str, str]:
    """Return {field name: the docstring written under it} of TamerConfig (or ``cls``)."""
    return _field_docs(cls)
