"""Launcher, parameter files, launch file and study runner for the language-attention TAMER graph."""
