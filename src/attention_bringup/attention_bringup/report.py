"""What a run leaves in its folder: progress.csv, summary.json, params.yaml and two figures."""

import csv
import json
import math
from pathlib import Path
import textwrap
from typing import Dict, Iterator, List, Mapping, Optional, Sequence

from attention_bringup.gallery import GallerySample
from attention_bringup.params import dump_params
from attention_bringup.progress import format_duration, parse_value, PROGRESS_COLUMNS
from attention_tasks.task import ROOM_1

PLOT_ROWS = 20_000
"""About as many rows of progress.csv as the learning curve draws (a long run is thinned)."""
PLOT_COLUMNS = ('agent_step', 'position', 'furthest_position', 'feedback_count', 'feedback_sum')


class ProgressWriter:
    """Appends rows to progress.csv as they come, so a crash keeps what was seen."""

    def __init__(self, path: Path, append: bool = False):
        """``append``: go on with the file of an earlier session (its header is kept)."""
        append = append and Path(path).exists() and Path(path).stat().st_size > 0
        self._file = open(path, 'a' if append else 'w', newline='')
        self._writer = csv.DictWriter(self._file, fieldnames=PROGRESS_COLUMNS)
        if not append:
            self._writer.writeheader()
        self.written = 0

    def write(self, rows: Sequence[dict]) -> None:
        """Append ``rows`` (new ones only) and flush."""
        if not rows:
            return
        self._writer.writerows(rows)
        self.written += len(rows)
        self._file.flush()

    def close(self) -> None:
        self._file.close()


def write_json(path: Path, data) -> None:
    tmp = path.with_suffix(path.suffix + '.tmp')
    tmp.write_text(json.dumps(data, indent=2, sort_keys=False, default=str) + '\n')
    tmp.replace(path)


def write_params(path: Path, node_params: Mapping[str, Mapping[str, object]],
                 options: Mapping[str, object], source: str) -> None:
    """
    params.yaml: every node's parameters, and the launcher's options under its own name.

    The file is itself a valid ``--params-file`` (nodes ignore sections not named after them).
    """
    graph = {name: dict(values) for name, values in node_params.items()}
    graph['attention_train'] = {key: value for key, value in options.items()
                                if value is not None and value != []}
    header = (f'Parameters of this run ({source}).\n'
              'Reuse: attention_train --params-file <this file> (launcher options are '
              'informational).')
    path.write_text(dump_params(graph, header=header))


def learner_log_counts(path: Path) -> Optional[dict]:
    """
    Count what the learner logged in ``feedback_log.jsonl`` (streamed; None without the file).

    The learner's own record, not what the launcher happened to hear: feedback lines by
    status, the mean h of those it accepted, and its utterance lines.
    """
    if not Path(path).exists():
        return None
    counts = {'feedback': 0, 'ok': 0, 'invalid': 0, 'duplicate': 0, 'no_observation': 0,
              'utterances': 0}
    total_h = 0.0
    with open(path, encoding='utf-8', errors='replace') as file:
        for line in file:
            try:
                entry = json.loads(line)
            except ValueError:  # cut short by a crash
                continue
            if entry.get('kind') == 'utterance':
                counts['utterances'] += 1
            elif entry.get('kind') == 'feedback':
                counts['feedback'] += 1
                status = entry.get('status', 'ok')
                counts[status] = counts.get(status, 0) + 1
                if status == 'ok':
                    total_h += float(entry.get('h', 0.0))
    counts['mean_h'] = round(total_h / counts['ok'], 4) if counts['ok'] else None
    return counts


def feedback_text(summary: Mapping) -> str:
    """Return the learner's own count of feedback (its log; the launcher hears only part)."""
    logged = summary.get('learner_log')
    if logged is not None:
        mean = f', mean h {logged["mean_h"]:+.2f}' if logged.get('mean_h') is not None else ''
        return (f'feedback logged by the learner {logged["feedback"]} ({logged["ok"]} used, '
                f'{logged["invalid"]} invalid{mean})')
    received = summary.get('metrics', {}).get('feedback/received')
    if received is not None:
        return f'feedback received by the learner {int(received)}'
    return 'no feedback log from the learner'


def summary_lines(summary: Mapping) -> List[str]:
    """Return the three lines printed at the end of a run."""
    counts = summary.get('message_counts', {})
    name = summary.get('furthest_milestone')
    kind = 'critical position' if summary.get('task', ROOM_1) == ROOM_1 else 'sub-goal'
    reached = (f'furthest {kind} {name.replace("critical position ", "")} (first at step '
               f'{summary["milestone_steps"][name]})' if name is not None
               else f'no {kind} reached')
    metrics = summary.get('metrics', {})
    loss = metrics.get('train/loss')
    loss_text = (f', loss {loss:.4g}' if isinstance(loss, (int, float)) and math.isfinite(loss)
                 else '')
    updates = metrics.get('train/updates')
    updates_text = f'{updates} learner updates' if updates is not None else 'learner'
    logged = summary.get('learner_log') or {}
    utterances = logged.get('utterances', summary.get('utterance_count', 0))
    first_key = summary.get('first_key_step')
    key_text = (f'the key at step {first_key} ({summary.get("keys", 0)} in all)'
                if first_key is not None else 'no key')
    if summary.get('task', ROOM_1) != ROOM_1:
        key_text = f'{summary.get("episodes_solved", 0)} solved'
    asked = metrics.get('ask/asked')
    asked_text = f', questions asked {int(asked)}' if asked else ''
    return [
        f'{summary.get("steps", 0)} steps in {format_duration(summary.get("wall_time_s", 0))} '
        f'({summary.get("steps_per_s", 0):.1f} steps/s), {summary.get("episodes", 0)} episodes, '
        f'{key_text}; {reached}',
        f'{feedback_text(summary)}{asked_text}, utterances {utterances}, '
        'saliency images '
        f'{counts.get("saliency", 0)}; {updates_text}{loss_text}',
        f'{summary.get("status", "?")}: {summary.get("exit_text", "")}' + (
            f' (teardown watchdog ended {", ".join(summary["teardown_watchdog"])}: its stack '
            'is in the log)' if summary.get('teardown_watchdog') else ''),
    ]


def read_progress_rows(path: Path) -> Iterator[dict]:
    """Yield the rows of ``progress.csv`` with their values parsed (streamed)."""
    with open(path, newline='') as file:
        for row in csv.DictReader(file):
            yield {key: parse_value(value or '') for key, value in row.items()}


def read_rows_for_plot(path: Path, count: int, most: int = PLOT_ROWS) -> List[dict]:
    """
    Read ``progress.csv`` back for the learning curve, streamed.

    Every row of a short run; of a long one (``count`` rows) every k-th and each row where the
    furthest position grew, about ``most`` + the growths (a million-step run is never held).
    """
    if not Path(path).exists():
        return []
    stride = max(1, math.ceil(count / most))
    rows, furthest = [], None
    for index, row in enumerate(read_progress_rows(path)):
        grew = row['furthest_position'] != furthest
        furthest = row['furthest_position']
        if index % stride == 0 or grew:
            rows.append({key: row[key] for key in PLOT_COLUMNS})
    return rows


def plot_learning_curve(rows: Sequence[dict], path: Path, title: str) -> bool:
    """Furthest critical position and cumulative feedback over agent steps."""
    if not rows:
        return False
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    steps = [row['agent_step'] for row in rows]
    figure, (top, bottom) = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    top.scatter(steps, [row['position'] for row in rows], s=2, color='0.7',
                label='position this step (-1: in between)')
    top.step(steps, [row['furthest_position'] for row in rows], where='post', color='C0',
             label='furthest so far')
    top.set_ylabel('critical position')
    top.set_yticks(range(-1, 6))
    top.set_ylim(-1.5, 5.5)
    top.legend(loc='upper left', fontsize='small')
    bottom.plot(steps, [row['feedback_count'] for row in rows], color='C1',
                label='feedback messages')
    bottom.plot(steps, [row['feedback_sum'] for row in rows], color='C2', label='sum of h')
    bottom.set_xlabel('agent step')
    bottom.set_ylabel('cumulative feedback')
    bottom.legend(loc='upper left', fontsize='small')
    figure.suptitle(title)
    figure.tight_layout()
    figure.savefig(path, dpi=100)
    plt.close(figure)
    return True


def decode_image(raw: Optional[bytes]):
    """Decode a serialized sensor_msgs/Image into a numpy array (None stays None)."""
    if raw is None:
        return None
    from attention_common.image_codec import image_to_numpy
    from rclpy.serialization import deserialize_message
    from sensor_msgs.msg import Image
    return image_to_numpy(deserialize_message(raw, Image))


def plot_gallery(samples: Sequence[GallerySample], path: Path, title: str,
                 step_of: Optional[Dict[int, int]] = None) -> bool:
    """Frame, mask and saliency image of a few steps, each row titled with its utterance."""
    if not samples:
        return False
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(len(samples), 3, figsize=(7.5, 3.6 * len(samples)),
                                squeeze=False)
    for row, sample in zip(axes, samples):
        images = (decode_image(sample.observation), decode_image(sample.mask),
                  decode_image(sample.saliency))
        for axis, image, name in zip(row, images, ('frame', 'mask', 'saliency')):
            axis.set_xticks([])
            axis.set_yticks([])
            if image is None:
                axis.text(0.5, 0.5, f'no {name}\nfor this step', ha='center', va='center',
                          transform=axis.transAxes, color='0.4')
            else:
                axis.imshow(image, cmap='gray' if image.ndim == 2 else None,
                            interpolation='nearest')
            axis.set_title(name, fontsize='small')
        step = (step_of or {}).get(sample.stamp_ns)
        label = f'step {step}' if step is not None else f't = {sample.stamp_ns / 1e9:.2f} s'
        utterance = sample.utterance or '(no utterance)'
        row[0].set_ylabel('\n'.join(textwrap.wrap(f'{label}: "{utterance}"', 30)),
                          fontsize='small')
    figure.suptitle(title)
    figure.tight_layout()
    figure.savefig(path, dpi=90)
    plt.close(figure)
    return True
