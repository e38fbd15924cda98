"""
DoorKey's representation, offline: can H's features tell the good actions on held-out layouts.

A diagnostic for issue 23 (DoorKey's every-step teacher solves few held-out layouts). States are
collected on training layouts (the expert's action with probability 0.6, else a random one) and
on held-out layouts; every state is labelled for all six actions by the teacher's own rule
(``DoorKeyKnowledge.as_good``): full information, which the online learner (one verdict, on the
action taken) never has. A head like H's (Linear, LeakyReLU, Linear to 6, regression to +-1) is
fitted on four representations, and the share of held-out states where its greedy action is good
is printed: the shipped frozen encoder, MiniGrid's symbolic 7 x 7 view (one-hot; what the pixels
hold at best), and the RGB frame averaged into 4 x 4 or 2 x 2 cells per tile.

Run: ``.venv/bin/python tests/benchmarks/doorkey_representation.py --states 8000``.
"""
import argparse
import time

from attention_tasks.doorkey.env import DoorKeyEnv, DoorKeyEnvConfig
from attention_tasks.doorkey.teaching import KNOWLEDGE
import numpy as np
from tamer_node.agent import encoder_for_task
from tamer_node.model import load_encoder, preprocess, to_input
import torch
from torch import nn

torch.set_num_threads(1)


def collect(seed, count, heldout, rng, expert_p=0.6):
    """Return (frames, symbolic views, (N, 6) good-action labels) of ``count`` states."""
    env = DoorKeyEnv(DoorKeyEnvConfig(seed=seed, size=8, distractors=4, max_episode_steps=100,
                                      heldout_after=1 if heldout else 0))
    step = env.reset()
    if heldout:
        env.step(0)
        step = env.reset()
    frames, sym, labels = [], [], []
    while len(frames) < count:
        state = step.state
        expert = KNOWLEDGE.expert_action(state)
        if expert is not None:
            good = [KNOWLEDGE.as_good(state, a, expert) for a in range(6)]
            frames.append(step.observation.copy())
            sym.append(env.world.gen_obs()['image'].copy())
            labels.append(good)
        a = expert if (expert is not None and rng.random() < expert_p) else int(rng.integers(6))
        step = env.step(a)
        if step.done:
            step = env.reset()
    env.close()
    return np.array(frames), np.array(sym), np.array(labels, dtype=np.float32)


def onehot_sym(sym):
    """Return one-hot rows of MiniGrid views: (N, 7, 7, 3) object, colour, state codes."""
    obj = np.eye(11)[sym[..., 0]]
    col = np.eye(6)[sym[..., 1]]
    st = np.eye(3)[np.clip(sym[..., 2], 0, 2)]
    return np.concatenate([obj, col, st], -1).reshape(len(sym), -1).astype(np.float32)


def tiles(frames, k=4):
    """(N, 112, 112, 3) frames -> each 16 px tile averaged into k x k RGB cells, rows."""
    n = len(frames)
    x = frames.reshape(n, 7, 16, 7, 16, 3).astype(np.float32) / 255.0
    x = x.reshape(n, 7, k, 16 // k, 7, k, 16 // k, 3).mean((3, 6))
    return x.reshape(n, -1)


def fit(xtr, ytr, xte, yte, hidden=64, epochs=30, lr=1e-3, label=''):
    """Fit H's head to the +-1 labels of all actions; print greedy-good shares."""
    torch.manual_seed(0)
    xtr, ytr, xte = map(torch.as_tensor, (xtr, ytr * 2 - 1, xte))
    mu, sd = xtr.mean(0), xtr.std(0).clamp_min(0.1)
    xtr, xte = (xtr - mu) / sd, (xte - mu) / sd
    net = nn.Sequential(nn.Linear(xtr.shape[1], hidden), nn.LeakyReLU(0.01),
                        nn.Linear(hidden, 6))
    opt = torch.optim.Adam(net.parameters(), lr=lr)
    for ep in range(epochs):
        perm = torch.randperm(len(xtr))
        for i in range(0, len(xtr), 32):
            b = perm[i:i + 32]
            loss = ((net(xtr[b]) - ytr[b]) ** 2).mean()
            opt.zero_grad()
            loss.backward()
            opt.step()
    with torch.no_grad():
        pick = net(xte).argmax(1).numpy()
        ptr = net(xtr).argmax(1).numpy()
    te = yte[np.arange(len(yte)), pick].mean()
    tr = ((ytr.numpy() + 1) / 2)[np.arange(len(ptr)), ptr].mean()
    print(f'{label}: greedy good train {tr:.3f} held-out {te:.3f}', flush=True)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    parser.add_argument('--states', type=int, default=8000, help='training states')
    n = parser.parse_args().states
    rng = np.random.default_rng(0)
    t = time.time()
    ftr, str_, ytr = collect(100, n, False, rng)
    fte, ste, yte = collect(100, 3000, True, rng)
    print(f'collected {len(ftr)} + {len(fte)} in {time.time() - t:.0f} s; '
          f'good share {ytr.mean():.3f}; best constant {yte.mean(0).max():.3f}', flush=True)
    enc = load_encoder(encoder_for_task('doorkey'))
    with torch.no_grad():
        def feats(f):
            return torch.cat([enc.standardized(to_input(np.stack([preprocess(x, (112, 112))
                                                                  for x in f[i:i + 256]])))
                              for i in range(0, len(f), 256)]).numpy()
        etr, ete = feats(ftr), feats(fte)
    fit(etr, ytr, ete, yte, label='frozen encoder')
    fit(onehot_sym(str_), ytr, onehot_sym(ste), yte, label='symbolic one-hot')
    fit(tiles(ftr), ytr, tiles(fte), yte, label='RGB tiles 4x4')
    fit(tiles(ftr, 2), ytr, tiles(fte, 2), yte, label='RGB tiles 2x2')


if __name__ == '__main__':
    main()
