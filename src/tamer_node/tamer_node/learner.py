"""The learner: owns the optimizer and takes gradient steps on H (thesis eq. 4.3 and 4.4)."""

from typing import Dict

from tamer_node.buffer import Batch
from tamer_node.model import HModel, to_input
import torch


def mixture_mse(judged: torch.Tensor, h: torch.Tensor, weights: torch.Tensor,
                groups: torch.Tensor) -> torch.Tensor:
    """
    Mean over feedbacks of (credit-weighted mean of H over its steps - h)^2.

    A late feedback is the verdict on *one* of the steps its window covers, each with its
    credit's probability, so its expected value is the credit-weighted mean of the verdicts:
    least squares on that mean is an unbiased fit of H (a deconvolution of the delay), where
    regressing every step to h ('each', Deep TAMER's) fits each step to the blur of its
    neighbours' verdicts. A feedback with one step (step credit) is the plain squared error.
    """
    count = int(groups.max()) + 1
    mass = torch.zeros(count).index_add_(0, groups, weights)
    mean = torch.zeros(count).index_add_(0, groups, weights * judged) / mass.clamp_min(1e-12)
    target = torch.zeros(count).index_add_(0, groups, weights * h) / mass.clamp_min(1e-12)
    used = mass > 0
    return ((mean - target)[used] ** 2).mean()


def excluded_mse(predictions: torch.Tensor, batch: Batch) -> torch.Tensor:
    """
    Credit-weighted mean over positive rows of the other actions' squared distance to -1.

    A verdict of +1 says the action judged is what the trainer wanted, so (as a label on the
    policy, Griffith et al. 2013) mostly that the others were not: each positive sample also
    teaches every other action of its state toward -1. Negative rows imply nothing.
    """
    positive = (batch.h > 0).to(predictions.dtype) * batch.weights
    if not bool((positive > 0).any()):
        return torch.zeros(())
    others = torch.ones_like(predictions).scatter_(1, batch.actions.unsqueeze(1), 0.0)
    per_row = ((predictions + 1.0) ** 2 * others).sum(1) / others.sum(1)
    return (positive * per_row).sum() / positive.sum()


class Learner:
    """Trains an ``HModel``; one thread at a time calls ``train_step`` (see learner_loop.py)."""

    def __init__(self, model: HModel, learning_rate: float = 3e-4, alpha: float = 1e-4,
                 max_grad_norm: float = 1.0, credit_loss: str = 'each',
                 positive_excludes: float = 0.0):
        self.model = model
        self.positive_excludes = float(positive_excludes)
        """Weight of the -1 a positive verdict implies for every other action (0: none)."""
        self.credit_loss = credit_loss
        """'each': every credited step regressed to h; 'mixture': their credit-weighted mean."""
        self.max_grad_norm = float(max_grad_norm)
        """Clip the gradient's global norm to this before each step (0 = no clipping)."""
        self.optimizer = torch.optim.Adam(model.trainable_parameters(), lr=learning_rate)
        self.alpha = float(alpha)
        """Weight of the saliency L2 term; may be changed between steps (a ROS parameter)."""
        self.updates = 0

    def predict(self, states: torch.Tensor) -> torch.Tensor:
        """
        H(., .) of a batch: (B, 105, 80) uint8 images, or (B, 1120) cached float features.

        Cached features come from the frozen encoder (the acting path computed them): the
        gradient then reaches the head only, which is what a frozen encoder means.
        """
        if states.dtype == torch.uint8:
            return self.model(to_input(states))
        return self.model.from_features(states)

    def loss(self, batch: Batch):
        """Return (loss, mse, l2) for a batch, as tensors with their graph."""
        predictions = self.predict(batch.states)                      # H(s, .), (B, 18)
        judged = predictions.gather(1, batch.actions.unsqueeze(1)).squeeze(1)
        if self.credit_loss == 'mixture' and batch.groups is not None:
            mse = mixture_mse(judged, batch.h, batch.weights, batch.groups)
        else:
            mse = (batch.weights * (judged - batch.h) ** 2).sum() / batch.weights.sum()
        if self.positive_excludes > 0.0:
            mse = mse + self.positive_excludes * excluded_mse(predictions, batch)
        rows = batch.has_companion
        if self.alpha == 0.0 or not bool(rows.any()):
            # Vanilla Deep TAMER: no saliency image is even run through the network.
            return mse, mse, torch.zeros(())
        # Eq. 4.3 over ALL 18 outputs, not only the judged action's: the saliency image tells
        # which pixels matter in this state, whatever the action, so the whole vector H(s, .)
        # should stay the same when the rest is blurred away. Mean over the rows that have one.
        # With a frozen encoder both sides are cached features and the gradient moves the head
        # only; with fine_tune_encoder it flows through the encoder on both images.
        on_saliency = self.predict(batch.companions[rows])            # H(s', .), (R, 18)
        l2 = ((predictions[rows] - on_saliency) ** 2).sum(dim=1).mean()
        return mse + self.alpha * l2, mse, l2

    def train_step(self, batch: Batch) -> Dict[str, float]:
        """Take one Adam step on the batch; return the loss terms as floats."""
        loss, mse, l2 = self.loss(batch)
        terms = {'loss': loss.item(), 'mse': mse.item(), 'l2': l2.item(),
                 'l2_rows': int(batch.has_companion.sum()) if self.alpha > 0.0 else 0,
                 'skipped': 0}
        if not torch.isfinite(loss):
            terms['skipped'] = 1  # a step on a NaN would spoil every weight for good
            return terms
        self.optimizer.zero_grad(set_to_none=True)
        loss.backward()
        if self.max_grad_norm > 0.0:
            torch.nn.utils.clip_grad_norm_(self.model.trainable_parameters(), self.max_grad_norm)
        self.optimizer.step()
        self.updates += 1
        return terms

    def snapshot(self) -> Dict[str, torch.Tensor]:
        """
        Copy the weights for the acting model (never shares memory with training).

        A frozen encoder never changes: only the head is copied (and loaded by the actor), so
        an update costs the actor a few small tensors, not the whole model.
        """
        state = self.model.state_dict()
        if self.model.freeze_encoder:
            state = {name: tensor for name, tensor in state.items()
                     if not name.startswith('encoder.')}
        return {name: tensor.detach().clone() for name, tensor in state.items()}

    def state_dict(self) -> dict:
        return {'model': self.model.state_dict(), 'optimizer': self.optimizer.state_dict(),
                'updates': self.updates}

    def load_state_dict(self, state: dict) -> None:
        self.model.load_state_dict(state['model'])
        self.optimizer.load_state_dict(state['optimizer'])
        self.updates = int(state['updates'])
