"""
Networks: the image preprocessing, the convolutional autoencoder and H(s, a).

Preprocessing (shared by frames and saliency images): RGB 210x160 -> luminance -> 105x80 by exact
2x2 area averaging, uint8 (another task's frames, DoorKey's 112x112, are area-averaged to the same
105x80, so the networks are the same for every task). Halving keeps most of the saliency blur
visible to the network (on a Room 1 frame blurred as the saliency node does, the mean absolute
pixel difference is 8.0 grey levels at 105x80 against 11.3 at full size and 6.0 at the usual 84x84
squeeze), keeps the agent's few pixels, and makes a frame 8.4 kB, so a buffer of 10,000 steps with
saliency images fits in about 170 MB. Colour is dropped: the study's objects differ in brightness
as well.

The encoder is fully convolutional: its 8x14x10 feature map keeps where things are, which is
what H needs (the thesis found the agent's position is nearly all that matters).
"""

from typing import Optional

from attention_common.joy_actions import action_to_joy, NUM_ACTIONS
import cv2
import numpy as np
import torch
from torch import nn
import torch.nn.functional as F

FRAME_SHAPE = (210, 160, 3)
"""What the env publishes: RGB rows x columns x channels."""
INPUT_SHAPE = (105, 80)
"""What the networks see: luminance, half the frame's size."""
FEATURE_SHAPE = (8, 14, 10)
"""Encoder output: channels x rows x columns."""
FEATURE_SIZE = int(np.prod(FEATURE_SHAPE))
ENCODER_FORMAT = 'tamer_node.encoder/1'
STD_FLOOR = 0.1
"""Smallest per-feature std used to standardize: features that hardly change in Room 1 (the
walls) are not blown up into noise, and images unlike the pretraining frames stay bounded."""


def preprocess(rgb: np.ndarray, frame_shape=FRAME_SHAPE[:2]) -> np.ndarray:
    """(rows, columns, 3) uint8 RGB frame or saliency image -> (105, 80) uint8 luminance."""
    expected = tuple(frame_shape) + (3,)
    if rgb.shape != expected or rgb.dtype != np.uint8:
        raise ValueError(f'expected a {expected} uint8 RGB image, got {rgb.shape} '
                         f'{rgb.dtype}')
    gray = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)
    return cv2.resize(gray, (INPUT_SHAPE[1], INPUT_SHAPE[0]), interpolation=cv2.INTER_AREA)


def to_input(images) -> torch.Tensor:
    """(B, 105, 80) uint8 array or tensor -> (B, 1, 105, 80) float32 in [0, 1]."""
    images = torch.as_tensor(images)
    if images.dim() == 2:
        images = images.unsqueeze(0)
    return images.unsqueeze(1).to(torch.float32) / 255.0


class Encoder(nn.Module):
    """(B, 1, 105, 80) -> (B, 8, 14, 10): three stride-2 convolutions and a 1-stride one."""

    def __init__(self):
        super().__init__()
        self.layers = nn.Sequential(
            nn.Conv2d(1, 8, 5, stride=2, padding=2), nn.ReLU(),    # 53x40
            nn.Conv2d(8, 16, 5, stride=2, padding=2), nn.ReLU(),   # 27x20
            nn.Conv2d(16, 16, 3, stride=2, padding=1), nn.ReLU(),  # 14x10
            nn.Conv2d(16, FEATURE_SHAPE[0], 3, padding=1),         # 8x14x10, linear code
        )
        # Per-feature mean and std over the pretraining frames (identity until set). Not in
        # the state dict: they travel in the encoder file (save_encoder / load_encoder).
        self.register_buffer('feature_mean', torch.zeros(FEATURE_SHAPE), persistent=False)
        self.register_buffer('feature_std', torch.ones(FEATURE_SHAPE), persistent=False)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.layers(x)

    def standardized(self, x: torch.Tensor) -> torch.Tensor:
        """
        Encode (B, 1, 105, 80) into (B, 1120) features, each standardized over Room 1 frames.

        Raw, every Room 1 frame has nearly the same code (the static walls dominate: per
        feature the std over frames is 0.09 against 0.84 over all features), so a head on raw
        features sees one point and, pushed by mostly -1 feedback, kills its ReLUs. Standardized,
        what changes between frames (the agent, the skull) is what the head sees.
        """
        z = self.layers(x).flatten(1)
        return (z - self.feature_mean.flatten()) / self.feature_std.flatten()

    def set_feature_stats(self, mean: torch.Tensor, std: torch.Tensor) -> None:
        self.feature_mean.copy_(mean.reshape(FEATURE_SHAPE))
        self.feature_std.copy_(std.reshape(FEATURE_SHAPE).clamp_min(STD_FLOOR))


@torch.no_grad()
def feature_stats(encoder: Encoder, images: np.ndarray, chunk: int = 256):
    """Per-feature (mean, std) of the encoder's raw code over (N, 105, 80) uint8 images."""
    codes = torch.cat([encoder(to_input(images[i:i + chunk])).flatten(1)
                       for i in range(0, len(images), chunk)])
    return codes.mean(0), codes.std(0)


class Decoder(nn.Module):
    """(B, 8, 14, 10) -> (B, 1, 105, 80) residual: nearest upsampling and convolutions."""

    def __init__(self):
        super().__init__()
        self.c1 = nn.Conv2d(FEATURE_SHAPE[0], 16, 3, padding=1)
        self.c2 = nn.Conv2d(16, 16, 3, padding=1)
        self.c3 = nn.Conv2d(16, 8, 3, padding=1)
        self.c4 = nn.Conv2d(8, 1, 3, padding=1)
        with torch.no_grad():  # start close to "no change from the mean image"
            self.c4.weight.mul_(0.1)
            self.c4.bias.zero_()

    def forward(self, z: torch.Tensor) -> torch.Tensor:
        x = F.relu(self.c1(z))
        x = F.relu(self.c2(F.interpolate(x, size=(27, 20))))
        x = F.relu(self.c3(F.interpolate(x, size=(53, 40))))
        return self.c4(F.interpolate(x, size=INPUT_SHAPE))


class ConvAutoencoder(nn.Module):
    """
    Encoder + decoder, pretrained on Room 1 frames to reconstruct them (tamer_pretrain).

    The reconstruction is the training set's mean image plus the decoded residual. Room 1 hardly
    changes, so the code has to carry what does (the agent, the skull, the key, saliency blur)
    instead of spending itself on the static walls that the mean image already holds.
    """

    def __init__(self):
        super().__init__()
        self.encoder = Encoder()
        self.decoder = Decoder()
        self.register_buffer('mean_image', torch.zeros((1, 1) + INPUT_SHAPE))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.mean_image + self.decoder(self.encoder(x))


class PartsHead(nn.Module):
    """
    H's last layer with outputs that share their joystick parts' weights.

    Output a = (W_a + P_h(a) + P_v(a) + P_f(a)) . x + its biases, where h, v and f are the
    action's horizontal, vertical and button parts (``parts``: one (h, v, f) index triple per
    action). A verdict on UPRIGHT then also moves RIGHT and UP a little: in Room 1 six of the
    18 actions walk right on the floor, and each would otherwise be learned wrong on its own.
    """

    def __init__(self, hidden: int, parts):
        super().__init__()
        parts = torch.as_tensor(parts, dtype=torch.int64)
        self.register_buffer('parts', parts, persistent=False)
        self.own = nn.Linear(hidden, len(parts))
        self.shared = nn.ModuleList(
            nn.Linear(hidden, int(parts[:, i].max()) + 1) for i in range(parts.shape[1]))
        with torch.no_grad():  # the same starting scale as one Linear layer's outputs
            for layer in self.shared:
                layer.weight.zero_()
                layer.bias.zero_()

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        out = self.own(x)
        for i, layer in enumerate(self.shared):
            out = out + layer(x)[:, self.parts[:, i]]
        return out


def joystick_parts(joy_actions) -> list:
    """Return the (horizontal, vertical, button) indices of each action's joystick action."""
    parts = []
    for joy in joy_actions:
        (horizontal, vertical), (fire,) = action_to_joy(joy)
        parts.append((int(horizontal) + 1, int(vertical) + 1, int(fire)))
    return parts


class HModel(nn.Module):
    """
    H(s, .): the encoder's standardized features into a small head, one output per action.

    Head: Linear(1120, hidden) -> LeakyReLU(0.01) -> Linear(hidden, actions) (ALE's 18 in Room
    1, MiniGrid's 6 in DoorKey). With a frozen encoder
    the learner trains the head on cached features (``features`` once per image, then
    ``from_features``): the same numbers as ``forward`` on the image, at a fraction of the cost.
    """

    def __init__(self, hidden: int = 64, freeze_encoder: bool = True,
                 encoder: Optional[Encoder] = None, num_actions: int = NUM_ACTIONS,
                 parts=None, streams: int = 1, text_size: int = 0):
        """
        ``parts``: each action's joystick parts (``joystick_parts``) to share, or None.

        ``streams``: images whose features the head reads side by side (2: the frame and its
        saliency image, ``input_image: both``; ``from_features`` then takes (B, 2240)).
        ``text_size`` > 0: FiLM, the hidden layer scaled by (1 + gamma) and shifted by beta,
        both linear in the utterance's bag of words, which ends each state (B, 1120 + size).
        """
        super().__init__()
        self.encoder = encoder if encoder is not None else Encoder()
        self.streams = int(streams)
        last = nn.Linear(hidden, num_actions) if parts is None else PartsHead(hidden, parts)
        self.head = nn.Sequential(nn.Linear(FEATURE_SIZE * self.streams, hidden),
                                  nn.LeakyReLU(0.01), last)
        self.text_size = int(text_size)
        self.film = None
        if self.text_size:
            self.film = nn.Linear(self.text_size, 2 * hidden)
            with torch.no_grad():  # no words: the plain head
                self.film.weight.zero_()
                self.film.bias.zero_()
        self.freeze_encoder = freeze_encoder
        self.encoder.requires_grad_(not freeze_encoder)

    def features(self, x: torch.Tensor) -> torch.Tensor:
        """(B, 1, 105, 80) float -> (B, 1120) standardized encoder features."""
        if self.freeze_encoder:
            with torch.no_grad():
                return self.encoder.standardized(x)
        return self.encoder.standardized(x)

    def from_features(self, features: torch.Tensor) -> torch.Tensor:
        """(B, 1120) features (then the bag of words, with FiLM) -> (B, 18)."""
        if self.film is None:
            return self.head(features)
        images, text = features[:, :-self.text_size], features[:, -self.text_size:]
        gamma, beta = self.film(text).chunk(2, dim=1)
        return self.head[2](self.head[1](self.head[0](images)) * (1.0 + gamma) + beta)

    def hidden(self, features: torch.Tensor) -> torch.Tensor:
        """(B, 1120) features -> (B, hidden) pre-activations (to count dead units)."""
        if self.film is not None:
            features = features[:, :-self.text_size]
        return self.head[0](features)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """(B, streams, 105, 80) float -> (B, 18) predicted feedback for every action."""
        return self.head(torch.cat([self.features(x[:, i:i + 1])
                                    for i in range(self.streams)], dim=1))

    def trainable_parameters(self):
        return [p for p in self.parameters() if p.requires_grad]


def save_encoder(encoder: Encoder, path, info: Optional[dict] = None) -> None:
    """Write the encoder's weights (and feature stats) with a format tag and their origin."""
    torch.save({'format': ENCODER_FORMAT, 'input_shape': list(INPUT_SHAPE),
                'info': dict(info or {}), 'state_dict': encoder.state_dict(),
                'feature_mean': encoder.feature_mean.clone(),
                'feature_std': encoder.feature_std.clone()}, path)


def load_encoder(path) -> Encoder:
    """Read weights written by ``save_encoder``; raise ValueError if they do not fit."""
    blob = torch.load(path, map_location='cpu', weights_only=True)
    if not isinstance(blob, dict) or blob.get('format') != ENCODER_FORMAT:
        raise ValueError(f'{path} is not a {ENCODER_FORMAT} file')
    if list(blob.get('input_shape', [])) != list(INPUT_SHAPE):
        raise ValueError(f'{path} was trained on {blob.get("input_shape")}, not {INPUT_SHAPE}')
    encoder = Encoder()
    encoder.load_state_dict(blob['state_dict'])
    if 'feature_mean' in blob:  # older files have none: features are used raw
        encoder.set_feature_stats(blob['feature_mean'], blob['feature_std'])
    return encoder
