"""
``attention_experiment SPEC --backend ray`` on a real local Ray cluster, against the local backend.

The cluster is a head and one more node, each with one unit of the graph resource, on
loopback. The spec: 2 arms x 1 seed of 300-step trials. Also: Ctrl-C during a study on either
backend leaves no process of the graph.
"""

import json
import os
from pathlib import Path
import signal
import subprocess
import sys
import time

from attention_bringup.experiment.ray_backend import GRAPH_RESOURCE, LOOPBACK
from attention_bringup.processes import is_running
from harness import listening_sockets, loopback_address, wait_until
import pytest
import yaml

STUDY = str(Path(sys.executable).parent / 'attention_study')
EXPERIMENT = str(Path(sys.executable).parent / 'attention_experiment')
STEPS = 300
SAME_FIELDS = ('condition', 'seed', 'budget', 'outcome', 'steps', 'parameters', 'trainer')
"""What a trial's result file says whichever backend ran it (times and folders differ)."""


@pytest.fixture(scope='module')
def cluster():
    os.environ.update(LOOPBACK)
    before = listening_sockets()
    from ray.cluster_utils import Cluster
    ray_cluster = Cluster(initialize_head=True, head_node_args={
        'num_cpus': 1, 'resources': {GRAPH_RESOURCE: 1}, 'include_dashboard': False})
    ray_cluster.add_node(num_cpus=1, resources={GRAPH_RESOURCE: 1})
    ray_cluster.opened = listening_sockets() - before
    yield ray_cluster
    ray_cluster.shutdown()


@pytest.mark.topics
def test_the_ray_cluster_listens_on_loopback_only(cluster):
    assert cluster.address.startswith('127.0.0.1:')
    assert cluster.opened, 'the cluster opened no listening socket?'
    assert [s for s in cluster.opened if not loopback_address(s[0])] == []


def _study(out: Path, *extra: str) -> subprocess.CompletedProcess:
    """Run a 2-arm x 1-seed spec of the thesis's study, its folders under ``out``."""
    out.mkdir(parents=True)
    spec = out / 'spec.yaml'
    spec.write_text(yaml.safe_dump({
        'name': 'two_by_two', 'plugin': 'thesis', 'budget': STEPS, 'seeds': [1],
        'out': str(out), 'report': str(out / 'results.md'), 'runs_dir': str(out / 'runs'),
        'launcher_args': ['--trainer', 'thesis'],
        'arms': [{'name': 'vanilla'}, {'name': 'language'}]}))
    return subprocess.run([EXPERIMENT, str(spec), *extra], capture_output=True, text=True,
                          timeout=600)


def _records(out: Path) -> dict:
    return {(path.parent.name, path.stem): json.loads(path.read_text())
            for path in sorted((out / 'trials').glob('*/seed*.json'))}


@pytest.mark.topics
@pytest.mark.slow
def test_a_study_on_ray_writes_what_the_local_backend_writes(cluster, tmp_path):
    on_ray = _study(tmp_path / 'ray', '--backend', 'ray', '--address', cluster.address)
    assert on_ray.returncode == 0, on_ray.stderr[-4000:]
    local = _study(tmp_path / 'local', '--parallel', '2')
    assert local.returncode == 0, local.stderr[-4000:]
    ray_records, local_records = _records(tmp_path / 'ray'), _records(tmp_path / 'local')
    assert sorted(ray_records) == sorted(local_records) == [
        ('language', 'seed1'), ('vanilla', 'seed1')]
    for key, record in ray_records.items():
        assert record['outcome'] == 'completed', record['problem']
        assert ({f: record[f] for f in SAME_FIELDS}
                == {f: local_records[key][f] for f in SAME_FIELDS}), key
    for out in ('ray', 'local'):
        analysis = json.loads((tmp_path / out / 'analysis.json').read_text())
        assert {c: s['usable'] for c, s in analysis['conditions'].items()} == {
            'vanilla': 1, 'language': 1}
        assert '| `vanilla` | 1/1 |' in (tmp_path / out / 'results.md').read_text()
        # Every node stopped at its SIGINT: a Ray worker's threads block SIGINT, and the
        # launcher and its nodes inherited that mask (each needed SIGTERM, 10 s later).
        summary = json.loads((tmp_path / out / 'runs' / 'vanilla' / 'seed1' /
                              'summary.json').read_text())
        assert set(map(tuple, summary['signals_sent'].values())) == {('SIGINT',)}, out
        # The run ended as soon as the learner had logged what the trainer gave: before the
        # learner counted its lines, a busy machine lost the first receipts and every trial
        # waited out the launcher's 60 s drain.
        for arm in ('vanilla', 'language'):
            said = (tmp_path / out / 'runs' / arm / 'seed1' / 'attention_train.log').read_text()
            assert 'stopping the nodes although' not in said, (out, arm, said)
    log = json.loads((tmp_path / 'ray' / 'study_log.json').read_text())
    assert log[-1]['backend'] == 'ray' and log[-1]['trials_run'] == 2


def _interrupt_and_check(argv, run_dir: Path, result_file: Path) -> None:
    """Ctrl-C a study command mid-trial: it stops every process of the graph and says so."""
    study = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert wait_until(lambda: (run_dir / 'progress.csv').exists() and
                          len((run_dir / 'progress.csv').read_text().splitlines()) > 20
                          or study.poll() is not None, 180), 'the trial did not start'
        assert study.poll() is None, study.communicate()[1][-3000:]
        pids = json.loads((run_dir / 'pids.json').read_text())
        study.send_signal(signal.SIGINT)
        _, stderr = study.communicate(timeout=200)
    finally:
        if study.poll() is None:
            study.kill()
    assert study.returncode == 130, stderr[-3000:]
    graph = {name: pid for name, pid in pids.items() if name != 'domain_id'}
    assert len(graph) >= 5  # the launcher and its four nodes
    time.sleep(1.0)
    assert [name for name, pid in graph.items() if is_running(pid)] == []
    # The launcher stopped its graph itself (not killed with its Ray worker): its run folder
    # says so, every node stopped at its SIGINT.
    summary = json.loads((run_dir / 'summary.json').read_text())
    assert summary['status'] == 'interrupted'
    assert set(summary['exit_codes'].values()) == {0}, summary['exit_text']
    assert not result_file.exists()  # runs again next time


@pytest.mark.topics
@pytest.mark.parametrize('backend', ['local', 'ray'])
def test_ctrl_c_during_a_study_leaves_no_process_of_the_graph(cluster, tmp_path, backend):
    out = tmp_path / 'study'
    extra = ['--backend', 'ray', '--address', cluster.address] if backend == 'ray' else []
    _interrupt_and_check(
        [STUDY, '--conditions', 'vanilla', '--trials', '1', '--steps', '100000', '--out',
         str(out), '--report', str(out / 'results.md'), *extra],
        out / 'runs' / 'vanilla' / 'seed0', out / 'trials' / 'vanilla' / 'seed0.json')


@pytest.mark.topics
@pytest.mark.parametrize('command', ['attention_experiment', 'attention_teaching'])
def test_ctrl_c_during_the_other_studies_leaves_no_process_of_the_graph(tmp_path, command):
    # attention_study_minigrid and attention_teaching used to re-raise Ctrl-C around their
    # trial threads: the command died with a traceback and its launchers ran on. Every study
    # command now runs on the engine (attention_study_minigrid is the doorkey spec's wrapper).
    out = tmp_path / 'study'
    argv = [str(Path(sys.executable).parent / command), '--steps', '100000', '--out', str(out),
            '--report', str(out / 'report.md'), '--runs-dir', str(out / 'runs')]
    if command == 'attention_teaching':
        argv += ['--settings', 'every_step_vanilla', '--seeds', '1000']
        run_dir = out / 'runs' / 'every_step_vanilla' / 'vanilla' / 'seed1000'
        result = out / 'every_step_vanilla' / 'trials' / 'vanilla' / 'seed1000.json'
    else:
        argv[1:1] = ['doorkey']
        argv += ['--arms', 'vanilla', '--seeds', '0']
        run_dir = out / 'runs' / 'vanilla' / 'seed0'
        result = out / 'trials' / 'vanilla' / 'seed0.json'
    _interrupt_and_check(argv, run_dir, result)
