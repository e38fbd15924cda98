"""
tamer_pretrain: collect a task's frames from the real game and pretrain the autoencoder.

Frames come from the task's world (``--task``; Room 1 by default: ``ALE/MontezumaRevenge-v5``, no
sticky actions, seeded), played by its expert (Room 1's scripted expert, DoorKey's planner) with
random detours (``Task.collect_frames``), or by a seeded random walk (``--no-expert``). As in the
thesis the autoencoder sees frames only; with ``--saliency-fraction`` some frames are added again
as saliency-like images (blurred outside a few random boxes), which we tried and dropped:
reconstructing the blur everywhere costs the small code the detail of the agent. Only the encoder's
weights are written (``tamer_node/weights/`` + the task's ``encoder_file`` by default): same seed
and options, same frames, same weights (one thread, CPU).

    tamer_pretrain                       # the shipped weights (Room 1)
    tamer_pretrain --task doorkey        # DoorKey's (weights/encoder_doorkey.pt)
    tamer_pretrain --frames 4000 --epochs 20 --out /tmp/encoder.pt
"""

import argparse
import hashlib
from pathlib import Path
import sys
import time
from typing import Optional, Tuple

from attention_tasks.montezuma.frames import collect_frames  # noqa: F401 (tests, benchmarks)
from attention_tasks.task import DEFAULT_TASK, load_task, task_names
import cv2
import numpy as np
from saliency_node.saliency import BLUR_RADIUS
from tamer_node.agent import encoder_for_task
from tamer_node.model import (
    ConvAutoencoder, feature_stats, load_encoder, preprocess, save_encoder, to_input)
import torch
import torch.nn.functional as F

BLUR_KSIZE = (2 * BLUR_RADIUS + 1,) * 2  # the saliency node's default radius


def saliency_like(frame: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Blur the frame everywhere but in 1 to 4 random boxes (a stand-in saliency image)."""
    blurred = cv2.GaussianBlur(frame, BLUR_KSIZE, 0)
    mask = np.zeros(frame.shape[:2], bool)
    for _ in range(int(rng.integers(1, 5))):
        height, width = int(rng.integers(8, 48)), int(rng.integers(8, 40))
        rows, columns = frame.shape[:2]
        top, left = int(rng.integers(0, rows - height)), int(rng.integers(0, columns - width))
        mask[top:top + height, left:left + width] = True
    return np.where(mask[:, :, None], frame, blurred)


def build_dataset(frames: np.ndarray, saliency_fraction: float, seed: int) -> np.ndarray:
    """(N, 105, 80) uint8 inputs: every frame, plus saliency-like copies of a fraction."""
    rng = np.random.default_rng(seed + 1)
    images = [preprocess(frame, frame.shape[:2]) for frame in frames]
    chosen = rng.choice(len(frames), int(round(saliency_fraction * len(frames))), replace=False)
    images += [preprocess(saliency_like(frames[i], rng), frames.shape[1:3])
               for i in sorted(chosen)]
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
    parser.add_argument('--task', default=DEFAULT_TASK, choices=task_names(),
                        help='whose frames (default: %(default)s)')
    parser.add_argument('--frames', type=int, default=2400, help='frames to collect')
    parser.add_argument('--stride', type=int, default=None,
                        help="keep every n-th step (default: the task's, Room 1 2, DoorKey 1)")
    parser.add_argument('--detour-probability', type=float, default=None,
                        help='chance per step to leave the expert route for a random detour '
                        "(default: the task's, Room 1 0.05, DoorKey 0.15)")
    parser.add_argument('--saliency-fraction', type=float, default=0.0,
                        help='fraction of frames added again as a saliency-like image')
    parser.add_argument('--epochs', type=int, default=15)
    parser.add_argument('--batch-size', type=int, default=32)
    parser.add_argument('--learning-rate', type=float, default=1e-3)
    parser.add_argument('--seed', type=int, default=0)
    parser.add_argument('--threads', type=int, default=1, help='torch CPU threads')
    parser.add_argument('--no-expert', action='store_true',
                        help='collect with the seeded random walk even if the expert exists')
    parser.add_argument('--out', type=Path, default=None,
                        help="default: tamer_node/weights/ + the task's encoder_file")
    parser.add_argument('--stats-only', action='store_true',
                        help='keep the weights in --out, only (re)compute its feature stats')
    args = parser.parse_args(argv)
    torch.set_num_threads(args.threads)
    cv2.setNumThreads(1)

    task = load_task(args.task)
    if args.out is None:
        args.out = encoder_for_task(task.name)
    chosen = {name: value for name, value in (('stride', args.stride),
                                              ('detour_probability', args.detour_probability))
              if value is not None}
    frames, policy = task.collect_frames(
        args.frames, args.seed, use_expert=not args.no_expert,
        progress=lambda done, total: _bar('collect', done, total), **chosen)
    if args.stats_only:
        encoder = load_encoder(args.out)
        encoder.set_feature_stats(*feature_stats(encoder, build_dataset(frames, 0.0, args.seed)))
        info = torch.load(args.out, map_location='cpu', weights_only=True)['info']
        save_encoder(encoder, args.out, dict(info, feature_stats_frames=len(frames)))
        print(f'feature stats of {len(frames)} frames written to {args.out}')
        return 0
    images = build_dataset(frames, args.saliency_fraction, args.seed)
    digest = hashlib.sha256(images.tobytes()).hexdigest()[:16]
    print(f'{len(frames)} {task.name} frames ({policy}), {len(images)} training images, '
          f'data sha256 {digest}')
    model, losses = train_autoencoder(images, args.epochs, args.batch_size, args.learning_rate,
                                      args.seed, progress=True)
    print(f'reconstruction MSE per pixel (0..1 scale): train {losses["train_mse"]:.5f}, '
          f'held-out {losses["val_mse"]:.5f} (the mean image alone: '
          f'{losses["val_mse_of_mean_image"]:.5f}); on the held-out pixels that differ from '
          f'the mean image {losses["val_mse_changing_pixels"]:.5f} (mean image alone: '
          f'{losses["val_mse_changing_pixels_of_mean_image"]:.5f}); {losses["seconds"]:.0f} s')
    args.out.parent.mkdir(parents=True, exist_ok=True)
    info = {'task': task.name, 'frames': len(frames), 'images': len(images), 'policy': policy,
            'data_sha256': digest, 'seed': args.seed, 'epochs': args.epochs,
            **chosen,
            'saliency_fraction': args.saliency_fraction, **losses}
    # The head standardizes each feature by its mean and std over the task's frames.
    model.encoder.set_feature_stats(*feature_stats(model.encoder, images[:len(frames)]))
    save_encoder(model.encoder, args.out, dict(info, feature_stats_frames=len(frames)))
    print(f'encoder weights written to {args.out} ({args.out.stat().st_size / 1024:.0f} kB)')
    return 0


if __name__ == '__main__':
    sys.exit(main())
