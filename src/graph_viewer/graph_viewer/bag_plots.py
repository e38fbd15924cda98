"""
``graph_viewer_plots BAG``: a finished session's plot channels, for Foxglove beside its bag.

The bag holds the graph's messages as they came; the layout's plots read the bridge's
``/plot/...`` channels, made live from the DiagnosticArrays. This makes the same channels from
the bag's messages, with the same functions and the bag's receive times, into one MCAP file
(foxglove-sdk's writer) next to the bag folder: open both files in Foxglove together and the
layout reads the session as it read it live. The bag itself is never written.
"""

import argparse
from pathlib import Path
import sys
from typing import Optional

from attention_common.stamps import stamp_to_ns
from attention_tasks.montezuma.critical_positions import DEFAULT_RADIUS
from attention_tasks.task import DEFAULT_TASK, load_task
from diagnostic_msgs.msg import DiagnosticArray
import foxglove
from graph_viewer.plots import encode, plot_topic, PLOTTED, record_of, SCHEMAS
from rclpy.serialization import deserialize_message
from session_bag.reader import BagReader, storage_path

PLOTS_FILE = 'foxglove_plots.mcap'
"""Written beside the bag folder (never in it: a rosbag2 folder holds its own files only)."""


def write_plots(bag_dir: Path, out: Path, task: str = DEFAULT_TASK) -> dict:
    """Write the plot channels of ``bag_dir`` into ``out``; return {channel: messages}."""
    knowledge = load_task(task)
    milestone_of = lambda values: knowledge.milestone_of(values, DEFAULT_RADIUS)  # noqa: E731
    context = foxglove.Context()
    channels, counts, errors = {}, {}, 0
    reader = BagReader(bag_dir)
    with foxglove.open_mcap(out, context=context):
        for message in reader.messages():
            kind = next((name for name in PLOTTED if message.topic.endswith('/' + name)), None)
            if kind is None:
                continue
            try:
                msg = deserialize_message(message.data, DiagnosticArray)
                record = record_of(kind, stamp_to_ns(msg.header.stamp), msg.status,
                                   milestone_of)
            except Exception:  # noqa: B902 - a malformed message is counted, never the end
                errors += 1
                continue
            name = plot_topic(message.topic)
            if name not in channels:
                channels[name] = foxglove.Channel(name, schema=SCHEMAS[kind], context=context)
                counts[name] = 0
            channels[name].log(encode(record), log_time=message.log_time)
            counts[name] += 1
    return {'channels': counts, 'not_plotted': errors, 'bag_complete': reader.complete}


def main(argv: Optional[list] = None) -> int:
    parser = argparse.ArgumentParser(
        prog='graph_viewer_plots',
        description="Write a session bag's plot channels (/plot/metrics, /plot/env_status) "
                    f'into {PLOTS_FILE} beside it: open both in Foxglove with the layout.')
    parser.add_argument('bag', help="the bag folder (a run folder's bag/)")
    parser.add_argument('--task', default=DEFAULT_TASK,
                        help="the session's task, for its milestones (default %(default)s)")
    parser.add_argument('--out', default=None,
                        help=f'the MCAP file to write (default: {PLOTS_FILE} beside the bag)')
    args = parser.parse_args(argv)
    bag_dir = Path(args.bag).resolve()
    try:
        storage_path(bag_dir)
    except (OSError, ValueError) as error:
        print(f'graph_viewer_plots: {bag_dir} is not a session bag ({error})', file=sys.stderr)
        return 2
    out = Path(args.out) if args.out else bag_dir.parent / PLOTS_FILE
    if out.exists():
        print(f'graph_viewer_plots: {out} exists; remove it or pass --out', file=sys.stderr)
        return 2
    summary = write_plots(bag_dir, out, args.task)
    print(f'{out}: {summary}')
    print(f'open {storage_path(bag_dir)} and {out} together in Foxglove, with the layout '
          'graph_viewer_layout writes')
    return 0
