"""The study of issue 15: the six conditions on DoorKey, a world that changes every episode."""
