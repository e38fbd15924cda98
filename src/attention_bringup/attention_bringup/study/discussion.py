"""
The discussion of the report, generated from the numbers (pure).

Each paragraph takes one finding of the thesis's chapter 5, states what our trials show about
it, and says whether they agree. The wording follows fixed rules, so it cannot claim more than
the numbers: "significant" means Welch p < 0.05 (unadjusted; Holm-adjusted p is quoted too),
"better" at a position means fewer mean steps to it counting unreached trials as budget + 1.
"""

from typing import List, Mapping, Optional

from attention_bringup.experiment.markdown import num, percent
from attention_bringup.experiment.trials import POSITIONS
from attention_bringup.study.analysis import BASELINE, SETTLED_SHARE, TESTED_POSITIONS
from attention_tasks.montezuma.critical_positions import DEFAULT_RADIUS
from attention_tasks.montezuma.reward import RewardConfig

ALPHA = 0.05

MEASURE_TEXT = {
    'furthest_position': 'furthest position',
    'steps_to_1': 'steps to position 1',
    'steps_to_2': 'steps to position 2',
    'steps_to_3': 'steps to position 3',
}


def p_text(p: Optional[float], name: str = 'p') -> str:
    """Return 'p = 0.123', 'p < 0.001' or 'p n/a'."""
    if p is None:
        return f'{name} n/a'
    return f'{name} < 0.001' if p < 0.001 else f'{name} = {p:.3f}'


def _tests_of(analysis: Mapping, condition: str) -> List[dict]:
    return [t for t in analysis['tests'] if t['condition'] == condition]


def _significant(test: Mapping) -> bool:
    """Return p < 0.05, or both samples constant and different (then Welch is undefined)."""
    if test['p'] is None:
        return test['note'] == 'constant samples'
    return test['p'] < ALPHA


def _improves(test: Mapping) -> bool:
    """Return whether the condition did better than vanilla on this measure."""
    if test['measure'] == 'furthest_position':
        return test['difference'] > 0
    return test['difference'] < 0


def _describe_test(test: Mapping) -> str:
    better = 'better' if _improves(test) else 'worse'
    if test['difference'] == 0:
        better = 'no different'
    if test['p'] is None:
        detail = "the same value in every trial of each group, so Welch's test is undefined"
    else:
        holm = test.get('p_holm')
        survives = '' if holm is None or holm < ALPHA else ', not significant after Holm'
        detail = (f'{p_text(test["p"])}, {p_text(holm, "Holm p")}{survives}, '
                  f'g = {num(test["hedges_g"], 2)}')
    return (f'{MEASURE_TEXT[test["measure"]]}: {test["condition"]} '
            f'{num(test["mean_a"], 2)} vs vanilla {num(test["mean_b"], 2)} ({better}; '
            f'{detail})')


def _missing(analysis: Mapping, *conditions: str) -> List[str]:
    return [c for c in conditions
            if c not in analysis['conditions'] or analysis['conditions'][c]['usable'] < 2]


def _reach_text(analysis: Mapping, condition: str, position: int) -> str:
    reach = analysis['conditions'][condition]['steps_to'][str(position)]['reach']
    return f'{reach["k"]}/{reach["n"]}'


def no_difference_paragraph(analysis: Mapping, condition: str, thesis: str) -> str:
    """Discuss a condition the thesis found no better than vanilla (language, every step)."""
    missing = _missing(analysis, condition, BASELINE)
    if missing:
        return f'{thesis} Not assessed: too few finished trials of {", ".join(missing)}.'
    tests = _tests_of(analysis, condition)
    significant = [t for t in tests if _significant(t)]
    testable = [t for t in tests if t['p'] is not None]
    if not significant:
        smallest = min(testable, key=lambda t: t['p']) if testable else None
        detail = (f' (smallest {p_text(smallest["p"])}, {MEASURE_TEXT[smallest["measure"]]})'
                  if smallest else '')
        untestable = len(tests) - len(testable)
        extra = (f' {untestable} of the {len(tests)} tests were undefined (the same value in '
                 'every trial of both groups).') if untestable else ''
        return (f'{thesis} **Agrees**: no difference between {condition} and vanilla is '
                f'significant at 5 %{detail}.{extra}')
    better = [t for t in significant if _improves(t)]
    verdict = ('**Disagrees**' if better else '**Disagrees in part**: no improvement over '
               'vanilla, as in the thesis, but a significant difference')
    return (f'{thesis} {verdict}: significant at 5 % (unadjusted): '
            + '; '.join(_describe_test(t) for t in significant) + '.')


def blind_obs_paragraph(analysis: Mapping) -> str:
    thesis = ('*Thesis (Figure 5.3): replacing the observation with the blind-agent image '
              '(alpha 0) hardly affected performance, with a tighter confidence interval.*')
    missing = _missing(analysis, 'blind_obs', BASELINE)
    if missing:
        return f'{thesis} Not assessed: too few finished trials of {", ".join(missing)}.'
    tests = _tests_of(analysis, 'blind_obs')
    significant = [t for t in tests if _significant(t)]
    blind = analysis['conditions']['blind_obs']['furthest_position']
    base = analysis['conditions'][BASELINE]['furthest_position']
    if significant:
        first = ('**Disagrees** on "hardly affected": significant at 5 %: '
                 + '; '.join(_describe_test(t) for t in significant) + '.')
    else:
        first = ('**Agrees** that performance was hardly affected: no difference from vanilla '
                 'is significant at 5 %.')
    if blind['sd'] is None or base['sd'] is None:
        second = ''
    else:
        tighter = blind['sd'] < base['sd']
        spread = ('smaller' if tighter else 'the same' if blind['sd'] == base['sd']
                  else 'larger')
        second = (f' The spread of the furthest position over trials is {spread} for '
                  f'blind_obs (sd {blind["sd"]:.2f} vs vanilla {base["sd"]:.2f}), so on the '
                  f'tighter interval it {"agrees" if tighter else "does **not** agree"}.')
    return f'{thesis} {first}{second}'


def blind_saliency_paragraph(analysis: Mapping) -> str:
    thesis = ('*Thesis (Figure 5.4): blind-agent saliency every step (alpha 1e-4) did better '
              'than vanilla and than language every step at reaching positions 1 and 3, but '
              'not significantly.*')
    others = ('vanilla', 'language_every_step')
    missing = _missing(analysis, 'blind_saliency', *others)
    if missing:
        return f'{thesis} Not assessed: too few finished trials of {", ".join(missing)}.'
    sentences, agreements, partial = [], [], []
    tests = {t['measure']: t for t in _tests_of(analysis, 'blind_saliency')}
    for position in (1, 3):
        three = ('blind_saliency',) + others
        if not any(analysis['conditions'][c]['steps_to'][str(position)]['reach']['k']
                   for c in three):
            sentences.append(f'Position {position}: no trial of the three conditions reached '
                             'it, so there is nothing to compare.')
            continue
        means = {c: analysis['conditions'][c]['steps_to'][str(position)]['censored']['mean']
                 for c in ('blind_saliency',) + others}
        better_than = [c for c in others if means['blind_saliency'] < means[c]]
        test = tests.get(f'steps_to_{position}')
        significant = test is not None and _significant(test)
        reach = ', '.join(f'{c} {_reach_text(analysis, c, position)}'
                          for c in ('blind_saliency',) + others)
        sentences.append(
            f'Position {position}: reached by {reach} trials; mean steps (unreached = budget + '
            f'1) blind_saliency {means["blind_saliency"]:.0f}, vanilla {means["vanilla"]:.0f}, '
            f'language_every_step {means["language_every_step"]:.0f}; blind_saliency is '
            + (f'better than {" and ".join(better_than)}' if better_than else 'better than '
               'neither')
            + f' (vs vanilla {p_text(test["p"] if test else None)}).')
        agreements.append(len(better_than) == 2 and not significant)
        partial.append('vanilla' in better_than)
    if not agreements:
        verdict = '**Not assessable**: none of the three conditions reached position 1 or 3.'
    elif all(agreements):
        verdict = ('**Agrees**: better than both, and not significantly, wherever a position '
                   'was reached.')
    elif any(agreements) or any(partial):
        verdict = ("**Agrees in part**: the thesis's pattern (better than both, not "
                   'significantly) holds only where stated above.')
    else:
        verdict = ('**Does not agree**: blind_saliency is not better than vanilla where a '
                   'comparison was possible.')
    return f'{thesis} ' + ' '.join(sentences) + f' {verdict}'


def hidden_agent_paragraph(analysis: Mapping) -> str:
    thesis = ('*Thesis: with the agent hidden from the learner, no trial made any progress '
              'along the route.*')
    missing = _missing(analysis, 'hidden_agent')
    if missing:
        return f'{thesis} Not assessed: too few finished trials of hidden_agent.'
    summary = analysis['conditions']['hidden_agent']
    n = summary['usable']
    counts = {int(p): k for p, k in summary['furthest_counts'].items()}
    any_position = sum(k for p, k in counts.items() if p >= 0)
    beyond_zero = sum(k for p, k in counts.items() if p >= 1)
    text = (f'{thesis} Here {any_position} of {n} hidden_agent trials reached any critical '
            f'position and {beyond_zero} of {n} reached position 1 or beyond')
    if BASELINE in analysis['conditions'] and analysis['conditions'][BASELINE]['usable']:
        base = analysis['conditions'][BASELINE]
        base_beyond = sum(k for p, k in base['furthest_counts'].items() if int(p) >= 1)
        text += f' (vanilla: {base_beyond} of {base["usable"]} reached position 1 or beyond)'
    if any_position == 0:
        verdict = '**Agrees**.'
    elif beyond_zero == 0:
        verdict = ('**Agrees beyond position 0**: the agent got down the first ladder at most, '
                   'which the random warm-up and a greedy policy can do without seeing itself.')
    else:
        verdict = ('**Disagrees**: some hidden-agent trials made progress along the route.'
                   + _hidden_agent_manner(analysis))
    return f'{text}. {verdict}'


def _hidden_agent_manner(analysis: Mapping) -> str:
    """Compare lives lost and mean h with vanilla: how the hidden agent got where it got."""
    conditions = analysis['conditions']
    if BASELINE not in conditions or not conditions[BASELINE]['usable']:
        return ''
    hidden, base = conditions['hidden_agent'], conditions[BASELINE]
    lives = (hidden['lives_lost']['mean'], base['lives_lost']['mean'])
    feedback = (hidden.get('where', {}).get('feedback_mean', {}).get('mean'),
                base.get('where', {}).get('feedback_mean', {}).get('mean'))
    if None in lives:
        return ''
    text = (f' It got there differently: it lost {lives[0]:.0f} lives per trial on average '
            f'against {lives[1]:.0f} for vanilla')
    if None not in feedback:
        text += f', and its mean feedback was {feedback[0]:+.2f} against {feedback[1]:+.2f}'
    return (text + '. That points to passes made while jumping and falling rather than a route '
            f'it learned (a position counts whenever the agent passes within {DEFAULT_RADIUS:g} '
            'px of it, also mid-fall).')


def floor_effect_note(analysis: Mapping) -> str:
    """Say so when vanilla never reached the tested positions (tests then cannot tell)."""
    if BASELINE not in analysis['conditions'] or not analysis['conditions'][BASELINE]['usable']:
        return ''
    steps_to = analysis['conditions'][BASELINE]['steps_to']
    rates = [steps_to[str(p)]['reach']['k'] for p in TESTED_POSITIONS]
    if any(rates):
        return ''
    return ('Note: vanilla never reached positions 1 to 3 in any trial, so the tests of steps to '
            'those positions compare mostly unreached (censored) trials; a "no significant '
            'difference" there reflects a floor, not evidence that the conditions are equal.')


def _h_text(estimate: Mapping) -> str:
    return 'n/a' if estimate['mean'] is None else f'{estimate["mean"]:+.2f}'


def _beyond_zero(share: Mapping) -> float:
    """Share of steps near positions 1 to 5."""
    return sum(share[str(p)] for p in POSITIONS[1:])


def _split(where: Mapping) -> str:
    """Return 'near position 0 / near 1 to 5 / mean h' of a where-the-steps-go summary."""
    share = where['share']
    return (f'{percent(share["0"], 1)} / {percent(_beyond_zero(share), 1)} / '
            f'{_h_text(where["feedback_mean"])}')


_THESIS_REWARD = RewardConfig()
REWARD_RULE = (
    "Reward property: the thesis's synthetic reward (equations 4.1/4.2; feedback_node's "
    '`nearest` variant, used in every condition) gives h = +1 whenever the agent is within '
    f'{_THESIS_REWARD.alpha_threshold:g} px of *any* critical position, 0 up to '
    f'{_THESIS_REWARD.beta_threshold:g} px, and -1 farther from all of them or after it has '
    f'stood still for more than {_THESIS_REWARD.stationary_steps} steps; it does not pay for '
    'moving on along the route.')


def _settled_text(where: Mapping) -> str:
    settled = {int(p): k for p, k in where['settled'].items() if k}
    total, n = sum(settled.values()), where['n']
    share = f'{100 * SETTLED_SHARE:.0f} %'
    if not total:
        return (f'In none of them did the agent spend more than {share} of its steps near one '
                'critical position.')
    places = ', '.join(f'position {p} in {k}' for p, k in sorted(settled.items()))
    return (f'In {total} of {n} trials the agent spent more than {share} of its steps near '
            f'one critical position ({places}).')


def _variant_text(variants: List[str]) -> str:
    if variants == ['nearest']:
        return ("This is the thesis's reward reproduced as written (every trial recorded "
                '`reward_variant: nearest`); our `progress` variant in feedback_node, which '
                'counts only the furthest position reached so far in a life and the next one, '
                'so that an earlier position stops paying once the agent has moved on, was not '
                'used in this study.')
    listed = ', '.join(f'`{v}`' for v in variants) or 'none recorded'
    return f'Reward variants recorded by the trials: {listed}.'


def reward_property_paragraph(analysis: Mapping) -> str:
    """State how much of their steps the agents spent near which position, and why it matters."""
    where = analysis.get('where')
    if not where or not where['n']:
        return ''
    share = where['share']
    per_condition = '; '.join(f'{c} {_split(s["where"])}'
                              for c, s in analysis['conditions'].items() if s['where']['n'])
    consequence = (
        'Because the reward pays for standing near any critical position, a greedy learner of '
        'H(s, a) can settle near one it has reached, often an early one, and collect +1 there '
        'instead of moving on'
        + ('; the settled trials above show this.' if any(where['settled'].values())
           else '; in these trials no single position held most of the steps.'))
    return ' '.join([
        REWARD_RULE,
        f'Over the {where["n"]} full trials with step counts, the agent spent on average '
        f'{percent(share["0"], 1)} of its recorded steps near position 0, '
        f'{percent(_beyond_zero(share), 1)} near '
        f'positions 1 to 5 and {percent(share["-1"], 1)} near none; mean h was '
        f'{_h_text(where["feedback_mean"])}. Per condition (near 0 / near 1 to 5 / mean h): '
        f'{per_condition}.',
        _settled_text(where),
        consequence,
        'This limits what any condition can show about the speed of progress along the route: '
        'a learner that collects +1 where it stands is not rewarded for going further, whatever '
        'saliency it is given.',
        _variant_text(analysis.get('reward_variants', [])),
    ])


def updates_note(analysis: Mapping, tolerance: float = 0.2) -> str:
    """Say so when conditions got clearly different numbers of learner updates per step."""
    means = {c: s['updates_per_step']['mean'] for c, s in analysis['conditions'].items()
             if s['updates_per_step']['mean'] is not None}
    if len(means) < 2 or BASELINE not in means or means[BASELINE] <= 0:
        return ''
    base = means[BASELINE]
    differing = {c: m for c, m in means.items() if abs(m / base - 1.0) > tolerance}
    if not differing:
        return ''
    listed = ', '.join(f'{c} {m:.2f}' for c, m in means.items())
    return ('Confound: the learner took different numbers of gradient steps per agent step '
            f'in different conditions (mean updates per step: {listed}). Its minibatch updates '
            'are owed per second of simulation time, the same number per agent step in every '
            'condition (unless the learner falls more than 5 s of simulation time behind and '
            'drops owed ones), but its immediate updates are not: feedback that arrives while an '
            'update runs, or while its step waits for a saliency image, shares one immediate '
            'update, and the L2 term adds a second pass through the network, so a condition '
            'whose updates are slower or whose steps are faster gets fewer updates per step. '
            'Differences between conditions can come from this as well as from the saliency '
            'images.')


REPRODUCTION_NOTES = (
    "Where this reproduction is not the thesis's set-up (design facts, not results): the "
    'critical positions are our own (located with a scripted expert; the thesis does not '
    'publish its coordinates), and a position counts as reached whenever the agent passes '
    f'within {DEFAULT_RADIUS:g} px of it, also in mid-jump or mid-fall; the autoencoder was '
    'pretrained on Room 1 frames of our scripted expert with random detours, not on Atari '
    'Grand Challenge frames; each feedback is credited to exactly the step it judges. The seed '
    'fixes the emulator, the '
    "random warm-up, the trainer's random draws and the learner's initial weights and "
    'minibatch sampling. The learner owes minibatch updates at a fixed rate per second of '
    'simulation time (`update_clock: sim`, 6 per simulation second, 0.4 per agent step) besides '
    'an immediate update on each new feedback, but it runs on its own thread, asynchronously '
    'to acting: which version of H acts at a step depends on timing, and a labelled sample '
    'waits at most 0.5 wall seconds (`saliency_timeout_s`) for its saliency image before it is '
    'used without the L2 term (in blind_obs and hidden_agent the actor, too, waits at most that '
    'long for the image it acts on). So a trial is not bit-for-bit repeatable and depends '
    'somewhat on the load of the machine.')


def paragraphs(analysis: Mapping) -> List[str]:
    """Return the discussion, one paragraph per finding of the thesis, then the caveats."""
    found = [
        no_difference_paragraph(
            analysis, 'language', '*Thesis: language saliency every 10 s (alpha 1e-4) gave no '
            'significant difference from vanilla Deep TAMER.*'),
        blind_obs_paragraph(analysis),
        blind_saliency_paragraph(analysis),
        no_difference_paragraph(
            analysis, 'language_every_step', '*Thesis: language feedback every step did not '
            'improve on vanilla either (Figure 5.4).*'),
        hidden_agent_paragraph(analysis),
    ]
    notes = [reward_property_paragraph(analysis), floor_effect_note(analysis),
             updates_note(analysis), REPRODUCTION_NOTES]
    return found + [note for note in notes if note]
