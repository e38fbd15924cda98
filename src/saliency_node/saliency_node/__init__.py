"""
Language-guided template matching: utterances into saliency images.

The objects an utterance names (and the agent) stay sharp, the rest is blurred.
"""
