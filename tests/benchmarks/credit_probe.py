"""
Credit probe (issue 23): how exactly a verdict must be attributed for Room 1 to be learned.

The real game and the teacher, and in place of Deep TAMER's network a table H(cell, a) on the
agent's position (``--cell`` px squares, with the key and the skull's side): a learner with no
generalization to blame, which learns the route from stamped feedback in a few thousand steps
and runs 10,000 steps in about 4 s. The teacher's verdicts reach it:

- ``--teacher every_step``: on every step, on time, stamped (credit to the judged step);
- ``--teacher stamped_late``: human-like (a third of the steps, 0.3-1.5 s late, 10 % wrong) but
  each verdict credited to the step it judges; ``--jitter J`` spreads it evenly over the judged
  step and J steps either side (``--shift`` moves that span): attribution off by up to J steps;
- ``--teacher human_like``: the same verdicts plain, credited by Deep TAMER's window (the one
  ``--human-like`` sets) to the steps before their arrival, as in the graph; ``--marked P``
  credits a share P of them to the step they judge instead (a person who marks the moment).

Credit mechanisms over the window: ``--credit each`` (every step regressed toward h, Deep
TAMER's), ``mixture`` (the window's credit-weighted mean fitted to h), ``posterior`` (each
step's credit weighed by how likely H makes the verdict there); ``--replay N`` re-learns N
stored verdicts a step. Acting: greedy on H clipped to [-1, 1], near-ties (``--margin``) broken
at random; ``--keep`` keeps the last action while it is among them and not judged bad;
``--epsilon E`` acts at random on a share E of the steps (so that the actions a window mixes
are independent of each other).

Questions (tamer_node ``ask_rate``): ``--ask RATE`` asks the teacher about a step where the two
best actions are within ``--ask-margin``, at most RATE a step; the teacher answers stamped with
that step (``ActionTeacher.ask``) and does not also judge it late.

Run: ``.venv/bin/python tests/benchmarks/credit_probe.py --teacher human_like --seeds 100 101
[--jitter 1] [--credit mixture --replay 1] [--knob feedback_delay_max=0.6] [--ask 0.15]
[--out FILE]``.
"""

import argparse
import collections
import json
from pathlib import Path
import sys
import time

import numpy as np


def run_trial(seed: int, args) -> dict:
    from attention_bringup.plan import HUMAN_LIKE_WINDOW_S
    from attention_common.joy_actions import NUM_ACTIONS
    from attention_tasks.montezuma.env import EnvConfig, MontezumaEnv
    from attention_tasks.montezuma.expert import Phase
    from attention_tasks.montezuma.teaching import RoomOneKnowledge, SeenStep
    from feedback_node.human_like import HUMAN_LIKE_SETTING
    from feedback_node.judging import TeacherConfig
    from feedback_node.task_teacher import TaskStep, TaskTeacher
    from tamer_node.config import TamerConfig
    from tamer_node.credit import spans_from_stamps, window_credit
    from tamer_node.questions import Asker
    import torch

    knobs = vars(HUMAN_LIKE_SETTING) if args.teacher != 'every_step' else {}
    knobs = dict(knobs, **{k: float(v) for k, v in (kv.split('=', 1) for kv in args.knob)})
    teacher = TaskTeacher(RoomOneKnowledge(None), NUM_ACTIONS,
                          TeacherConfig(utterance_interval=-1.0, seed=seed, **knobs))
    asker = (Asker(args.ask, args.ask_margin, TamerConfig().ask_burst)  # tamer_node's
             if args.ask > 0.0 else None)
    window = (args.window_min, args.window_max) if args.window_max else HUMAN_LIKE_WINDOW_S
    rng = np.random.default_rng(seed)
    values = collections.defaultdict(lambda: np.zeros(NUM_ACTIONS))
    env = MontezumaEnv(EnvConfig(seed=seed))

    def cell(step):
        s = step.state
        side = 0
        if s.skull_x >= 0 and s.y < 160:  # the skull rolls on the floor, below y 160
            side = int(np.sign(s.skull_x - s.x) * min(abs(s.skull_x - s.x) // 16, 2))
        return (s.x // args.cell, s.y // args.cell, s.has_key, side)

    def see(step):
        s = step.state
        seen = SeenStep(s.x, s.y, s.has_key, s.pose, s.skull_x, step.action)
        return teacher.on_step(TaskStep(step.sim_time_ns, step.action, step.episode,
                                        step.agent_step, seen)).feedback

    def learn(items, h):
        if args.credit == 'posterior' and len(items) > 1:
            likely = [w * (0.1 + 0.8 * (1 + h * float(np.clip(values[c][a], -1, 1))) / 2)
                      for c, a, w in items]
            items = [(c, a, p / sum(likely)) for (c, a, _), p in zip(items, likely)]
        if args.credit == 'mixture':
            error = h - sum(w * values[c][a] for c, a, w in items)
            for c, a, w in items:
                values[c][a] += args.lr * w * error
        else:
            for c, a, w in items:
                values[c][a] += args.lr * w * (h - values[c][a])

    recent = collections.deque(maxlen=120)  # newest stamps: more than any window holds
    acted, verdicts, purity = {}, [], []

    def credit_of(judgement, newest):
        marked = judgement.marked or (args.marked > 0.0 and rng.random() < args.marked)
        if args.teacher == 'human_like' and not marked:
            return window_credit(spans_from_stamps(list(recent), newest), newest, *window)
        order = list(recent)
        if judgement.stamp_ns not in order:
            return {}
        at = order.index(judgement.stamp_ns) + args.shift
        span = range(max(at - args.jitter, 0), min(at + args.jitter + 1, len(order)))
        return {order[i]: 1.0 for i in span}

    def hear(feedback, newest):
        for judgement in feedback:
            credit = credit_of(judgement, newest)
            total = sum(credit.values())
            if total <= 0:
                continue
            purity.append(sum(w for stamp, w in credit.items()
                              if acted[stamp][1] == judgement.action) / total)
            merged = collections.defaultdict(float)
            for stamp, w in credit.items():
                merged[acted[stamp]] += w / total
            verdicts.append(([(c, a, w) for (c, a), w in merged.items()], judgement.h))
            learn(*verdicts[-1])
        for _ in range(args.replay if verdicts else 0):
            learn(*verdicts[int(rng.integers(len(verdicts)))])

    where, deaths = collections.Counter(), collections.Counter()
    route = [phase for phase in Phase if phase is not Phase.AIRBORNE]
    step = env.warm_up()
    see(step)
    first_key, lives_lost, furthest, last = None, 0, 0, None
    for t in range(1, args.steps + 1):
        here = cell(step)
        q = np.clip(values[here], -1.0, 1.0)
        best = q.max()
        if (args.keep and last is not None and q[last] >= best - args.margin
                and q[last] > -1.0 + args.margin):
            action = last
        else:
            action = int(rng.choice(np.flatnonzero(q >= best - args.margin)))
        if args.epsilon > 0.0 and rng.random() < args.epsilon:
            action = int(rng.integers(NUM_ACTIONS))
        last = action
        answers = []
        if asker is not None and asker.consider(torch.from_numpy(q)) is not None:
            answers = teacher.ask(step.sim_time_ns)  # answered when judged (marked)
        acted[step.sim_time_ns] = (here, action)
        recent.append(step.sim_time_ns)
        newest = step.sim_time_ns  # what a plain verdict is stamped with on arrival
        step = env.step(action)
        feedback, ended = answers + see(step), step
        if step.done:
            step = env.reset()
            feedback += see(step)
        hear(feedback, newest)
        if ended.state.has_key and first_key is None:
            first_key = t
        lives_lost += int(ended.life_lost)
        if args.trace and t > args.steps - 3000:
            place = (teacher.knowledge.expert.phase.name, ended.state.x // 8 * 8)
            where[place] += 1
            deaths[place] += int(ended.life_lost)
        if teacher.knowledge.expert.phase in route:
            furthest = max(furthest, route.index(teacher.knowledge.expert.phase))
    env.close()
    if args.trace:
        print('where', sorted(where.items(), key=lambda kv: -kv[1])[:12])
        print('deaths', sorted(deaths.items(), key=lambda kv: -kv[1])[:8])  # (where it fell)
    return {'seed': seed, 'first_key_step': first_key, 'lives_lost': lives_lost,
            'questions': teacher.counts['questions'], 'answered': teacher.counts['answered'],
            'furthest_stage': route[furthest].name,
            'label_purity': round(float(np.mean(purity)), 3) if purity else None,
            'agreement': round(teacher.counts['agreed'] / max(teacher.counts['judged'], 1), 3)}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    parser.add_argument('--seeds', type=int, nargs='+', default=list(range(100, 106)))
    parser.add_argument('--steps', type=int, default=10_000)
    parser.add_argument('--teacher', choices=('every_step', 'stamped_late', 'human_like'),
                        default='human_like')
    parser.add_argument('--knob', action='append', default=[], metavar='NAME=VALUE',
                        help="a human-like knob of the teacher (feedback_node's HumanLike)")
    parser.add_argument('--jitter', type=int, default=0, metavar='J',
                        help='stamped: credit the judged step and J steps either side')
    parser.add_argument('--shift', type=int, default=0, help='stamped: move that span')
    parser.add_argument('--marked', type=float, default=0.0, metavar='P',
                        help='human_like: a share P of the verdicts credited to the step they '
                             'judge (a person who marks the moment), the rest by the window')
    parser.add_argument('--window-min', type=float, default=0.0)
    parser.add_argument('--window-max', type=float, default=0.0,
                        help="human_like: the credit window (default --human-like's)")
    parser.add_argument('--credit', choices=('each', 'mixture', 'posterior'), default='each')
    parser.add_argument('--replay', type=int, default=0, metavar='N')
    parser.add_argument('--cell', type=int, default=4, help="the table's squares, px")
    parser.add_argument('--lr', type=float, default=0.3)
    parser.add_argument('--margin', type=float, default=0.1)
    parser.add_argument('--keep', action='store_true')
    parser.add_argument('--epsilon', type=float, default=0.0,
                        help='a share of the steps acted at random (decorrelates the actions '
                             'a window mixes)')
    parser.add_argument('--ask', type=float, default=0.0, metavar='RATE',
                        help='the learner asks about steps where its two best actions are '
                             'within --ask-margin, at most RATE a step; answered stamped')
    parser.add_argument('--ask-margin', type=float, default=0.5,
                        help='3: every step is unsure (questions at random steps)')
    parser.add_argument('--trace', action='store_true',
                        help='print where the agent was and died in the last 3,000 steps')
    parser.add_argument('--out', type=Path, default=None)
    args = parser.parse_args(argv)
    results = []
    for seed in args.seeds:
        started = time.monotonic()
        result = run_trial(seed, args)
        result['wall_s'] = round(time.monotonic() - started, 1)
        results.append(result)
        print(json.dumps(result), flush=True)
    keys = sorted(r['first_key_step'] for r in results if r['first_key_step'])
    purity = [r['label_purity'] for r in results if r['label_purity'] is not None]
    summary = {'key': len(keys), 'trials': len(results), 'first_keys': keys,
               'median_first_key': float(np.median(keys)) if keys else None,
               'label_purity': round(float(np.mean(purity)), 3) if purity else None}
    print(json.dumps(summary))
    if args.out:
        args.out.write_text(json.dumps({'argv': sys.argv[1:], 'summary': summary,
                                        'results': results}, indent=1) + '\n')
    return 0


if __name__ == '__main__':
    sys.exit(main())
