"""
``attention_bag``: what a session bag holds, and a bag cut short made whole.

  attention_bag info BAG     topics, types, message counts, size (like ``ros2 bag info``)
  attention_bag repair BAG   a bag whose recorder was killed: summary and footer written back,
                             metadata.yaml recounted (like ``ros2 bag reindex``)

BAG is a bag folder, or a run folder of attention_train with its bag in ``bag/``. Exit code 0,
or 2 for a path that holds no bag.
"""

import argparse
from pathlib import Path
import sys
from typing import Optional

from session_bag.info import bag_summary
from session_bag.metadata import METADATA_FILE
from session_bag.reader import BagReader
from session_bag.repair import repair


def bag_folder(path: str) -> Path:
    folder = Path(path)
    if not (folder / METADATA_FILE).is_file() and (folder / 'bag' / METADATA_FILE).is_file():
        folder = folder / 'bag'
    return folder


def info(folder: Path, out) -> None:
    summary = bag_summary(folder)
    reader = BagReader(folder)
    for _ in reader.messages():
        pass
    out.write(f'Bag: {folder}\nFile: {summary["file"]} ({summary["bytes"] / 1e6:.1f} MB, '
              f'{summary["storage"]}), {"complete" if reader.complete else "cut short: "}'
              f'{"" if reader.complete else (reader.problem or "?") + " (attention_bag repair)"}'
              f'\nDuration: {summary["duration_s"]:.1f} s\nMessages: '
              f'{sum(reader.counts.values())} (metadata.yaml: {summary["messages"]})\nTopics:\n')
    width = max((len(name) for name in reader.topics), default=0)
    for name, topic in reader.topics.items():
        out.write(f'  {name:<{width}}  {topic.type_name:<38} {reader.counts.get(name, 0):>8}\n')


def main(argv: Optional[list] = None) -> int:
    parser = argparse.ArgumentParser(prog='attention_bag', description=__doc__.split('\n')[1])
    parser.add_argument('command', choices=('info', 'repair'))
    parser.add_argument('bag', help='a bag folder, or a run folder holding bag/')
    args = parser.parse_args(argv)
    folder = bag_folder(args.bag)
    try:
        if args.command == 'info':
            info(folder, sys.stdout)
        else:
            result = repair(folder)
            sys.stdout.write(
                f'{folder}: ' + ('complete already; metadata.yaml checked' if result.was_complete
                                 else f'repaired ({result.problem} at the cut)')
                + f', {result.messages} messages\n')
    except (OSError, ValueError) as error:
        sys.stderr.write(f'attention_bag: {error}\n')
        return 2
    return 0


if __name__ == '__main__':
    sys.exit(main())
