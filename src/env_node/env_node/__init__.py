"""Atari Montezuma's Revenge (ALE) as a ROS 2 node: frames and RAM state out, Joy in."""
