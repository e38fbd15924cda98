"""
Test harness for topic-level tests: real node processes and a probe node that talks to them.

Every wait has a deadline; nothing here sleeps for a fixed time to let things "settle".
"""

import json
import os
from pathlib import Path
import signal
import socket
import subprocess
import sys
import threading
import time
from typing import Callable, Dict, List, Optional

import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor

BIN = Path(sys.executable).parent


def read_json(path: Path) -> dict:
    """Return the JSON file at ``path``."""
    return json.loads(path.read_text())


def progress_rows(run_dir: Path) -> int:
    """Return the rows a run has written to its ``progress.csv`` so far (0 before the file)."""
    try:
        with open(run_dir / 'progress.csv') as progress:
            return sum(1 for _ in progress) - 1
    except OSError:
        return 0


def wait_until(predicate: Callable[[], bool], timeout: float, interval: float = 0.01) -> bool:
    """Poll ``predicate`` until it is true or ``timeout`` seconds pass; return its last value."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(interval)
    return bool(predicate())


def thread_niceness(pid: int) -> Dict[int, int]:
    """Return each thread's niceness (tid -> nice) of process ``pid``."""
    niceness = {}
    for task in Path(f'/proc/{pid}/task').iterdir():
        fields = (task / 'stat').read_text().rsplit(')', 1)[1].split()
        niceness[int(task.name)] = int(fields[16])  # field 19 of stat: nice
    return niceness


def _format_param(value) -> str:
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, str):
        return f"'{value}'"  # quoted: YAML would read on/off/yes/no as booleans
    return str(value)


def listening_sockets() -> set:
    """Return the (address, port) of every listening TCP socket on this machine."""
    found = set()
    for name in ('/proc/net/tcp', '/proc/net/tcp6'):
        with open(name) as table:
            for line in list(table)[1:]:
                fields = line.split()
                if fields[3] == '0A':  # LISTEN
                    address, port = fields[1].split(':')
                    found.add((address, int(port, 16)))
    return found


def loopback_address(hex_address: str) -> bool:
    """Tell a /proc/net address on loopback (127.x, ::1, ::ffff:127.x) from any other."""
    if len(hex_address) == 8:  # IPv4, its bytes reversed: 127.0.0.1 is 0100007F
        return hex_address.endswith('7F')
    mapped_v4 = hex_address.startswith('0000000000000000FFFF0000')
    return (hex_address == '00000000000000000000000001000000'
            or mapped_v4 and hex_address.endswith('7F'))


def free_port() -> int:
    """Return a TCP port free on 127.0.0.1 now (for a server a test or script starts)."""
    with socket.socket() as probe:
        probe.bind(('127.0.0.1', 0))
        return probe.getsockname()[1]


class NodeProcess:
    """A node executable from the venv, run as its own process with its log in a file."""

    def __init__(self, executable: str, params: Dict[str, object], log_dir: Path,
                 ros_args=(), name: Optional[str] = None):
        self.executable = executable
        self.name = name or executable
        self.log_path = Path(log_dir) / f'{self.name}.log'
        command = [str(BIN / executable), '--ros-args']
        for key, value in params.items():
            command += ['-p', f'{key}:={_format_param(value)}']
        command += list(ros_args)
        self.command = command
        self._log = open(self.log_path, 'wb')
        self.process = subprocess.Popen(
            command, stdout=self._log, stderr=subprocess.STDOUT, env=dict(os.environ))

    def alive(self) -> bool:
        return self.process.poll() is None

    def log_text(self) -> str:
        if not self._log.closed:
            self._log.flush()
        return self.log_path.read_text(errors='replace')

    def wait_for_log(self, text: str, timeout: float) -> bool:
        return wait_until(lambda: text in self.log_text(), timeout, interval=0.05)

    def stop(self, sig=signal.SIGINT, timeout: float = 15.0) -> int:
        """Send ``sig`` and return the exit code (killing it if it outlives ``timeout``)."""
        if self.alive():
            self.process.send_signal(sig)
        try:
            code = self.process.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()
            raise AssertionError(f'{self.name} did not exit within {timeout}s of {sig!r}\n'
                                 + self.log_text()[-3000:])
        finally:
            self._log.close()
        return code

    def kill_if_running(self) -> None:
        if self.alive():
            self.process.kill()
            self.process.wait()
        if not self._log.closed:
            self._log.close()


class MessageLog:
    """Messages received on one subscription, with deadline-bound waits."""

    def __init__(self):
        self.messages: List[object] = []
        self.subscription = None  # set by TopicProbe.subscribe
        self._cond = threading.Condition()

    def append(self, msg) -> None:
        with self._cond:
            self.messages.append(msg)
            self._cond.notify_all()

    def wait_for(self, predicate: Callable[[List[object]], bool], timeout: float) -> bool:
        """Wait until ``predicate(messages)`` holds; return whether it did before the deadline."""
        with self._cond:
            return self._cond.wait_for(lambda: predicate(self.messages), timeout)

    def wait_count(self, count: int, timeout: float) -> bool:
        return self.wait_for(lambda m: len(m) >= count, timeout)

    def snapshot(self) -> List[object]:
        with self._cond:
            return list(self.messages)


class TopicProbe:
    """A probe node in its own rclpy Context, its executor spinning on a thread."""

    def __init__(self, name: str = 'test_probe'):
        self.context = Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node(name, context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self._thread = threading.Thread(target=self._spin, daemon=True)
        self._thread.start()

    def _spin(self) -> None:
        try:
            self.executor.spin()
        except Exception:  # shutdown while spinning
            pass

    def subscribe(self, msg_type, topic: str, qos) -> MessageLog:
        log = MessageLog()
        log.subscription = self.node.create_subscription(msg_type, topic, log.append, qos)
        return log

    def publisher(self, msg_type, topic: str, qos):
        return self.node.create_publisher(msg_type, topic, qos)

    def wait_for_subscribers(self, publisher, count: int = 1, timeout: float = 10.0) -> bool:
        return wait_until(lambda: publisher.get_subscription_count() >= count, timeout)

    def wait_for_publishers(self, topic: str, count: int = 1, timeout: float = 10.0) -> bool:
        return wait_until(lambda: self.node.count_publishers(topic) >= count, timeout)

    @staticmethod
    def wait_matched(log: 'MessageLog', count: int = 1, timeout: float = 10.0) -> bool:
        """Wait until ``count`` writers are matched to the subscription behind ``log``."""
        return wait_until(lambda: log.subscription.get_publisher_count() >= count, timeout)

    def close(self) -> None:
        self.executor.shutdown(timeout_sec=1.0)
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)
        self._thread.join(timeout=5.0)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
