"""The DoorKey-with-distractors task (MiniGrid): world, expert, progress and sentences."""
