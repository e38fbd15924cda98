"""Deep TAMER learner with the saliency L2 loss; acts greedily and trains asynchronously."""
