"""A feedback line is synced to disk (fdatasync) before its receipt goes out (``sync``)."""

import json
import os
import threading

from attention_common.run_files import FEEDBACK_LOG
from harness import wait_until
import pytest
from tamer_node.config import TamerConfig
from tamer_node.persistence import FeedbackLog
from test_tamer_agent import agents, play, stamp  # noqa: F401 - the fixture


@pytest.fixture
def synced(monkeypatch):
    """Record, at every fdatasync, how many bytes of each file it made durable."""
    durable = {}
    real = os.fdatasync

    def fdatasync(fd):
        real(fd)
        durable[os.readlink(f'/proc/self/fd/{fd}')] = os.fstat(fd).st_size

    monkeypatch.setattr(os, 'fdatasync', fdatasync)
    return durable


def _end_of_line(path, text):
    """Return the byte offset just past the log line that contains ``text``."""
    data = path.read_bytes()
    return data.index(text.encode()) + data[data.index(text.encode()):].index(b'\n') + 1


@pytest.mark.parametrize('sync', ['every', 'grouped'])
def test_every_receipt_follows_the_sync_of_its_line(agents, tmp_path, synced, sync):  # noqa: F811
    agent = agents(sync=sync)
    log = str(tmp_path / 'run' / FEEDBACK_LOG)
    late = []  # receipts sent before their line was durable

    def receipt(entry):
        marker = f'"seq": {entry["seq"]},' if entry['kind'] == 'feedback' else entry['text']
        if synced.get(log, 0) < _end_of_line(tmp_path / 'run' / FEEDBACK_LOG, marker):
            late.append(entry)
        got.append(entry)

    got = []
    agent.on_logged = receipt
    play(agent, 5)
    for i in range(60):  # a burst, as a person's key held down would give
        agent.on_feedback(1.0, 'stamped', stamp(i % 5))
    agent.on_utterance('climb down the ladder')
    assert wait_until(lambda: len(got) == 61, 10)
    assert late == []
    syncs = agent.metrics()['disk/feedback_syncs']
    assert 1 <= syncs <= 61 and (sync == 'grouped' or syncs >= 61)


def test_grouped_lines_share_one_sync_and_wait_at_most_the_group_time(tmp_path, synced):
    log = FeedbackLog(tmp_path / 'log.jsonl', 'grouped')
    sent = []
    for i in range(3):
        log.append({'seq': i}, lambda i=i: sent.append(i))
    assert sent == [] and log.syncs == 0  # waiting for the disk thread's commit
    log.commit()
    assert sent == [0, 1, 2] and log.syncs == 1
    log.commit()
    assert log.syncs == 1  # nothing new: no sync
    log.close()


def test_off_sends_receipts_at_once_without_a_sync(tmp_path, synced):
    log = FeedbackLog(tmp_path / 'log.jsonl', 'off')
    sent = []
    log.append({'seq': 1}, lambda: sent.append(1))
    log.commit()
    log.close()
    assert sent == [1] and log.syncs == 0 and synced == {}
    assert json.loads((tmp_path / 'log.jsonl').read_text()) == {'seq': 1}


def test_a_failed_sync_sends_no_receipt_and_keeps_the_line(tmp_path, monkeypatch):
    log = FeedbackLog(tmp_path / 'log.jsonl', 'every')

    def broken(fd):
        raise OSError(5, 'Input/output error')

    monkeypatch.setattr(os, 'fdatasync', broken)
    sent = []
    with pytest.raises(OSError):
        log.append({'seq': 1}, lambda: sent.append(1))
    assert sent == []
    assert json.loads((tmp_path / 'log.jsonl').read_text()) == {'seq': 1}
    monkeypatch.undo()
    log.close()


def test_the_sync_parameter_is_checked():
    with pytest.raises(ValueError, match='sync must be one of'):
        TamerConfig(sync='sometimes').validate()
    assert TamerConfig().sync == 'grouped'  # a person's feedback survives a power cut


def test_a_receipt_is_never_held_back_by_the_group_when_the_disk_thread_idles(tmp_path):
    log = FeedbackLog(tmp_path / 'log.jsonl', 'grouped')
    from tamer_node.persistence import DiskWriter, StepJournal
    disk = DiskWriter(StepJournal(tmp_path / 'steps'), print, when_idle=log.commit)
    disk.start()
    sent = threading.Event()
    disk.submit(lambda: log.append({'seq': 1}, sent.set))
    assert sent.wait(5)  # the queue emptied: committed at once
    disk.stop()
    log.close()
