"""
A study's trials as Ray tasks (``--backend ray``): one trial, one task, on any node of a cluster.

A trial is a whole graph of 4-5 processes in a ROS domain of its own (its launcher reserves one
on the node it runs on), so a task asks for no CPU of Ray's accounting but for one unit of the
``attention_graph`` resource, which says how many graphs a node holds (``ray start
--resources '{"attention_graph": 2}'``). The worker runs ``attention_train`` exactly as the
local backend does, the run folder on its own disk, and returns the trial's result record; the
driver writes the result file, so a study resumes the same way on either backend. Ray's retries
are off: a crashed trial is recorded as crashed and run again only with ``--retry-crashed``.
On Ctrl-C the driver tells every task (an actor holds the flag), and each one stops its
launcher (one SIGINT: it stops its nodes cleanly) before it ends. See docs/cluster.md.
"""

import os
import threading
import time
from typing import Callable, List, Optional, Sequence

from attention_bringup.experiment import runner
from attention_bringup.experiment.trials import write_json

GRAPH_RESOURCE = 'attention_graph'
LOOPBACK = {'RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER': '0'}
"""On Linux, Ray binds the machine's network address unless this is set: with it, a cluster
started here stays on 127.0.0.1 (the network rule). The study sets it unless it is set already;
=1 is Ray's own Linux default, how docs/cluster.md opens a cluster up on purpose."""
CANCEL_GRACE_S = runner.STOP_GRACE_S + 30.0
"""After a Ctrl-C, how long the driver waits for every trial to stop its graph (then it
cancels what is left)."""


class _StopFlag:
    """The study's Ctrl-C, told to every task (a Ray actor: tasks ask it twice a second)."""

    def __init__(self):
        self.stopped = False

    def stop(self) -> None:
        self.stopped = True

    def asked(self) -> bool:
        return self.stopped


def _trial_on_worker(job: runner.TrialJob, timeout_s: float, flag) -> Optional[dict]:
    """Run one trial on this Ray worker; once the study stops, stop its launcher first."""
    import ray
    launcher = runner.launcher_path()
    stop, box = threading.Event(), {}
    thread = threading.Thread(
        target=lambda: box.update(record=runner.run_trial(job, launcher, stop, timeout_s,
                                                          write=False)),
        name='trial', daemon=True)
    thread.start()
    while thread.is_alive():
        try:
            thread.join(timeout=0.5)
            if not stop.is_set() and ray.get(flag.asked.remote()):
                stop.set()  # SIGINT to the launcher; the task ends once its graph has
        except KeyboardInterrupt:  # ray.cancel: the same
            stop.set()
    return box.get('record')


def run_trials(jobs: Sequence[runner.TrialJob], address: str, timeout_s: float,
               stop: threading.Event,
               report: Callable[[runner.TrialJob, Optional[dict], int], None]) -> List[dict]:
    """Run ``jobs`` on the Ray cluster at ``address`` until done or ``stop`` is set."""
    for name, value in LOOPBACK.items():  # kept as the user set it: a cluster opened up
        os.environ.setdefault(name, value)
    import ray
    ray.init(address=address, logging_level='WARNING', log_to_driver=False)
    try:
        if not ray.cluster_resources().get(GRAPH_RESOURCE):
            raise ValueError(f'the Ray cluster at {address} has no {GRAPH_RESOURCE!r} resource: '
                             f'start its nodes with --resources \'{{"{GRAPH_RESOURCE}": N}}\' '
                             '(docs/cluster.md)')
        task = ray.remote(num_cpus=0, resources={GRAPH_RESOURCE: 1}, max_retries=0)(
            _trial_on_worker)
        flag = ray.remote(num_cpus=0)(_StopFlag).remote()
        pending = {task.remote(job, timeout_s, flag): job for job in jobs}
        records: List[dict] = []
        stopped_at = None
        while pending:
            if stop.is_set() and stopped_at is None:
                # Not ray.cancel: a cancelled task counts as done at once, while its graph is
                # still stopping; each task ends only once its launcher has stopped its nodes.
                stopped_at = time.monotonic()
                ray.get(flag.stop.remote())
            if stopped_at is not None and time.monotonic() - stopped_at > CANCEL_GRACE_S:
                for ref in pending:
                    ray.cancel(ref)
                break
            done, _ = ray.wait(list(pending), num_returns=1, timeout=0.5)
            for ref in done:
                job = pending.pop(ref)
                try:
                    record = ray.get(ref)
                except (ray.exceptions.TaskCancelledError, ray.exceptions.RayTaskError,
                        ray.exceptions.WorkerCrashedError):
                    record = None
                if record is not None:
                    write_json(job.result_path, record)
                    records.append(record)
                report(job, record, len(records))
        return records
    finally:
        ray.shutdown()
