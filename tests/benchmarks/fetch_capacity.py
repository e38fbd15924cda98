"""
Can H represent Fetch at all? H fitted offline on every action's judgement, then acted greedily.

The greedy learners of the words study stayed below chance (docs/results_words_greedy.md).
This asks whether the learner's model could do better with perfect, dense supervision: states
visited by the expert (with ``--epsilon`` random actions for coverage) on training rooms; every
action of every state labelled as Fetch's teacher would judge it (+1 as good as the expert's,
else -1); H's head fitted on them with the frozen DoorKey encoder, as tamer_node does; then
greedy episodes on held-out rooms with training target pairs and with held-out pairs. Each
input is one design of what H reads besides the frame:

- ``observation``: the frame alone (vanilla, the thesis's language: at acting time);
- ``blur``: the frame and the saliency image (language_input as built: radius-3 blur outside
  the named object and the agent);
- ``faded``: the frame and the saliency image in faded mode (outside at 30 % brightness);
- ``mask``: the frame and the saliency mask drawn as an image (white on black);
- ``text``: the frame and the mission's bag of words through FiLM (text_film).

Run: ``.venv/bin/python tests/benchmarks/fetch_capacity.py --states 20000 --episodes 200
[--inputs observation blur ...] [--out results.json]``. Prints one line per input.
"""

import argparse
import json
from pathlib import Path
import sys
import time

import numpy as np

INPUTS = ('observation', 'blur', 'faded', 'mask', 'text')
EPISODE_STEPS = 50
"""As the words study's episodes."""


def saliency_of(manifest_path):
    """Return the saliency node's maker and grounder for a task's template manifest."""
    from saliency_node.grounding import Grounder
    from saliency_node.manifest import load_backdrops, load_manifest, load_template_images
    from saliency_node.matching import build_objects, method_from_name
    from saliency_node.saliency import SaliencyMaker
    manifest = load_manifest(manifest_path)
    maker = SaliencyMaker(build_objects(manifest, load_template_images(manifest),
                                        load_backdrops(manifest)),
                          manifest.search_region, manifest.background,
                          method_from_name('TM_CCORR_NORMED'))
    return maker, Grounder.from_manifest(manifest)


class Views:
    """The images each input reads of a step (frame, and the grounded mission's rendering)."""

    def __init__(self):
        from attention_tasks.fetch.task import TASK
        from saliency_node.saliency import SaliencyConfig
        self.maker, self.grounder = saliency_of(TASK.manifest)
        self.blur = SaliencyConfig(mode='language')
        self.faded = SaliencyConfig(mode='faded')

    def images(self, step, kinds) -> dict:
        """Return {input: its second image} of a step for ``kinds`` (the scene matched once)."""
        from attention_tasks.fetch.world import mission
        wanted = set(kinds) & {'blur', 'faded', 'mask'}
        if not wanted:
            return {}
        frame = step.observation
        scene = self.maker.observe(frame)
        color, _, kind = step.state.target.partition(' ')
        named = self.grounder.ground(mission(color, kind)).objects
        images = {}
        blurred, mask = self.maker.render(frame, scene, named, self.blur)
        images['blur'] = blurred
        images['mask'] = np.repeat((mask * 255).astype(np.uint8)[:, :, None], 3, axis=2)
        if 'faded' in wanted:
            images['faded'] = self.maker.render(frame, scene, named, self.faded)[0]
        return images


class Featurizer:
    """The frozen encoder's standardized features of images, as tamer_node computes them."""

    def __init__(self):
        import torch
        from tamer_node.agent import encoder_for_task
        from tamer_node.model import load_encoder
        self.torch = torch
        self.encoder = load_encoder(encoder_for_task('fetch'))
        self.encoder.eval()

    def __call__(self, images):
        from tamer_node.model import preprocess, to_input
        batch = np.stack([preprocess(image, image.shape[:2]) for image in images])
        with self.torch.no_grad():
            return self.encoder.standardized(to_input(batch))


def state_vector(kind: str, step, views: dict, featurize, text_size: int):
    """Return H's input of a step for ``kind`` (features, then the bag of words for text)."""
    import torch
    from attention_tasks.fetch.world import mission
    from tamer_node.words import bag_of_words
    frame = featurize([step.observation])[0]
    if kind == 'observation':
        return frame
    if kind == 'text':
        color, _, target_kind = step.state.target.partition(' ')
        return torch.cat([frame, bag_of_words(mission(color, target_kind), text_size)])
    return torch.cat([frame, featurize([views[kind]])[0]])


def labels(state) -> np.ndarray:
    """Every action's judgement by Fetch's teacher: +1 as good as the expert's, else -1."""
    from attention_tasks.fetch.teaching import KNOWLEDGE
    from attention_tasks.gridworld import NUM_ACTIONS
    expert = KNOWLEDGE.expert_action(state)
    if expert is None:
        return None
    return np.array([1.0 if KNOWLEDGE.as_good(state, a, expert) else -1.0
                     for a in range(NUM_ACTIONS)], np.float32)


def collect(seed: int, count: int, epsilon: float, kinds, views, featurize, text_size: int):
    """Return {kind: (N, size) states}, (N, 6) labels from expert-led training episodes."""
    import torch
    from attention_tasks.fetch.env import FetchEnv, FetchEnvConfig
    from attention_tasks.fetch.expert import next_action
    rng = np.random.default_rng(seed)
    env = FetchEnv(FetchEnvConfig(seed=seed, max_episode_steps=EPISODE_STEPS))
    states = {kind: [] for kind in kinds}
    judged = []
    step = env.reset()
    while len(judged) < count:
        label = labels(step.state)
        if label is not None:
            images = views.images(step, kinds)
            for kind in kinds:
                states[kind].append(state_vector(kind, step, images, featurize, text_size))
            judged.append(label)
        expert = next_action(step.state)
        action = (int(rng.integers(6)) if expert is None or rng.random() < epsilon
                  else expert)
        step = env.step(action)
        if step.done:
            step = env.reset()
    env.close()
    return {k: torch.stack(v) for k, v in states.items()}, torch.as_tensor(np.stack(judged))


def fit(kind: str, states, judged, epochs: int, text_size: int, seed: int):
    """Fit H's head (tamer_node's HModel, frozen encoder) to every action's judgement."""
    import torch
    from tamer_node.config import TamerConfig
    from tamer_node.model import HModel
    torch.manual_seed(seed)
    streams = 2 if kind in ('blur', 'faded', 'mask') else 1
    model = HModel(TamerConfig().head_hidden, num_actions=6, streams=streams,
                   text_size=text_size if kind == 'text' else 0)
    optimizer = torch.optim.Adam(model.trainable_parameters(), lr=1e-3)
    for _ in range(epochs):
        order = torch.randperm(len(states))
        for start in range(0, len(order), 64):
            batch = order[start:start + 64]
            loss = torch.nn.functional.mse_loss(model.from_features(states[batch]),
                                                judged[batch])
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
    with torch.no_grad():
        predicted = model.from_features(states)
        agree = (predicted.argmax(1)[:, None] == torch.arange(6)).float()
        train_good = float((agree * (judged > 0)).sum(1).mean())
    return model, train_good


def evaluate(kind: str, model, seed: int, episodes: int, heldout_pairs: bool, views,
             featurize, text_size: int) -> dict:
    """Greedy episodes on held-out rooms: success, pick-ups, the target's share of them."""
    import torch
    from attention_tasks.fetch.env import FetchEnv, FetchEnvConfig
    from attention_tasks.gridworld import PICKUP
    # Rooms never trained on (another seed's layouts); held-out pairs: past heldout_after.
    env = FetchEnv(FetchEnvConfig(seed=seed, max_episode_steps=EPISODE_STEPS,
                                  heldout_after=1 if heldout_pairs else 0))
    env.reset()
    env.step(0)
    solved = picked = 0
    for _ in range(episodes):
        step = env.reset()
        assert step.state.heldout == heldout_pairs
        while not step.done:
            x = state_vector(kind, step, views.images(step, [kind]), featurize, text_size)
            with torch.no_grad():
                action = int(model.from_features(x[None])[0].argmax())
            step = env.step(action)
            if action == PICKUP and step.state.carrying:
                picked += 1
                solved += int(step.state.fetched)
    env.close()
    return {'success': solved / episodes, 'picked': picked / episodes,
            'target_share': solved / picked if picked else 0.0}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--states', type=int, default=20000)
    parser.add_argument('--epsilon', type=float, default=0.3)
    parser.add_argument('--epochs', type=int, default=20)
    parser.add_argument('--episodes', type=int, default=100)
    parser.add_argument('--seed', type=int, default=0)
    parser.add_argument('--inputs', nargs='+', choices=INPUTS, default=list(INPUTS))
    parser.add_argument('--out', type=Path)
    args = parser.parse_args(argv)
    from tamer_node.agent import share_the_cpu
    from tamer_node.config import TamerConfig
    share_the_cpu()
    text_size = TamerConfig().text_size
    views, featurize = Views(), Featurizer()
    started = time.monotonic()
    states, judged = collect(args.seed, args.states, args.epsilon, args.inputs, views,
                             featurize, text_size)
    print(f'{len(judged)} judged states in {time.monotonic() - started:.0f} s', flush=True)
    results = {'states': len(judged), 'epsilon': args.epsilon, 'epochs': args.epochs,
               'episodes': args.episodes, 'seed': args.seed, 'inputs': {}}
    for kind in args.inputs:
        model, train_good = fit(kind, states[kind], judged, args.epochs, text_size, args.seed)
        row = {'train_greedy_as_good': round(train_good, 4)}
        for name, pairs in (('heldout_rooms', False), ('heldout_pairs', True)):
            scores = evaluate(kind, model, 10_000 + args.seed, args.episodes, pairs, views,
                              featurize, text_size)
            row[name] = {k: round(v, 4) for k, v in scores.items()}
        results['inputs'][kind] = row
        print(f'{kind:12s} greedy as good as the expert on training states '
              f'{train_good:.3f} | held-out rooms: success {row["heldout_rooms"]["success"]:.3f}'
              f' (target {row["heldout_rooms"]["target_share"]:.2f} of pick-ups) | held-out '
              f'pairs: success {row["heldout_pairs"]["success"]:.3f} (target '
              f'{row["heldout_pairs"]["target_share"]:.2f})', flush=True)
    if args.out:
        args.out.write_text(json.dumps(results, indent=1) + '\n')
    return 0


if __name__ == '__main__':
    sys.exit(main())
