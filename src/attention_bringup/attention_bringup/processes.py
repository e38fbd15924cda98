"""
The node processes of one run: start them, watch them, stop them in escalating steps.

Each node runs in its own process group, so a Ctrl-C at the terminal reaches only the launcher,
which then sends exactly one SIGINT to every node (a second SIGINT could interrupt the tamer's
final checkpoint). On Linux every node also gets SIGTERM if the launcher dies: a small shim sets
``PR_SET_PDEATHSIG`` and then ``exec``s the node (no ``preexec_fn``, which is unsafe once the
launcher's own ROS threads run).
"""

import contextlib
from dataclasses import dataclass, field
import os
from pathlib import Path
import signal
import subprocess
import sys
import time
from typing import Callable, Dict, List, Mapping, Optional, Sequence, Tuple

from attention_bringup.plan import NodeCommand
from attention_common.isolation import isolated_environ, reserved_domain
from attention_common.teardown_watchdog import DUMP_HEADER

# argv: <launcher pid> <'idle' or 'normal'> <executable> <args...>. Exits if the launcher is
# already gone. 'idle': the idle scheduling class, which every thread of the node inherits.
_DIE_WITH_PARENT_SHIM = (
    'import ctypes, os, signal, sys\n'
    'ctypes.CDLL(None).prctl(1, int(signal.SIGTERM))  # PR_SET_PDEATHSIG\n'
    "if sys.argv[2] == 'idle':\n"
    '    os.sched_setscheduler(0, os.SCHED_IDLE, os.sched_param(0))\n'
    'sys.exit(1) if os.getppid() != int(sys.argv[1]) else os.execv(sys.argv[3], sys.argv[3:])\n'
)

LAST_STOP_S = 10.0
"""At least this long for the nodes stopped last (``NodeGroup.stop(last=...)``) to exit."""


def node_environ(domain_id: int, log_dir: Path) -> dict:
    """Return the environment of a node process: the isolated domain, plain unbuffered logs."""
    env = isolated_environ(domain_id)
    env.update({
        'PYTHONUNBUFFERED': '1',
        'RCUTILS_COLORIZED_OUTPUT': '0',
        'RCUTILS_LOGGING_BUFFERED_STREAM': '1',
        'ROS_LOG_DIR': str(Path(log_dir) / 'ros'),
    })
    return env


def executables_found(prog: str, commands: Sequence[NodeCommand]) -> bool:
    """Return whether every node executable is there; say which are not."""
    missing = [command.argv[0] for command in commands if not os.access(command.argv[0], os.X_OK)]
    if missing:
        sys.stderr.write(f'{prog}: node executables not found: {", ".join(missing)} '
                         '(run make setup)\n')
    return not missing


def run_graph(prog: str, commands: Sequence[NodeCommand], chosen: Optional[int],
              run: Callable[[int], int]) -> int:
    """
    Return ``run(domain_id)`` when every node executable is there, in the chosen ROS domain.

    ``chosen`` None: a domain reserved for this run (``attention_common.isolation``). Missing
    executables, or a run folder that is not empty (``FileExistsError``), are said and give 2.
    """
    if not executables_found(prog, commands):
        return 2
    domain = reserved_domain() if chosen is None else contextlib.nullcontext(chosen)
    with domain as domain_id:
        try:
            return run(domain_id)
        except FileExistsError as error:
            sys.stderr.write(f'{prog}: {error}\n')
            return 2


def dying_with_parent(argv: List[str], idle: bool = False) -> List[str]:
    """
    Return a command line that runs ``argv`` and gets SIGTERM when this process dies.

    ``idle``: in the idle scheduling class (SCHED_IDLE: it runs only on a core nothing else
    wants). Both are Linux's; elsewhere ``argv`` runs as it is.
    """
    if not sys.platform.startswith('linux'):
        return list(argv)
    return ([sys.executable, '-I', '-c', _DIE_WITH_PARENT_SHIM, str(os.getpid()),
             'idle' if idle else 'normal'] + list(argv))


def idle_this_process() -> None:
    """Put every thread of this process in the idle scheduling class (Linux; else nothing)."""
    if not sys.platform.startswith('linux'):
        return
    for tid in os.listdir('/proc/self/task'):
        with contextlib.suppress(ProcessLookupError):  # a thread that has just ended
            os.sched_setscheduler(int(tid), os.SCHED_IDLE, os.sched_param(0))


def exit_description(code: Optional[int]) -> str:
    if code is None:
        return 'still running'
    if code < 0:
        try:
            return f'killed by {signal.Signals(-code).name}'
        except ValueError:
            return f'killed by signal {-code}'
    return f'exit code {code}'


def log_tail(path: Path, lines: int = 20) -> str:
    """Return the last ``lines`` lines of a log file ('' if there is none)."""
    try:
        with open(path, 'rb') as log:
            log.seek(0, os.SEEK_END)
            log.seek(max(0, log.tell() - 64 * 1024))
            text = log.read().decode(errors='replace')
    except OSError:
        return ''
    return '\n'.join(text.splitlines()[-lines:])


def resident_memory_kb(pid: int) -> Dict[str, int]:
    """Return the resident memory (VmRSS) and its peak (VmHWM) of a process, in kB."""
    values = {}
    try:
        with open(f'/proc/{pid}/status') as status:
            for line in status:
                key, _, rest = line.partition(':')
                if key in ('VmRSS', 'VmHWM'):
                    values[key] = int(rest.split()[0])
    except (OSError, ValueError, IndexError):
        pass
    return values


def is_running(pid: int) -> bool:
    """Tell whether a process runs (a zombie, exited but not yet reaped, does not)."""
    try:
        with open(f'/proc/{pid}/stat') as stat:
            return stat.read().rsplit(')', 1)[1].split()[0] != 'Z'
    except OSError:
        return False


def cpu_seconds(pid: int) -> Optional[float]:
    """Return the CPU time (user + system) a process has used so far, from /proc."""
    try:
        with open(f'/proc/{pid}/stat') as stat:
            fields = stat.read().rsplit(')', 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')
    except (OSError, ValueError, IndexError):
        return None


@dataclass
class NodeProcess:
    """One running node."""

    command: NodeCommand
    process: subprocess.Popen
    log_file: object
    stopped_with: List[str] = field(default_factory=list)
    """Signals the launcher sent, in order."""

    @property
    def name(self) -> str:
        return self.command.name

    @property
    def pid(self) -> int:
        return self.process.pid

    def poll(self) -> Optional[int]:
        return self.process.poll()

    def signal(self, sig: signal.Signals) -> None:
        if self.process.poll() is None:
            self.stopped_with.append(sig.name)
            try:
                self.process.send_signal(sig)
            except ProcessLookupError:
                pass


class NodeGroup:
    """The node processes of a run, started one by one."""

    def __init__(self, env: Mapping[str, str]):
        self.env = dict(env)
        self.nodes: List[NodeProcess] = []

    def start(self, command: NodeCommand) -> NodeProcess:
        command.log_path.parent.mkdir(parents=True, exist_ok=True)
        log_file = open(command.log_path, 'wb')
        process = subprocess.Popen(
            dying_with_parent(command.argv, command.idle), stdin=subprocess.DEVNULL,
            stdout=log_file, stderr=subprocess.STDOUT, env=self.env, process_group=0)
        node = NodeProcess(command, process, log_file)
        self.nodes.append(node)
        return node

    def pids(self) -> Dict[str, int]:
        return {node.name: node.pid for node in self.nodes}

    def first_exited(self) -> Optional[NodeProcess]:
        """Return a node that has exited (whatever its code), or None."""
        for node in self.nodes:
            if node.poll() is not None:
                return node
        return None

    def running(self) -> List[NodeProcess]:
        return [node for node in self.nodes if node.poll() is None]

    def wait(self, deadline_s: float) -> bool:
        """Wait until every node has exited or ``deadline_s`` passes; True if all exited."""
        end = time.monotonic() + deadline_s
        while self.running() and time.monotonic() < end:
            time.sleep(0.05)
        return not self.running()

    def stop(self, sigint_timeout: float = 30.0, sigterm_timeout: float = 5.0,
             escalate=lambda: False, last: Sequence[str] = ()) -> Dict[str, Optional[int]]:
        """
        SIGINT every node, then SIGTERM and SIGKILL the ones still running after a deadline.

        The nodes named in ``last`` (the recorder) get their SIGINT once the others have
        exited, so they hear everything the others still say. ``escalate()`` returning True (a
        second Ctrl-C) cuts the SIGINT wait short.
        """
        end = time.monotonic() + sigint_timeout
        for index, group in enumerate(([n for n in self.running() if n.name not in last],
                                       [n for n in self.running() if n.name in last])):
            if index:  # the last ones get a deadline of their own
                end = max(end, time.monotonic() + min(sigint_timeout, LAST_STOP_S))
            for node in group:
                node.signal(signal.SIGINT)
            while (any(n.poll() is None for n in group) and time.monotonic() < end
                   and not escalate()):
                time.sleep(0.05)
        for sig, timeout in ((signal.SIGTERM, sigterm_timeout), (signal.SIGKILL, 5.0)):
            if not self.running():
                break
            for node in self.running():
                node.signal(sig)
            self.wait(timeout)
        for node in self.nodes:
            node.log_file.close()
        return self.exit_codes()

    def exit_codes(self) -> Dict[str, Optional[int]]:
        return {node.name: node.poll() for node in self.nodes}

    def interrupted_or_dead(self, interrupted: bool, say: Callable[[str], None],
                            program: str) -> Optional[Tuple[str, Optional[str]]]:
        """
        Return ('interrupted', None) after a Ctrl-C, ('node_failed', node) when a node died.

        A death is said once, through ``say``, with the last lines of the node's log; None
        while the run goes on.
        """
        if interrupted:
            return 'interrupted', None
        dead = self.first_exited()
        if dead is None:
            return None
        tail = log_tail(dead.command.log_path)
        indented = '\n'.join('    ' + line for line in tail.splitlines()) or '    (empty log)'
        say(f'{program}: {dead.name} died ({exit_description(dead.poll())}); the last lines '
            f'of {dead.command.log_path}:\n{indented}\n{program}: stopping the other nodes.\n')
        return 'node_failed', dead.name

    def wait_ready(self, ready: Callable[[], bool], timeout_s: float,
                   ended: Callable[[], Optional[tuple]]) -> Optional[Tuple[str, Optional[str]]]:
        """Wait until ``ready()``: None, else ``ended()``'s result or ('stalled', None)."""
        deadline = time.monotonic() + timeout_s
        while not ready():
            result = ended()
            if result:
                return result
            if time.monotonic() > deadline:
                return 'stalled', None
            time.sleep(0.05)
        return None

    def teardown_hangs(self) -> List[str]:
        """Return the nodes whose teardown watchdog fired (its stack dump ends their log)."""
        return [node.name for node in self.nodes
                if any(line.startswith(DUMP_HEADER)
                       for line in log_tail(node.command.log_path, 60).splitlines())]
