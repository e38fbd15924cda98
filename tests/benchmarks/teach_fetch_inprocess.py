"""
Teaching Fetch in one process: the real MiniGrid room, Fetch's teacher, TamerAgent, no ROS.

The graph's loop one step after the other, as ``teach_doorkey_inprocess.py`` does for DoorKey,
with the saliency node's work done here: each frame is matched and the mission ("pick up the
<target>", said at every episode's start and in force all episode) rendered in ``--mode``
(mask: language_input; language: its first, blurred design) for a learner with ``input_image``
both. The teacher judges every action on time (stamped), or as a person would
(``--human-like``: plain, late, sparse, 10 % wrong; the credit window). As in the graph, a
verdict the teacher releases when it sees a step reaches the learner after that step's
observation did (so the learner stamps it with that step). ``--explore E``: the
learner's ``explore`` (a share E of its decisions at random, judged too): the greedy learner
otherwise never tries a pick-up in front of the target once pick-ups elsewhere taught it that
they are bad. ``--set ask_rate=R``: the learner asks about steps it is unsure of and the
teacher answers them stamped (``ActionTeacher.ask``), as over the ``question`` topic.
The settings are the words study's (8 x 8, four objects, 50 steps an episode, 1.5 updates a
step); the last ``--heldout`` steps are on held-out rooms with held-out target pairs.

Run: ``.venv/bin/python tests/benchmarks/teach_fetch_inprocess.py --seeds 900 901 --steps 10000
[--mode mask|language|off] [--explore 0.1] [--human-like [--press-times] [--marked 0.5]]
[--stamped-late]
[--set NAME=VALUE ...]
[--out results.json]``.
"""

import argparse
import json
from pathlib import Path
import sys
import tempfile
import time

from fetch_capacity import EPISODE_STEPS, Views
from teach_inprocess import give, parse_value


def run_trial(seed: int, steps: int, heldout: int, mode: str, explore: float, human_like: bool,
              overrides: dict, workdir: Path, stamped_late: bool = False,
              press_times: bool = False, marked: float = 0.0) -> dict:
    from attention_bringup.plan import human_like_window_s, PRESS_TIMES_CREDIT
    from attention_tasks.fetch.env import FetchEnv, FetchEnvConfig
    from attention_tasks.gridworld import STEP_S
    from feedback_node.human_like import HUMAN_LIKE_SETTING
    from attention_tasks.gridworld import NUM_ACTIONS, PICKUP
    from attention_tasks.fetch.world import mission
    from env_node.status import Counters, parse_status, status_values
    from feedback_node.judging import TeacherConfig
    from feedback_node.task_teacher import load_knowledge, TaskTeacher
    from saliency_node.saliency import SaliencyConfig
    from tamer_node.agent import share_the_cpu, TamerAgent
    from tamer_node.config import TamerConfig

    share_the_cpu()
    knobs = vars(HUMAN_LIKE_SETTING) if human_like or stamped_late else {}
    if marked:  # a person who pauses to judge a share of the verdicts
        knobs = dict(knobs, feedback_marked=marked)
    plain = human_like and not stamped_late  # plain verdicts: the credit window attributes them
    teacher = TaskTeacher(load_knowledge('fetch'), NUM_ACTIONS,
                          TeacherConfig(utterance_interval=-1.0, seed=seed, **knobs))
    config = {'task': 'fetch', 'seed': seed, 'alpha': 0.0, 'update_rate_hz': 1.5,
              'greedy_margin': 0.1, 'credit': 'window' if plain else 'step',
              'input_image': 'observation' if mode == 'off' else 'both', 'explore': explore}
    if plain:  # as attention_train --human-like sets it
        config['window_min_s'], config['window_max_s'] = human_like_window_s(STEP_S)
    if plain and press_times:  # as attention_train --human-like --press-times sets it
        config.update(PRESS_TIMES_CREDIT)
    config.update(overrides)
    run_dir = workdir / f'seed{seed}'
    agent = TamerAgent(TamerConfig(run_dir=str(run_dir), **config), run_dir)
    agent.start()
    env = FetchEnv(FetchEnvConfig(seed=seed, max_episode_steps=EPISODE_STEPS,
                                  heldout_after=steps - heldout))
    views = Views()
    rendering = SaliencyConfig(mode=mode if mode != 'off' else 'language')
    counters = Counters()

    def see(step):
        values = parse_status(status_values(step, counters, False))
        return teacher.on_step(teacher.see(step.sim_time_ns, values)).feedback

    def act(step) -> int:
        action = agent.on_observation(step.sim_time_ns, step.observation)
        if mode != 'off':
            frame = step.observation
            scene = views.maker.observe(frame)
            named = views.grounder.ground(mission(*step.state.target.split(' ', 1))).objects
            image, _ = views.maker.render(frame, scene, named, rendering)
            action = agent.on_saliency(step.sim_time_ns, image)
        return action

    episodes = []  # (held out, picked, solved, started at step)
    started = time.monotonic()
    step = env.reset()
    due = see(step)
    begun = 0
    for k in range(steps):
        action = act(step)
        due += [answer for stamp, _, _ in agent.acting.take_questions()  # (tamer ask_rate)
                for answer in teacher.ask(stamp)]  # else answered when judged (marked)
        give(agent, due, plain, press_times)  # heard after the step they were released on
        step = env.step(action)
        due = see(step)
        if step.done:
            episodes.append((bool(step.state.heldout), action == PICKUP and bool(
                step.state.carrying), bool(step.state.fetched), begun))
            step = env.reset()
            begun = k + 1
            due += see(step)  # the last action's verdict may fall due as the new room shows
    metrics = agent.metrics()
    agent.close()
    env.close()
    held = [e for e in episodes if e[0]]
    late = [e for e in episodes if not e[0] and e[3] >= steps - 2 * heldout]
    return {'seed': seed, 'episodes': len(episodes), 'heldout_episodes': len(held),
            'heldout_picked': sum(e[1] for e in held), 'heldout_solved': sum(e[2] for e in held),
            'late_episodes': len(late), 'late_picked': sum(e[1] for e in late),
            'late_solved': sum(e[2] for e in late),
            'training_picked': sum(e[1] for e in episodes if not e[0]),
            'updates_per_step': metrics['train/updates_per_step'],
            'questions': teacher.counts['questions'], 'answered': teacher.counts['answered'],
            'wall_s': round(time.monotonic() - started, 1)}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    parser.add_argument('--seeds', type=int, nargs='+', default=[900])
    parser.add_argument('--steps', type=int, default=10000)
    parser.add_argument('--heldout', type=int, default=2500,
                        help='the last steps, on held-out rooms and target pairs')
    parser.add_argument('--mode', choices=('mask', 'language', 'faded', 'off'), default='mask')
    parser.add_argument('--explore', type=float, default=0.0)
    parser.add_argument('--human-like', action='store_true',
                        help='the human-like teacher (a third of the steps, late, 10 %% wrong)')
    parser.add_argument('--stamped-late', action='store_true',
                        help="the human-like teacher's verdicts, but each stamped with the step "
                             'it judges (attribution exact; as sparse, late and wrong)')
    parser.add_argument('--press-times', action='store_true',
                        help='with --human-like: each late verdict carries the moment it was '
                             "given (source pressed), as the console's key presses do")
    parser.add_argument('--marked', type=float, default=0.0, metavar='P',
                        help="with --human-like: the teacher's feedback_marked, a share P of "
                             'its late verdicts given stamped with their step (a person who '
                             'pauses to judge)')
    parser.add_argument('--set', action='append', default=[], metavar='NAME=VALUE',
                        help='a TamerConfig field (repeatable)')
    parser.add_argument('--out', type=Path, default=None)
    args = parser.parse_args(argv)
    overrides = {item.split('=', 1)[0]: parse_value(item.split('=', 1)[1]) for item in args.set}
    results = []
    with tempfile.TemporaryDirectory() as workdir:
        for seed in args.seeds:
            result = run_trial(seed, args.steps, args.heldout, args.mode, args.explore,
                               args.human_like, overrides, Path(workdir), args.stamped_late,
                               args.press_times, args.marked)
            results.append(result)
            print(json.dumps(result), flush=True)
    held = sum(r['heldout_episodes'] for r in results)
    print(f'held-out solved {sum(r["heldout_solved"] for r in results)} of {held} '
          f'(picked {sum(r["heldout_picked"] for r in results)}); mode {args.mode}, explore '
          f'{args.explore}, overrides {overrides}')
    if args.out:
        args.out.write_text(json.dumps({'argv': sys.argv[1:], 'mode': args.mode,
                                        'explore': args.explore,
                                        'human_like': args.human_like,
                                        'stamped_late': args.stamped_late,
                                        'press_times': args.press_times,
                                        'marked': args.marked, 'overrides': overrides,
                                        'results': results}, indent=1) + '\n')
    return 0


if __name__ == '__main__':
    sys.exit(main())
