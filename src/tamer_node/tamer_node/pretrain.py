"""
tamer_pretrain: collect Room 1 frames from the real game and pretrain the autoencoder.

Frames come from ``ALE/MontezumaRevenge-v5`` (no sticky actions, seeded), played by the scripted
expert (``attention_tasks.montezuma.expert.RoomOneExpert``) with random detours, or by a seeded
random walk if that package is not installed. As in the thesis the autoencoder sees frames only;
with ``--saliency-fraction`` some frames are added again as saliency-like images (blurred outside a
few random boxes), which we tried and dropped: reconstructing the blur everywhere costs the small
code the detail of the agent. Only the encoder's weights are written
(``tamer_node/weights/encoder.pt`` by default): same seed and options, same frames, same weights
(one thread, CPU).

    tamer_pretrain                       # the shipped weights
    tamer_pretrain --frames 4000 --epochs 20 --out /tmp/encoder.pt
"""

import argparse
import hashlib
from pathlib import Path
import sys
import time
from typing import Optional, Tuple

from attention_common.joy_actions import NUM_ACTIONS
import cv2
from env_node.core import EnvConfig, MontezumaEnv
import numpy as np
from saliency_node.saliency import BLUR_RADIUS
from tamer_node.agent import DEFAULT_ENCODER
from tamer_node.model import (
    ConvAutoencoder, feature_stats, load_encoder, preprocess, save_encoder, to_input)
import torch
import torch.nn.functional as F

ROOM_ONE = 1
BLUR_KSIZE = (2 * BLUR_RADIUS + 1,) * 2  # the saliency node's default radius


def load_expert():
    """Return (RoomOneExpert(), skull_x_from_ram), or (None, None) without attention_tasks."""
    try:
        from attention_tasks.montezuma.expert import RoomOneExpert, skull_x_from_ram
    except ImportError:
        return None, None
    return RoomOneExpert(), skull_x_from_ram


def collect_frames(count: int, seed: int = 0, stride: int = 2, detour_probability: float = 0.05,
                   detour_steps: Tuple[int, int] = (4, 24), use_expert: bool = True,
                   episode_steps: int = 1500,
                   progress: bool = False) -> Tuple[np.ndarray, str]:
    """
    Return ((count, 210, 160, 3) uint8 Room 1 frames, the policy's name).

    Every ``stride``-th step is kept. With probability ``detour_probability`` per step the agent
    leaves the route for a random number of steps holding one random action, then the expert
    takes over again from wherever it is. An episode ends at game over, on leaving Room 1, with
    the key, or after ``episode_steps``.
    """
    rng = np.random.default_rng(seed)
    expert, skull_x_from_ram = load_expert() if use_expert else (None, None)
    policy = 'expert with random detours' if expert is not None else 'seeded random walk'
    if expert is None:
        detour_probability = 0.1  # a random walk: hold a random action for a while
    env = MontezumaEnv(EnvConfig(seed=seed, warmup_steps=0, sticky_actions=0.0))
    frames = np.empty((count,) + (210, 160, 3), np.uint8)
    kept = 0
    detour_left, detour_action = 0, 0
    try:
        step = env.reset()
        if expert is not None:
            expert.reset()
        while kept < count:
            if step.state.room == ROOM_ONE and step.episode_step % stride == 0:
                frames[kept] = step.observation
                kept += 1
                if progress and kept % 200 == 0:
                    _bar('collect', kept, count)
            if detour_left == 0 and rng.random() < detour_probability:
                detour_left = int(rng.integers(detour_steps[0], detour_steps[1] + 1))
                detour_action = int(rng.integers(NUM_ACTIONS))
            if expert is not None:
                # The expert sees every step (its skull tracker keeps time) even when the
                # detour overrides its choice.
                expert_action = int(expert.act(step.state, skull_x_from_ram(env.ale.getRAM())))
            if detour_left > 0 or expert is None:
                action = detour_action
                detour_left = max(0, detour_left - 1)
            else:
                action = expert_action
            step = env.step(action)
            if step.done or step.state.has_key or step.episode_step >= episode_steps:
                step = env.reset()
                if expert is not None:
                    expert.reset()
    finally:
        env.close()
    return frames, policy


def saliency_like(frame: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Blur the frame everywhere but in 1 to 4 random boxes (a stand-in saliency image)."""
    blurred = cv2.GaussianBlur(frame, BLUR_KSIZE, 0)
    mask = np.zeros(frame.shape[:2], bool)
    for _ in range(int(rng.integers(1, 5))):
        height, width = int(rng.integers(8, 48)), int(rng.integers(8, 40))
        top, left = int(rng.integers(0, 210 - height)), int(rng.integers(0, 160 - width))
        mask[top:top + height, left:left + width] = True
    return np.where(mask[:, :, None], frame, blurred)


def build_dataset(frames: np.ndarray, saliency_fraction: float, seed: int) -> np.ndarray:
    """(N, 105, 80) uint8 inputs: every frame, plus saliency-like copies of a fraction."""
    rng = np.random.default_rng(seed + 1)
    images = [preprocess(frame) for frame in frames]
    chosen = rng.choice(len(frames), int(round(saliency_fraction * len(frames))), replace=False)
    images += [preprocess(saliency_like(frames[i], rng)) for i in sorted(chosen)]
    return np.stack(images)


def train_autoencoder(images: np.ndarray, epochs: int = 15, batch_size: int = 32,
                      learning_rate: float = 1e-3, seed: int = 0, validation: float = 0.1,
                      progress: bool = False) -> Tuple[ConvAutoencoder, dict]:
    """Train on a seeded split; return the model and its losses (per-pixel MSE, [0, 1])."""
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed + 2)
    order = rng.permutation(len(images))
    held = max(1, int(round(validation * len(images))))
    val_x, train_x = to_input(images[order[:held]]), to_input(images[order[held:]])
    model = ConvAutoencoder()
    model.mean_image.copy_(train_x.mean(dim=0, keepdim=True))
    optimizer = torch.optim.Adam(model.parameters(), lr=learning_rate)
    started = time.monotonic()
    train_loss = float('nan')
    for epoch in range(epochs):
        total = 0.0
        permutation = torch.from_numpy(rng.permutation(len(train_x)))
        for start in range(0, len(train_x), batch_size):
            batch = train_x[permutation[start:start + batch_size]]
            loss = F.mse_loss(model(batch), batch)
            optimizer.zero_grad(set_to_none=True)
            loss.backward()
            optimizer.step()
            total += loss.item() * len(batch)
        train_loss = total / len(train_x)
        if progress:
            _bar('train', epoch + 1, epochs, f'loss {train_loss:.5f}')
    with torch.no_grad():
        error = (model(val_x) - val_x) ** 2
        mean_error = (model.mean_image - val_x) ** 2
        moving = (model.mean_image - val_x).abs() > 0.05  # pixels that differ from the mean
    return model, {
        'train_mse': train_loss, 'val_mse': float(error.mean()),
        'val_mse_of_mean_image': float(mean_error.mean()),
        'val_mse_changing_pixels': float(error[moving].mean()),
        'val_mse_changing_pixels_of_mean_image': float(mean_error[moving].mean()),
        'seconds': time.monotonic() - started}


def _bar(label: str, done: int, total: int, suffix: str = '') -> None:
    filled = int(30 * done / total)
    sys.stderr.write(f'\r{label:8s} [{"#" * filled}{"." * (30 - filled)}] {done}/{total} '
                     f'{suffix}')
    if done >= total:
        sys.stderr.write('\n')
    sys.stderr.flush()


def main(argv: Optional[list] = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.strip().split('\n')[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--frames', type=int, default=2400, help='Room 1 frames to collect')
    parser.add_argument('--stride', type=int, default=2, help='keep every n-th step')
    parser.add_argument('--detour-probability', type=float, default=0.05,
                        help='chance per step to leave the expert route for a random detour')
    parser.add_argument('--saliency-fraction', type=float, default=0.0,
                        help='fraction of frames added again as a saliency-like image')
    parser.add_argument('--epochs', type=int, default=15)
    parser.add_argument('--batch-size', type=int, default=32)
    parser.add_argument('--learning-rate', type=float, default=1e-3)
    parser.add_argument('--seed', type=int, default=0)
    parser.add_argument('--threads', type=int, default=1, help='torch CPU threads')
    parser.add_argument('--no-expert', action='store_true',
                        help='collect with the seeded random walk even if the expert exists')
    parser.add_argument('--out', type=Path, default=DEFAULT_ENCODER)
    parser.add_argument('--stats-only', action='store_true',
                        help='keep the weights in --out, only (re)compute its feature stats')
    args = parser.parse_args(argv)
    torch.set_num_threads(args.threads)
    cv2.setNumThreads(1)

    frames, policy = collect_frames(args.frames, args.seed, args.stride,
                                    args.detour_probability, use_expert=not args.no_expert,
                                    progress=True)
    if args.stats_only:
        encoder = load_encoder(args.out)
        encoder.set_feature_stats(*feature_stats(encoder, build_dataset(frames, 0.0, args.seed)))
        info = torch.load(args.out, map_location='cpu', weights_only=True)['info']
        save_encoder(encoder, args.out, dict(info, feature_stats_frames=len(frames)))
        print(f'feature stats of {len(frames)} frames written to {args.out}')
        return 0
    images = build_dataset(frames, args.saliency_fraction, args.seed)
    digest = hashlib.sha256(images.tobytes()).hexdigest()[:16]
    print(f'{len(frames)} Room 1 frames ({policy}), {len(images)} training images, '
          f'data sha256 {digest}')
    model, losses = train_autoencoder(images, args.epochs, args.batch_size, args.learning_rate,
                                      args.seed, progress=True)
    print(f'reconstruction MSE per pixel (0..1 scale): train {losses["train_mse"]:.5f}, '
          f'held-out {losses["val_mse"]:.5f} (the mean image alone: '
          f'{losses["val_mse_of_mean_image"]:.5f}); on the held-out pixels that differ from '
          f'the mean image {losses["val_mse_changing_pixels"]:.5f} (mean image alone: '
          f'{losses["val_mse_changing_pixels_of_mean_image"]:.5f}); {losses["seconds"]:.0f} s')
    args.out.parent.mkdir(parents=True, exist_ok=True)
    info = {'frames': len(frames), 'images': len(images), 'policy': policy,
            'data_sha256': digest, 'seed': args.seed, 'epochs': args.epochs,
            'stride': args.stride, 'detour_probability': args.detour_probability,
            'saliency_fraction': args.saliency_fraction, **losses}
    # The head standardizes each feature by its mean and std over the Room 1 frames.
    model.encoder.set_feature_stats(*feature_stats(model.encoder, images[:len(frames)]))
    save_encoder(model.encoder, args.out, dict(info, feature_stats_frames=len(frames)))
    print(f'encoder weights written to {args.out} ({args.out.stat().st_size / 1024:.0f} kB)')
    return 0


if __name__ == '__main__':
    sys.exit(main())
