"""Launcher, parameter files, launch file and benchmarks of the language-attention TAMER graph."""
