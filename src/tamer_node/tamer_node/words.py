"""
An utterance as the text-conditioned learner reads it: a bag of its words, hashed (pure).

BabyAI's agents embed the instruction's words and condition their features on them (FiLM).
Here an utterance is lower-cased, split into words, and each word counted in one of ``size``
buckets by a stable hash (crc32), normalised to unit length: no vocabulary to ship per task,
and "pick up the purple ball" differs from "pick up the red ball" in two buckets.
"""

import re
import zlib

import torch

WORD = re.compile(r'[a-z]+')


def bag_of_words(text: str, size: int) -> torch.Tensor:
    """Return the (size,) float32 hashed bag of words of ``text``, unit length (zeros: none)."""
    if size < 1:
        raise ValueError(f'size must be at least 1, got {size}')
    bag = torch.zeros(size, dtype=torch.float32)
    for word in WORD.findall(text.lower()):
        bag[zlib.crc32(word.encode()) % size] += 1.0
    norm = torch.linalg.vector_norm(bag)
    return bag / norm if norm > 0 else bag
