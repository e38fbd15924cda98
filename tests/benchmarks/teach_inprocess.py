"""
Teaching in one process: the real game, the teacher and TamerAgent, without ROS.

The loop is the graph's, one step after the other: the env steps, the teacher sees the step (the
action applied, the state) and judges the previous one, the agent acts on the observation.
Feedback the teacher gives without delay goes in stamped (``credit`` step); delayed feedback
goes in plain, stamped by the agent on arrival (``credit`` window), as over topics. The learner
runs on its own thread, as in tamer_node; ``--pace`` caps steps per second so that it gets the
updates per step it gets in the graph (about 100 steps/s there).

For late (plain) feedback it also measures the credit window's *label purity*: the share of
each feedback's credit that lands on steps where the agent did what the teacher judged, and the
share on the judged step itself; and the same of what the learner holds at the end
(``learned_purity``: after credit by prediction or decisions). ``furthest_stage`` is the furthest
stage of the expert's route the agent was in. ``--knob`` changes a human-like knob of the
teacher (``--knob feedback_delay_max=0 --knob feedback_delay_min=0``: on time and stamped).
``--marked P`` hands a share P of the late verdicts over stamped with the step they judge, as a
person who pauses to judge in the trainer console (feedback_node's ``feedback_marked``). With
``--set ask_rate=R`` the agent asks about steps it is unsure of and the teacher answers them
stamped (``ActionTeacher.ask``), as over the ``question`` topic.

Used to find what stops Deep TAMER from learning the route (``docs/teaching.md``, the
ablation); the targets themselves are measured through the graph (``attention_teaching``).

Run: ``.venv/bin/python tests/benchmarks/teach_inprocess.py --seeds 100 101 --steps 10000
[--human-like [--marked 0.5]] [--set learning_rate=1e-3 ...] [--out results.json]``.
"""

import argparse
import collections
import json
from pathlib import Path
import sys
import tempfile
import time

import numpy as np


def parse_value(text: str):
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return {'true': True, 'false': False}.get(text, text)


def give(agent, judgements, human_like: bool, press_times: bool = False) -> None:
    """
    Hand the teacher's judgements to the agent: stamped on time, or plain (late, human-like).

    ``press_times``: late ones carry the moment they were given (source 'pressed'), as the
    console's key presses and ``attention_train --press-times`` do. A late one the teacher
    marked (``feedback_marked``) goes stamped, as feedback_node sends it.
    """
    for judgement in judgements:
        if human_like and judgement.marked:  # given with its step (the teacher's feedback_marked)
            agent.on_feedback(judgement.h, 'stamped', judgement.stamp_ns)
        elif human_like and press_times:
            agent.on_feedback(judgement.h, 'pressed', judgement.pressed_ns)
        elif human_like:
            agent.on_feedback(judgement.h, 'plain')
        else:
            agent.on_feedback(judgement.h, 'stamped', judgement.stamp_ns)


def run_trial(seed: int, steps: int, human_like: bool, overrides: dict, pace: float,
              workdir: Path, table: str = '', knobs: dict = None,
              stamped_late: bool = False, marked: float = 0.0) -> dict:
    from attention_common.joy_actions import NUM_ACTIONS
    from attention_tasks.montezuma.action_effects import EffectTable, STRICT
    from attention_tasks.montezuma.env import EnvConfig, MontezumaEnv
    from attention_tasks.montezuma.teaching import RoomOneKnowledge, SeenStep
    from feedback_node.human_like import HUMAN_LIKE_SETTING
    from feedback_node.judging import TeacherConfig
    from feedback_node.task_teacher import TaskStep, TaskTeacher
    from tamer_node.agent import share_the_cpu, TamerAgent
    from tamer_node.config import TamerConfig

    share_the_cpu()
    knobs = dict(vars(HUMAN_LIKE_SETTING) if human_like else {}, **(knobs or {}))
    if table == 'strict':  # +1 only for the expert's very action, never silent
        effects = EffectTable({'': STRICT}, {}, ())
    else:
        effects = EffectTable.load(Path(table)) if table else None
    teacher = TaskTeacher(RoomOneKnowledge(effects), NUM_ACTIONS,
                          TeacherConfig(utterance_interval=-1.0, seed=seed, **knobs))
    from attention_bringup.plan import HUMAN_LIKE_WINDOW_S
    late = teacher.config.delayed and not stamped_late
    config = {'seed': seed, 'alpha': 0.0, 'credit': 'window' if late else 'step'}
    if late:  # as attention_train --human-like sets it
        config['window_min_s'], config['window_max_s'] = HUMAN_LIKE_WINDOW_S
    config.update(overrides)
    run_dir = workdir / f'seed{seed}'
    agent = TamerAgent(TamerConfig(run_dir=str(run_dir), **config), run_dir)
    agent.start()
    env = MontezumaEnv(EnvConfig(seed=seed))
    stamped = not late  # --stamped-late: late feedback that carries its step's stamp
    marking = np.random.default_rng(seed + 1)  # --marked: which late verdicts carry it

    def see(step):
        s = step.state
        out = teacher.on_step(TaskStep(step.sim_time_ns, step.action, step.episode,
                                       step.agent_step,
                                       SeenStep(s.x, s.y, s.has_key, s.pose, s.skull_x,
                                                step.action)))
        return out.feedback

    from tamer_node.credit import spans_from_stamps, window_credit
    acted = {}       # stamp -> the agent's action
    recent = collections.deque(maxlen=120)  # the newest stamps, enough for any credit window
    purity = []      # per late feedback: (credit on steps with the judged action, on the step)
    judged_plain = []  # per feedback sent, in order (its seq - 1): (stamp, action judged)
    credit_window = (agent.config.window_min_s, agent.config.window_max_s)

    def credit_check(judgement, now_ns) -> None:
        credit = window_credit(spans_from_stamps(list(recent), now_ns), now_ns, *credit_window)
        total = sum(credit.values())
        if total > 0:
            same = sum(w for s, w in credit.items() if acted[s] == judgement.action)
            purity.append((same / total, credit.get(judgement.stamp_ns, 0.0) / total))

    from attention_tasks.montezuma.expert import Phase
    route = [phase for phase in Phase if phase is not Phase.AIRBORNE]
    furthest = 0  # the furthest stage of the route the expert saw the agent in
    first_key, keys, lives_lost, had_key = None, 0, 0, False
    curve = []
    window = [0, 0]
    step = env.warm_up()
    see(step)
    started = time.monotonic()
    for t in range(1, steps + 1):
        action = agent.on_observation(step.sim_time_ns, step.observation)
        answers = [answer for stamp, _, _ in agent.acting.take_questions()  # (tamer ask_rate)
                   for answer in teacher.ask(stamp)]  # else answered when judged
        acted[step.sim_time_ns] = action
        recent.append(step.sim_time_ns)
        newest = step.sim_time_ns  # what the agent stamps plain feedback with (its newest)
        step = env.step(action)
        feedback = answers + see(step)
        ended = step
        if step.done:  # the teacher's due feedback at the reset goes out too, as in the graph
            step = env.reset()
            feedback += see(step)
        for judgement in feedback:
            if stamped or judgement.marked or (marked and marking.random() < marked):
                agent.on_feedback(judgement.h, 'stamped', judgement.stamp_ns)
                judged_plain.append((judgement.stamp_ns, judgement.action))  # (its seq)
            else:
                agent.on_feedback(judgement.h, 'plain')
                credit_check(judgement, newest)
                judged_plain.append((judgement.stamp_ns, judgement.action))
        if ended.state.has_key and not had_key:
            keys += 1
            first_key = first_key or t
        had_key = ended.state.has_key and not ended.done
        lives_lost += int(ended.life_lost)
        if teacher.knowledge.expert.phase in route:
            furthest = max(furthest, route.index(teacher.knowledge.expert.phase))
        counts = teacher.counts
        if t % 500 == 0:
            judged, agreed = counts['judged'] - window[0], counts['agreed'] - window[1]
            window = [counts['judged'], counts['agreed']]
            curve.append({'step': t, 'agreement': agreed / max(judged, 1), 'keys': keys,
                          'x': step.state.x, 'y': step.state.y,
                          'phase': teacher.knowledge.expert.phase.name})
        if pace > 0:
            delay = started + t / pace - time.monotonic()
            if delay > 0:
                time.sleep(delay)
    metrics = agent.metrics()
    agent.close()
    learned = learned_purity(agent.buffer, judged_plain, acted)
    env.close()
    n = max(len(purity), 1)
    return {'seed': seed, 'first_key_step': first_key, 'keys': keys, 'lives_lost': lives_lost,
            'furthest_stage': furthest, 'furthest_stage_name': route[furthest].name,
            'agreement': teacher.counts['agreed'] / max(teacher.counts['judged'], 1),
            'teacher': teacher.counts, 'updates': metrics['train/updates'],
            'updates_per_step': metrics['train/updates_per_step'],
            'skipped_updates': metrics['train/skipped_updates'],
            'wall_s': time.monotonic() - started, 'curve': curve,
            'label_purity': sum(p for p, _ in purity) / n if purity else None,
            'credit_on_judged_step': sum(q for _, q in purity) / n if purity else None,
            **learned}


def learned_purity(buffer, judged_plain, acted) -> dict:
    """
    Return the label purity of what the learner holds at the end.

    The share of each late feedback's weight in the buffer (after any credit by prediction) on
    steps that did the judged action, and on the judged step (the newest 10,000 samples).
    """
    if not judged_plain:
        return {}
    columns = buffer.columns
    size = len(buffer)
    same = collections.defaultdict(float)
    on_step = collections.defaultdict(float)
    total = collections.defaultdict(float)
    for seq, stamp, weight in zip(columns['seqs'][:size], columns['stamps'][:size],
                                  columns['weights'][:size]):
        if not 0 < seq <= len(judged_plain):
            continue
        judged_stamp, judged_action = judged_plain[seq - 1]
        total[seq] += weight
        same[seq] += weight * (acted.get(int(stamp)) == judged_action)
        on_step[seq] += weight * (int(stamp) == judged_stamp)
    seqs = [q for q in total if total[q] > 0]
    return {'learned_purity': float(sum(same[q] / total[q] for q in seqs) / max(len(seqs), 1)),
            'learned_on_judged_step': float(
                sum(on_step[q] / total[q] for q in seqs) / max(len(seqs), 1))}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    parser.add_argument('--seeds', type=int, nargs='+', default=[100])
    parser.add_argument('--steps', type=int, default=10000)
    parser.add_argument('--human-like', action='store_true')
    parser.add_argument('--knob', action='append', default=[], metavar='NAME=VALUE',
                        help='a human-like knob of the teacher over --human-like, e.g. '
                             'feedback_delay_max=0 (no delay: stamped feedback)')
    parser.add_argument('--set', action='append', default=[], metavar='NAME=VALUE',
                        help='a TamerConfig field (repeatable)')
    parser.add_argument('--pace', type=float, default=100.0, help='steps/s cap (0: none)')
    parser.add_argument('--table', default='',
                        help="the teacher's action table: a JSON file from teacher_effects, "
                             "'strict' (every action its own class: +1 only for the expert's "
                             'very action), default the shipped one')
    parser.add_argument('--skull-gone-steps', type=int, default=None,
                        help="the expert's rule for a vanished skull (a huge value: no rule)")
    parser.add_argument('--stamped-late', action='store_true',
                        help='late feedback goes in stamped with the step it judges (step '
                             'credit): attribution perfect, the delay kept (a diagnostic)')
    parser.add_argument('--marked', type=float, default=0.0, metavar='P',
                        help='with --human-like: a share P of the verdicts stamped with the '
                             'step they judge (a person judging a paused frame), the rest plain')
    parser.add_argument('--what', default='', help='a line describing the variant (--out)')
    parser.add_argument('--out', type=Path, default=None)
    args = parser.parse_args(argv)
    overrides = {item.split('=', 1)[0]: parse_value(item.split('=', 1)[1])
                 for item in args.set}
    if args.skull_gone_steps is not None:
        from attention_tasks.montezuma import expert
        expert.SKULL_GONE_STEPS = args.skull_gone_steps
    results = []
    with tempfile.TemporaryDirectory() as workdir:
        for seed in args.seeds:
            result = run_trial(seed, args.steps, args.human_like, overrides, args.pace,
                               Path(workdir), args.table,
                               {k.split('=', 1)[0]: float(k.split('=', 1)[1]) for k in args.knob},
                               args.stamped_late, args.marked)
            results.append(result)
            print(json.dumps({k: v for k, v in result.items() if k != 'curve'}), flush=True)
            print('  agreement per 500 steps:',
                  ' '.join(f'{c["agreement"]:.2f}' for c in result['curve']), flush=True)
            print('  where:', ' '.join(f'({c["x"]},{c["y"]},{c["phase"][:8]})'
                                       for c in result['curve']), flush=True)
    keyed = [r for r in results if r['first_key_step']]
    print(f'key in {len(keyed)} of {len(results)}; first keys '
          f'{sorted(r["first_key_step"] for r in keyed)}; overrides {overrides}')
    if args.out:
        args.out.write_text(json.dumps({
            'what': args.what, 'argv': sys.argv[1:], 'overrides': overrides,
            'human_like': args.human_like, 'table': args.table or 'shipped',
            'results': results}, indent=1))
    return 0


if __name__ == '__main__':
    sys.exit(main())
