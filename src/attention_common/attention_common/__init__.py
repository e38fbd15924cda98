"""
Shared pieces of the language-attention TAMER graph.

Topic names, QoS profiles, Image/numpy conversion, Joy/ALE action mapping, stamps, network
isolation and the nodes' shared ``main()``.
"""
