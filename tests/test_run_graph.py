"""``processes.run_graph``: how the launcher and the replay start a run (pure, no ROS)."""

import sys

from attention_bringup.plan import NodeCommand
from attention_bringup.processes import run_graph


def commands(*argv0):
    return [NodeCommand(f'node{i}', [path], None) for i, path in enumerate(argv0)]


def test_a_run_goes_in_the_chosen_domain_or_one_reserved_for_it():
    here = commands(sys.executable)
    assert run_graph('prog', here, 42, lambda domain: domain) == 42
    reserved = run_graph('prog', here, None, lambda domain: domain)
    assert 1 <= reserved <= 100


def test_missing_executables_are_named_and_nothing_runs(capsys):
    ran = []
    code = run_graph('prog', commands(sys.executable, '/no/such/env_node'), 7,
                     lambda domain: ran.append(domain) or 0)
    assert (code, ran) == (2, [])
    assert 'prog: node executables not found: /no/such/env_node (run make setup)' in (
        capsys.readouterr().err)


def test_a_run_folder_in_use_is_said_and_gives_2(capsys):
    def run(domain):
        raise FileExistsError('runs/x is not empty; choose another --run-dir')

    assert run_graph('prog', commands(sys.executable), 7, run) == 2
    assert 'prog: runs/x is not empty; choose another --run-dir' in capsys.readouterr().err
