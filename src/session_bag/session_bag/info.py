"""What a bag holds, from its metadata.yaml (cheap: no message is read). Pure."""

from pathlib import Path

from session_bag import metadata
from session_bag.reader import storage_path


def bag_summary(bag_dir: Path) -> dict:
    """Return {dir, file, bytes, messages, duration_s, topics: {name: count}, types: {...}}."""
    bag_dir = Path(bag_dir)
    info = metadata.read(bag_dir)
    path = storage_path(bag_dir)
    entries = info.get('topics_with_message_count') or []
    return {
        'dir': str(bag_dir),
        'file': path.name,
        'storage': info.get('storage_identifier'),
        'bytes': path.stat().st_size,
        'messages': int(info.get('message_count', 0)),
        'duration_s': round(int(info.get('duration', {}).get('nanoseconds', 0)) / 1e9, 3),
        'topics': metadata.topic_counts(info),
        'types': {e['topic_metadata']['name']: e['topic_metadata']['type'] for e in entries},
    }


def summary_line(summary: dict) -> str:
    """One line for a terminal: 'bag: 12,345 messages on 13 topics, 8.1 MB in <dir>'."""
    return (f'bag: {summary["messages"]:,} messages on {len(summary["topics"])} topics, '
            f'{summary["bytes"] / 1e6:.1f} MB in {summary["dir"]}'
            + (' (repaired: its recorder did not exit cleanly)' if summary.get('repaired')
               else ''))
