"""
Credit by prediction: which step of a window a late feedback was about, asked of H itself.

A person's feedback arrives 0.2-4 s after what it judges, with no stamp; the credit window
(``credit.window_credit``) spreads it over every step of that time, in proportion to the prior
probability of the delay. Most of those steps did something else than the judged one (in Room 1
with the human-like teacher only 37 % of the credit lands on steps that did what was judged), so
the label of a good action is mostly the verdict on other actions.

Here the delay is a latent variable, and its posterior given the feedback is the credit (the
E-step of EM): step j of a window gets

    w_j  proportional to  prior_j * P(h | s_j, a_j),   P(h | s, a) = noise + (1 - 2 noise) q

where q = (1 + sign(h) * clip(H(s, a), -1, 1)) / 2 is H's probability that a trainer judging
(s_j, a_j) gives h's sign, and ``noise`` the probability that a verdict has the wrong sign. The
weights of one feedback keep their prior total (the window's mass), so a feedback counts as much
as before; only where it lands changes. While H knows nothing (H = 0 everywhere) the posterior
is the prior: the plain window. As H learns, a +1 goes to the steps that did something H
believes good, which is what the trainer most likely judged (the M-step is the learner's next
updates on those weights). ``noise`` bounds how far one prediction can move credit: at 0.1 a
step is at most 9 times likelier than another of equal prior.

Pure numpy; the learner thread calls it on new samples (pairing.py) and on the whole buffer
every ``credit_refit_updates`` updates (buffer.py), as H changes.
"""

import numpy as np


def feedback_likelihood(h: np.ndarray, predicted: np.ndarray, noise: float) -> np.ndarray:
    """P(sign of h | H's prediction) per sample; h = 0 (no sign) is equally likely anywhere."""
    if not 0.0 <= noise < 0.5:
        raise ValueError(f'noise must be in [0, 0.5), got {noise}')
    h = np.asarray(h, np.float64)
    q = 0.5 * (1.0 + np.sign(h) * np.clip(np.asarray(predicted, np.float64), -1.0, 1.0))
    return noise + (1.0 - 2.0 * noise) * q


def posterior_weights(priors: np.ndarray, likelihoods: np.ndarray,
                      groups: np.ndarray) -> np.ndarray:
    """
    Return prior * likelihood, normalized to each group's prior total (float32).

    ``groups`` names the feedback each sample came from (its seq): samples of one feedback are
    the candidate steps of one latent delay.
    """
    priors = np.asarray(priors, np.float64)
    joint = priors * np.asarray(likelihoods, np.float64)
    _, index = np.unique(np.asarray(groups), return_inverse=True)
    prior_mass = np.bincount(index, weights=priors)
    joint_mass = np.bincount(index, weights=joint)
    scale = np.divide(prior_mass, joint_mass, out=np.zeros_like(prior_mass),
                      where=joint_mass > 0)
    return (joint * scale[index]).astype(np.float32)
