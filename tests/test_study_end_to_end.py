"""``attention_study`` with the real launcher and node graph: one short trial, then a resume."""

import json
from pathlib import Path
import subprocess
import sys

import pytest

STUDY = str(Path(sys.executable).parent / 'attention_study')
STEPS = 200


@pytest.mark.topics
@pytest.mark.slow
def test_one_real_trial_then_resume_skips_it(tmp_path):
    out, report = tmp_path / 'study', tmp_path / 'results.md'
    command = [STUDY, '--conditions', 'vanilla', '--trials', '1', '--steps', str(STEPS),
               '--out', str(out), '--report', str(report)]
    first = subprocess.run(command, capture_output=True, text=True, timeout=280)
    assert first.returncode == 0, first.stderr[-3000:]
    record = json.loads((out / 'trials' / 'vanilla' / 'seed0.json').read_text())
    assert record['outcome'] == 'completed', record['problem']
    assert record['steps'] == STEPS and record['seed'] == 0
    assert record['parameters']['env_node.seed'] == 0
    assert record['parameters']['tamer_node.alpha'] == 0.0
    assert record['parameters']['saliency_node.mode'] == 'off'
    assert record['episodes'] >= 1 and record['feedback_count'] > 0
    assert len(record['furthest_curve']) == STEPS // 100 + 1
    assert (out / 'runs' / 'vanilla' / 'seed0' / 'summary.json').exists()
    text = report.read_text()
    assert '| `vanilla` | 1/1 | none |' in text and 'figure_5_3.png' in text
    log = json.loads((out / 'study_log.json').read_text())
    assert [entry['trials_run'] for entry in log] == [1]

    again = subprocess.run(command, capture_output=True, text=True, timeout=60)
    assert again.returncode == 0, again.stderr[-3000:]
    assert '1 trial(s) already have results: skipped' in again.stderr
    assert len(json.loads((out / 'study_log.json').read_text())) == 1
