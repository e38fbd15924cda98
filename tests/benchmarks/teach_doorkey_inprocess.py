"""
Teaching DoorKey in one process: the real MiniGrid level, the teacher and TamerAgent, no ROS.

The graph's loop, one step after the other, as ``teach_inprocess.py`` does for Room 1: the agent
acts on the observation, the env steps, the teacher sees the step's status values (as it reads
env_status) and judges the previous action; feedback without delay goes in stamped, late
feedback plain (stamped by the agent on arrival with the newest step it saw: as in the graph, a
verdict released when the teacher sees a step arrives after that step's observation; credited
by its window), or with ``--press-times`` carrying the moment it was given (source 'pressed').
The settings are DoorKey's (8 x 8, four distractors, 100 steps an episode; the learner's
parameters from ``config/tasks/doorkey.yaml``: 1.5 minibatch updates per step, the verdict
memory); the last ``--heldout`` steps are on held-out layouts. ``--knob`` sets one human-like
knob of the teacher (``feedback_probability=0.33``: sparse alone), ``--stamped-late`` stamps
late verdicts with the step they judge (a diagnostic: attribution perfect). ``--set
ask_rate=R``: the learner asks about steps it is unsure of and the teacher answers them stamped
(``ActionTeacher.ask``), as over the ``question`` topic.

``--words mask``: the language_input condition (the teacher says the next sub-goal at the start of
each layout and every ``--utterance-interval`` s, the saliency node's mask of the named objects is
rendered here for every step, and H reads it beside the frame).

Run: ``.venv/bin/python tests/benchmarks/teach_doorkey_inprocess.py --seeds 100 101 --steps 10000
[--human-like] [--words mask] [--set hold_steps=1 ...] [--out results.json]``.
"""

import argparse
import json
from pathlib import Path
import sys
import tempfile
import time

from fetch_capacity import saliency_of
from teach_inprocess import learned_purity, parse_value


def run_trial(seed: int, steps: int, heldout: int, human_like: bool, overrides: dict,
              workdir: Path, knobs: dict = None, stamped_late: bool = False,
              press_times: bool = False, words: str = 'off',
              utterance_interval: float = 10.0) -> dict:
    from attention_bringup.graph import task_file
    from attention_bringup.params import load_params_file, node_params
    from attention_bringup.plan import human_like_window_s, PRESS_TIMES_CREDIT
    from attention_tasks.doorkey.env import DoorKeyEnv, DoorKeyEnvConfig
    from attention_tasks.gridworld import ACTION_NAMES, STEP_S
    from env_node.status import Counters, parse_status, status_values
    from feedback_node.human_like import HUMAN_LIKE_SETTING
    from feedback_node.judging import TeacherConfig
    from feedback_node.task_teacher import load_knowledge, TaskTeacher
    from tamer_node.agent import share_the_cpu, TamerAgent
    from tamer_node.config import TamerConfig

    share_the_cpu()
    knobs = dict(vars(HUMAN_LIKE_SETTING) if human_like else {}, **(knobs or {}))
    teacher = TaskTeacher(load_knowledge('doorkey'), 6, TeacherConfig(
        utterance_interval=utterance_interval if words != 'off' else -1.0, seed=seed, **knobs))
    task_params = node_params(load_params_file(task_file('doorkey')), 'tamer_node')
    task_params.pop('task', None)
    config = {'task': 'doorkey', 'seed': seed, 'alpha': 0.0, 'greedy_margin': 0.1,
              **task_params}  # the task file's learner (update rate, memory)
    late = teacher.config.delayed and not stamped_late
    config['credit'] = 'window' if late else 'step'
    if late:
        config['window_min_s'], config['window_max_s'] = human_like_window_s(STEP_S)
    if late and press_times:  # as attention_train --human-like --press-times sets it
        config.update(PRESS_TIMES_CREDIT)
    if words != 'off':  # as the language_input condition sets it
        config.update(input_image='both', alpha=0.0)
    config.update(overrides)
    run_dir = workdir / f'seed{seed}'
    agent = TamerAgent(TamerConfig(run_dir=str(run_dir), **config), run_dir)
    agent.start()
    env = DoorKeyEnv(DoorKeyEnvConfig(seed=seed, size=8, distractors=4, max_episode_steps=100,
                                      heldout_after=steps - heldout))
    counters = Counters()

    saliency = Saliency(words) if words != 'off' else None

    def see(step):
        values = parse_status(status_values(step, counters, False))
        said = teacher.on_step(teacher.see(step.sim_time_ns, values))
        if said.utterance is not None and saliency is not None:
            saliency.hear(said.utterance.text)
        return said.feedback

    episodes = []  # (held out, solved, sub-goals)
    acted = {}  # stamp -> the agent's action
    late_actions = [0] * 6  # the actions of the held-out part
    judged_plain = []  # per late feedback, in the order sent (its seq - 1): (stamp, action)
    started = time.monotonic()
    step = env.reset()
    due = see(step)
    for _ in range(steps):
        action = agent.on_observation(step.sim_time_ns, step.observation)
        if saliency is not None:  # the step's saliency image: H acts on both
            action = agent.on_saliency(step.sim_time_ns, saliency.image(step.observation))
        acted[step.sim_time_ns] = action
        if len(acted) > steps - heldout:
            late_actions[action] += 1
        due += [answer for stamp, _, _ in agent.acting.take_questions()  # (tamer ask_rate)
                for answer in teacher.ask(stamp)]  # else answered when judged (marked)
        for judgement in due:  # released as this step showed, heard after it (the graph)
            if judgement.marked:  # an answer to a question: given with its step
                agent.on_feedback(judgement.h, 'stamped', judgement.stamp_ns)
            elif late and press_times:  # when it was given, not the step it judges
                agent.on_feedback(judgement.h, 'pressed', judgement.pressed_ns)
                judged_plain.append((judgement.stamp_ns, judgement.action))
            elif late:
                agent.on_feedback(judgement.h, 'plain')
                judged_plain.append((judgement.stamp_ns, judgement.action))
            else:
                agent.on_feedback(judgement.h, 'stamped', judgement.stamp_ns)
        step = env.step(action)
        due = see(step)
        if step.done:
            values = parse_status(status_values(step, counters, False))
            episodes.append((bool(step.state.heldout), bool(values.get('at_goal')),
                             int(values.get('subgoals', 0))))
            step = env.reset()
            due += see(step)  # due now, late: sent as the new layout shows
    metrics = agent.metrics()
    agent.close()
    learned = learned_purity(agent.buffer, judged_plain, acted)
    env.close()
    held = [e for e in episodes if e[0]]
    return {'seed': seed, 'episodes': len(episodes), 'heldout_episodes': len(held),
            'heldout_solved': sum(e[1] for e in held),
            'heldout_subgoals': sum(e[2] for e in held) / max(len(held), 1),
            'training_solved': sum(e[1] for e in episodes if not e[0]),
            'agreement': teacher.counts['agreed'] / max(teacher.counts['judged'], 1),
            'updates_per_step': metrics['train/updates_per_step'],
            'questions': teacher.counts['questions'], 'answered': teacher.counts['answered'],
            'heldout_actions': dict(zip(ACTION_NAMES, late_actions)),
            'wall_s': time.monotonic() - started, **learned}


class Saliency:
    """The saliency node's work for DoorKey in this process: the latest words, grounded."""

    def __init__(self, mode: str):
        from attention_tasks.doorkey.task import TASK
        from saliency_node.saliency import SaliencyConfig
        self.maker, self.grounder = saliency_of(TASK.manifest)
        self.rendering = SaliencyConfig(mode=mode)
        self.named = []

    def hear(self, text: str) -> None:
        self.named = self.grounder.ground(text).objects

    def image(self, frame):
        return self.maker.render(frame, self.maker.observe(frame), self.named, self.rendering)[0]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    parser.add_argument('--seeds', type=int, nargs='+', default=[100])
    parser.add_argument('--steps', type=int, default=10000)
    parser.add_argument('--heldout', type=int, default=2500,
                        help='the last steps, on held-out layouts')
    parser.add_argument('--human-like', action='store_true')
    parser.add_argument('--stamped-late', action='store_true',
                        help="late feedback that carries its step's stamp (a diagnostic)")
    parser.add_argument('--press-times', action='store_true',
                        help='late feedback carries the moment it was given (source pressed)')
    parser.add_argument('--knob', action='append', default=[], metavar='NAME=VALUE',
                        help='a human-like knob of the teacher (repeatable)')
    parser.add_argument('--set', action='append', default=[], metavar='NAME=VALUE',
                        help='a TamerConfig field (repeatable)')
    parser.add_argument('--words', choices=('off', 'mask', 'language'), default='off',
                        help='mask: the language_input condition (H reads the mask of the '
                             'grounded sub-goal beside the frame); language: its first design, '
                             'the blurred saliency image')
    parser.add_argument('--utterance-interval', type=float, default=10.0,
                        help='with --words: seconds of simulation time between sentences '
                             '(0: every step)')
    parser.add_argument('--what', default='')
    parser.add_argument('--out', type=Path, default=None)
    args = parser.parse_args(argv)
    overrides = {item.split('=', 1)[0]: parse_value(item.split('=', 1)[1]) for item in args.set}
    knobs = {item.split('=', 1)[0]: parse_value(item.split('=', 1)[1]) for item in args.knob}
    results = []
    with tempfile.TemporaryDirectory() as workdir:
        for seed in args.seeds:
            result = run_trial(seed, args.steps, args.heldout, args.human_like, overrides,
                               Path(workdir), knobs, args.stamped_late,
                               args.press_times, args.words, args.utterance_interval)
            results.append(result)
            print(json.dumps(result), flush=True)
    held = sum(r['heldout_episodes'] for r in results)
    solved = sum(r['heldout_solved'] for r in results)
    print(f'held-out solved {solved} of {held}; overrides {overrides}')
    if args.out:
        args.out.write_text(json.dumps({'what': args.what, 'argv': sys.argv[1:],
                                        'overrides': overrides, 'knobs': knobs,
                                        'stamped_late': args.stamped_late,
                                        'press_times': args.press_times,
                                        'human_like': args.human_like,
                                        'words': args.words,
                                        'utterance_interval': args.utterance_interval,
                                        'results': results}, indent=1))
    return 0


if __name__ == '__main__':
    sys.exit(main())
