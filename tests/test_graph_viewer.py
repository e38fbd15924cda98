"""
graph_viewer, the Foxglove bridge.

Its pure parts, the shipped layout, and the real graph watched by a client speaking the
Foxglove WebSocket protocol (``foxglove.websocket.v1``).
"""

import asyncio
import csv
import json
import math
from pathlib import Path
import subprocess
import sys
import time

import aiohttp
from attention_tasks.task import load_task
from diagnostic_msgs.msg import DiagnosticArray
from foxglove_client import FoxgloveClient, SUBPROTOCOL
from graph_viewer.bag_plots import main as plots_main, PLOTS_FILE
from graph_viewer.config import ViewerConfig
from graph_viewer.forwarded import FORWARDED, RateLimit
from graph_viewer.layout import LAYOUT_FILE, layout_json, layout_topics, LICHTBLICK_FILE
from graph_viewer.lichtblick import to_lichtblick
from graph_viewer.plots import (action_values_record, env_status_record, metrics_record,
                                plot_topic, PLOTTED)
from graph_viewer.subprotocol import LEGACY, rewrite_request, rewrite_response, SDK
from harness import (free_port, listening_sockets, loopback_address, thread_niceness,
                     TopicProbe, wait_until)
from mcap.reader import make_reader
import pytest
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import Image

LAUNCHER = str(Path(sys.executable).parent / 'attention_train')
STEPS = 300
"""20 s of Room 1 in real time (15 Hz)."""


# The pure parts.
def test_metrics_become_numbers_nested_by_their_slashes():
    record = metrics_record(1_500_000_000, [
        ('train/loss', '0.25'), ('train/updates', '12'), ('act/latency_p50_ms', 'nan'),
        ('feedback/count', '3'), ('feedback', '7'), ('note/x', 'words')])
    assert record['stamp'] == {'sec': 1, 'nsec': 500_000_000}
    assert record['train'] == {'loss': 0.25, 'updates': 12}
    assert isinstance(record['train']['updates'], int)
    assert record['act'] == {'latency_p50_ms': None}  # JSON has no NaN: null, not a lie
    assert record['feedback'] == {'count': 3, 'value': 7}  # a key and its own prefix both kept
    assert record['note'] == {'x': 'words'}
    json.dumps(record, allow_nan=False)


def test_action_values_name_the_action_taken_and_every_h():
    record = action_values_record(10, 'UP', [('action', '2'), ('version', '5'), ('NOOP', '0.1'),
                                             ('FIRE', '-0.2'), ('UP', '0.4')])
    assert record['h'] == {'NOOP': 0.1, 'FIRE': -0.2, 'UP': 0.4}
    assert (record['action'], record['action_index'], record['version']) == ('UP', 2, 5)
    assert (record['h_taken'], record['h_best']) == (0.4, 0.4)
    with pytest.raises(ValueError):
        action_values_record(10, 'DOWN', [('action', '2'), ('version', '5'), ('UP', '0.4')])
    with pytest.raises(ValueError):
        action_values_record(10, 'UP', [('UP', '0.4')])


def test_env_status_is_typed_and_names_the_milestone():
    task = load_task('montezuma')
    record = env_status_record(7, [('agent_step', '42'), ('episode', '1'), ('lives', '5'),
                                   ('has_key', 'false'), ('room', '1'), ('x', '77'),
                                   ('y', '148')],
                               lambda values: task.milestone_of(values, 8.0))
    assert (record['agent_step'], record['lives'], record['has_key']) == (42, 5, False)
    assert record['milestone'] == task.milestone_of({'room': 1, 'x': 77, 'y': 148}, 8.0)


def test_images_are_forwarded_at_most_at_the_rate_asked():
    limit = RateLimit(30.0)
    passed = [t for t in (i / 200 for i in range(200)) if limit.allow(t)]  # 1 s at 200 Hz
    assert 29 <= len(passed) <= 31
    limit = RateLimit(30.0)
    assert all(limit.allow(i / 15) for i in range(15))  # real time passes whole


def test_the_bridge_is_loopback_unless_asked():
    with pytest.raises(ValueError, match='allow_remote'):
        ViewerConfig(host='0.0.0.0').validate()
    ViewerConfig(host='0.0.0.0', allow_remote=True).validate()
    ViewerConfig().validate()
    assert ViewerConfig().host == '127.0.0.1'


def test_a_client_of_the_protocols_first_name_is_renamed_for_the_sdk_and_back():
    head = (b'GET / HTTP/1.1\r\nHost: 127.0.0.1:8765\r\nSec-WebSocket-Key: abc==\r\n'
            b'sec-websocket-protocol: ' + LEGACY.encode() + b'\r\n\r\n')
    renamed, legacy = rewrite_request(head)
    assert legacy and renamed == head.replace(LEGACY.encode(), SDK.encode())
    both = head.replace(LEGACY.encode(), f'{SDK}, {LEGACY}'.encode())
    assert rewrite_request(both) == (both, False)  # the SDK's own name: untouched
    other = head.replace(LEGACY.encode(), b'chat')
    assert rewrite_request(other) == (other, False)  # not ours: the SDK refuses it as it is
    answer = (b'HTTP/1.1 101 Switching Protocols\r\nSec-WebSocket-Protocol: ' + SDK.encode()
              + b'\r\nSec-WebSocket-Accept: xyz=\r\n\r\n')
    assert rewrite_response(answer) == answer.replace(SDK.encode(), LEGACY.encode())


def test_the_shipped_layout_is_the_code_and_reads_only_served_channels():
    assert LAYOUT_FILE.read_text() == layout_json(), 'run graph_viewer_layout to refresh it'
    served = {'/' + topic.name for topic in FORWARDED}
    served |= {plot_topic('/' + name) for name in PLOTTED}
    read = layout_topics()
    assert {'/observation', '/saliency', '/feedback', '/plot/metrics'} <= read
    assert read <= served, read - served


def _mosaic_leaves(node) -> list:
    if isinstance(node, str):
        return [node]
    assert set(node) == {'first', 'second', 'direction', 'splitPercentage'}, node
    assert node['direction'] in ('row', 'column') and 0 < node['splitPercentage'] < 100
    return _mosaic_leaves(node['first']) + _mosaic_leaves(node['second'])


def test_the_lichtblick_layout_holds_every_panel_where_lichtblick_looks():
    assert LICHTBLICK_FILE.read_text() == layout_json('lichtblick'), (
        'run graph_viewer_layout --format lichtblick to refresh it')
    layout = json.loads(LICHTBLICK_FILE.read_text())
    # What Lichtblick's import checks before it takes a file (its validateLayoutData).
    assert isinstance(layout['configById'], dict) and isinstance(layout['globalVariables'], dict)
    assert isinstance(layout['playbackConfig']['speed'], float)
    configs = layout['configById']
    top = _mosaic_leaves(layout['layout'])
    in_tabs = [leaf for panel_id in top if panel_id.startswith('Tab!')
               for tab in configs[panel_id]['tabs'] for leaf in _mosaic_leaves(tab['layout'])]
    assert sorted(top + in_tabs) == sorted(configs)  # every panel placed once, none missing
    foxglove = json.loads(LAYOUT_FILE.read_text())
    panels = []

    def visit(content):
        if content['type'] == 'panel':
            panels.append(content)
        for child in content.get('items', []) + content.get('tabs', []):
            visit(child['content'])
    visit(foxglove['content'])
    assert len(panels) == sum(not panel_id.startswith('Tab!') for panel_id in configs)
    for panel in panels:  # the same config under the same title
        matches = [c for c in configs.values() if c.get('lichtblickPanelTitle') == panel['title']]
        assert len(matches) == 1, panel['title']
        mine = {k: v for k, v in matches[0].items() if not k.endswith('PanelTitle')}
        if panel['panelType'] == 'Plot':
            assert all(path.pop('enabled') is True for path in mine['paths'])
        assert mine == panel['config']


def test_a_split_of_three_becomes_two_nested_splits_with_its_proportions():
    panel = {'type': 'panel', 'panelType': 'Plot', 'title': 'a', 'config': {'paths': []}}
    layout = {'version': 1, 'content': {'type': 'split', 'direction': 'row', 'items': [
        {'proportion': 1, 'content': panel}, {'proportion': 1, 'content': panel},
        {'proportion': 2, 'content': panel}]}}
    mosaic = to_lichtblick(layout)['layout']
    assert mosaic['splitPercentage'] == 25.0 and mosaic['second']['splitPercentage'] == 33.333
    assert _mosaic_leaves(mosaic) == ['Plot!a', 'Plot!a_2', 'Plot!a_3']  # ids never collide
    with pytest.raises(ValueError, match='not a foxglove-sdk layout'):
        to_lichtblick({'configById': {}})


# The real graph, watched from Foxglove's side of the protocol.

WATCHED = ('/observation', '/metrics', '/plot/metrics', '/plot/env_status')
READERS = 'graph_viewer_readers'
"""The bridge's reading node."""


async def _watch(url: str, frames_for_s: float, run_dir: Path) -> FoxgloveClient:
    """Connect as soon as the bridge serves, subscribe, and read while the graph steps."""
    deadline = time.monotonic() + 90.0
    while True:
        try:
            client = FoxgloveClient(url)
            await client.__aenter__()
            break
        except (aiohttp.ClientError, OSError):
            if time.monotonic() > deadline:
                raise
            await asyncio.sleep(0.2)
    try:
        assert client.protocol == SUBPROTOCOL
        assert await client.wait_for_channels(WATCHED, 30.0), sorted(client.channels)
        client.listening = listening_sockets()
        client.niceness = thread_niceness(json.loads((run_dir / 'pids.json').read_text())[
            'graph_viewer'])
        await client.subscribe(WATCHED)
        while not client.of('/observation') and time.monotonic() < deadline:
            await client.read_for(0.5)  # the graph's start-up
        client.first_frame_at = time.monotonic()
        await client.read_for(frames_for_s)
        client.frames_until = time.monotonic()
        client.readers = _readers_of(('/observation', '/observation/preview',
                                      '/env_status', '/env_status/preview'))
        await client.read_for(1.5)  # one more metrics period
    finally:
        await client.__aexit__(None, None, None)
    return client


def _readers_of(names) -> dict:
    """Return {topic: the names of the nodes that subscribe to it} as the ROS graph has them."""
    with TopicProbe('graph_probe') as probe:
        def readers(name):
            return [info.node_name for info in probe.node.get_subscriptions_info_by_topic(name)]
        wait_until(lambda: READERS in readers('/env_status/preview'), 10.0)
        return {name: readers(name) for name in names}


def _flat(record: dict, prefix: str = '') -> dict:
    flat = {}
    for key, value in record.items():
        name = key if key != 'value' or not prefix else ''
        path = f'{prefix}/{name}'.strip('/') if name else prefix
        if isinstance(value, dict):
            flat.update(_flat(value, path))
        else:
            flat[path] = value
    return flat


def _same(csv_text: str, value) -> bool:
    if value is None:
        return csv_text.lower() in ('nan', 'inf', '-inf', '')
    # The metrics topic carries 6 significant digits (tamer_node formats with .6g).
    return math.isclose(float(csv_text), value, rel_tol=1e-5, abs_tol=1e-9)


@pytest.fixture(scope='module')
def watched_session(tmp_path_factory):
    """Run a real-time Room 1 session with the bridge, recorded, watched by a Foxglove client."""
    run_dir = tmp_path_factory.mktemp('foxglove') / 'run'
    port = free_port()
    launcher = subprocess.Popen(
        [LAUNCHER, '--steps', str(STEPS), '--realtime', '--record', '--run-dir', str(run_dir),
         '--foxglove', '--foxglove-port', str(port)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        client = asyncio.run(_watch(f'ws://127.0.0.1:{port}', 8.0, run_dir))
        out, err = launcher.communicate(timeout=180)
    finally:
        if launcher.poll() is None:
            launcher.kill()
    return run_dir, port, client, launcher.returncode, err


@pytest.mark.topics
def test_foxglove_gets_the_frames_at_the_envs_rate(watched_session):
    run_dir, port, client, returncode, err = watched_session
    assert returncode == 0, err[-3000:]
    summary = json.loads((run_dir / 'summary.json').read_text())
    assert summary['foxglove_url'] == f'ws://127.0.0.1:{port}'
    assert f'Foxglove: ws://127.0.0.1:{port}' in err
    assert summary['exit_codes']['graph_viewer'] == 0
    frames = [m for m in client.of('/observation')
              if client.first_frame_at <= m.arrived <= client.frames_until]
    rate = (len(frames) - 1) / (frames[-1].arrived - frames[0].arrived)
    # The env's own rate over the same seconds, from its status (every step in real time).
    steps = [(m.arrived, json.loads(m.payload)['agent_step']) for m in client.of(
        '/plot/env_status') if client.first_frame_at <= m.arrived <= client.frames_until]
    env_rate = (steps[-1][1] - steps[0][1]) / (steps[-1][0] - steps[0][0])
    assert abs(rate - env_rate) <= 0.1 * env_rate, (rate, env_rate)  # the env's rate, live
    if env_rate >= 15.0 * 0.9:  # an env that kept real time (not starved of CPU): 15 a second
        assert 15.0 * 0.9 <= rate <= 15.0 * 1.1, rate
    # Read from the copies the env thins at the source: DDS never brings the bridge the rest.
    readers = client.readers
    assert READERS in readers['/observation/preview'], readers
    assert READERS in readers['/env_status/preview'], readers
    assert READERS not in readers['/observation'] + readers['/env_status'], readers
    image = deserialize_message(frames[-1].payload, Image)  # the ROS 2 message itself
    assert (image.width, image.height, image.encoding) == (160, 210, 'rgb8')
    assert client.channels['/observation']['schemaName'] == 'sensor_msgs/msg/Image'
    assert client.channels['/observation']['encoding'] == 'cdr'
    # Every thread of the bridge (DDS's, the server's) yields the cores to the graph.
    assert client.niceness and min(client.niceness.values()) >= ViewerConfig.nice, (
        client.niceness)
    # Served on loopback only.
    ours = [address for address, listen_port in client.listening if listen_port == port]
    assert ours and all(loopback_address(address) for address in ours), ours


@pytest.mark.topics
def test_foxglove_gets_the_learners_metrics_as_metrics_csv_has_them(watched_session):
    run_dir, port, client, returncode, err = watched_session
    with open(run_dir / 'metrics.csv', newline='') as file:
        rows = list(csv.DictReader(file))
    plotted = [json.loads(m.payload) for m in client.of('/plot/metrics')]
    assert len(plotted) >= 3, len(plotted)  # one a second (fewer on a starved machine)
    for record in plotted:
        flat = _flat({k: v for k, v in record.items() if k != 'stamp'})
        # Its row: several can share act/count and train/updates (the learner idle while
        # feedback is logged and a checkpoint taken), so the row is the one equal on every key.
        candidates = [r for r in rows if float(r['act/count']) == flat['act/count']
                      and float(r['train/updates']) == flat['train/updates']]
        assert candidates, flat
        assert all(set(flat) == set(row) - {'wall_time'} for row in candidates)
        different = [{key: (row[key], value) for key, value in flat.items()
                      if not _same(row[key], value)} for row in candidates]
        assert not all(different), different
    raw = [deserialize_message(m.payload, DiagnosticArray) for m in client.of('/metrics')]
    assert len(raw) == len(plotted)
    assert {kv.key for kv in raw[-1].status[0].values} == set(rows[0]) - {'wall_time'}
    status = [json.loads(m.payload) for m in client.of('/plot/env_status')]
    steps = [record['agent_step'] for record in status]
    assert steps == sorted(steps) and len(steps) >= 100
    assert all(record['milestone'] >= -1 and record['lives'] >= 0 for record in status)


@pytest.mark.topics
def test_a_bags_plots_are_what_foxglove_saw_live(watched_session, capsys):
    run_dir, port, client, returncode, err = watched_session
    assert plots_main([str(run_dir / 'bag')]) == 0
    assert plots_main([str(run_dir / 'bag')]) == 2  # never written over
    with open(run_dir / PLOTS_FILE, 'rb') as file:
        reader = make_reader(file)
        from_bag = {}
        for schema, channel, message in reader.iter_messages(topics=['/plot/metrics']):
            record = json.loads(message.data)
            from_bag[json.dumps(record['stamp'])] = record
    live = [json.loads(m.payload) for m in client.of('/plot/metrics')]
    assert live and all(from_bag[json.dumps(record['stamp'])] == record for record in live)


def _bench_graph():
    sys.path.insert(0, str(Path(__file__).parent / 'benchmarks'))
    import bench_graph
    return bench_graph


def test_each_phase_counts_the_steps_of_its_own_seconds_after_it_settled():
    bench = _bench_graph()
    timeline = [(t, 100.0 * t if t < 10 else 1000.0 + 80.0 * (t - 10)) for t in range(31)]
    timeline += [(t, 2600.0) for t in range(31, 40)]  # stopped: the learner still writes rows
    phases = [(-5.0, 0.0, False),  # before the graph stepped: left out
              (0.0, 10.0, False), (10.0, 20.0, True), (20.0, 30.0, False),
              (27.0, 35.0, True),  # ran past its last step (at 30 s): left out
              (35.0, 39.0, False)]  # after it stopped: left out
    rates = bench.phase_rates(timeline, phases, settle_s=2.0)
    assert rates == [(False, pytest.approx(100.0)), (True, pytest.approx(80.0)),
                     (False, pytest.approx(80.0))]


def test_a_watched_phase_is_set_against_the_phases_alone_on_either_side():
    bench = _bench_graph()
    rates = [(False, 100.0), (True, 90.0), (False, 80.0), (True, 76.0), (False, 80.0)]
    assert bench.paired_slowdowns(rates) == [pytest.approx(0.0), pytest.approx(5.0)]


@pytest.mark.topics
def test_the_interleaved_cost_benchmark_runs_and_prints_its_table(tmp_path):
    """bench_graph.py --foxglove-interleaved end to end: the graph, the bridge, a client."""
    result = subprocess.run(
        [sys.executable, str(Path(__file__).parent / 'benchmarks' / 'bench_graph.py'),
         '--foxglove-interleaved', '2', '--graph-steps', '1200'],
        capture_output=True, text=True, timeout=300, cwd=tmp_path)
    assert result.returncode == 0, result.stdout[-2000:] + result.stderr[-3000:]
    assert '| alone |' in result.stdout and '| watched |' in result.stdout, result.stdout
    assert ' messages to it' in result.stdout and ' (0 messages' not in result.stdout
