"""The suite's own scheduling: the files it runs first are files it has."""

from pathlib import Path

from conftest import LONGEST_FIRST


def test_every_file_scheduled_first_exists_and_is_named_once():
    here = Path(__file__).resolve().parent
    assert [name for name in LONGEST_FIRST if not (here / name).is_file()] == []
    assert len(set(LONGEST_FIRST)) == len(LONGEST_FIRST)
