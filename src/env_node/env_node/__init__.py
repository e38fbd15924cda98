"""Atari Montezuma's Revenge (ALE) as a ROS 2 node: observations, agent position and /clock out, Joy actions in."""
