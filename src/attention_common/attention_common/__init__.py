"""Shared pieces of the language-attention TAMER graph: topic names, QoS profiles, Image/numpy conversion, Joy/ALE action mapping, stamps, network isolation."""
