"""Language-guided template matching: utterances into saliency images (kept objects sharp, the rest blurred)."""
