"""
The Foxglove layout of a teaching session, built with foxglove-sdk's layout types.

``graph_viewer_layout [OUT]`` writes it (default: the shipped ``layouts/attention_graph.json``,
which a test keeps equal to this code). In Foxglove: Layouts, Import from file.
``graph_viewer_layout --format lichtblick`` writes the same layout in Lichtblick's format
(``layouts/attention_graph_lichtblick.json``, ``lichtblick.py``). The panels:

- the frame (``/observation``), the saliency image and its mask (tabs);
- the feedback timeline: each press (``/feedback``), the synthetic trainer's stamped verdicts
  (``/feedback_stamped``), H of the action taken and the best H at each step;
- the learning curve: the learner's loss terms and updates per step, the milestone reached;
- the env's status (step, episode, lives, milestone) and the last utterance, as messages.

Every other channel (the credit of each feedback, receipts, actions) is one click away in
Foxglove's topic list; the layout leaves them out so that watching costs the graph little.
"""

import argparse
import json
from pathlib import Path
import sys
from typing import Optional

from attention_common import topics
import foxglove.layouts as fl
from graph_viewer.lichtblick import to_lichtblick
from graph_viewer.plots import plot_topic

LAYOUT_FILE = Path(__file__).resolve().parent / 'layouts' / 'attention_graph.json'
LICHTBLICK_FILE = LAYOUT_FILE.with_name('attention_graph_lichtblick.json')


def _topic(name: str) -> str:
    return '/' + name


def _series(path: str, label: str, line: bool = True) -> fl.PlotSeries:
    return fl.PlotSeries(value=path, label=label, show_line=line, timestamp_method='receiveTime')


def _plot(title: str, *series: fl.PlotSeries) -> fl.PlotPanel:
    return fl.PlotPanel(title=title, config=fl.PlotConfig(paths=list(series), show_legend=True,
                                                          legend_display='top'))


def _image(title: str, name: str) -> fl.ImagePanel:
    return fl.ImagePanel(title=title, config=fl.ImageConfig(
        image_mode=fl.ImageModeConfig(image_topic=_topic(name))))


def build_layout() -> fl.Layout:
    """Return the session layout: images left, the feedback and learning plots right."""
    metrics = plot_topic(_topic(topics.METRICS))
    values = plot_topic(_topic(topics.ACTION_VALUES))
    status = plot_topic(_topic(topics.ENV_STATUS))
    images = fl.TabContainer(tabs=[
        fl.TabItem(title='saliency', content=_image('saliency image', topics.SALIENCY)),
        fl.TabItem(title='mask', content=_image('saliency mask', topics.SALIENCY_MASK)),
    ])
    feedback = _plot(
        'feedback timeline',
        _series(_topic(topics.FEEDBACK) + '.data', 'feedback (a person, ros2 topic pub)', False),
        _series(_topic(topics.FEEDBACK_STAMPED) + '.vector.x', 'feedback (stamped)', False),
        _series(_topic(topics.FEEDBACK_PRESSED) + '.vector.x', 'feedback (pressed)', False),
        _series(values + '.h_taken', 'H of the action taken'),
        _series(values + '.h_best', 'best H'))
    learning = _plot(
        'learning curve',
        _series(metrics + '.train.mse', 'MSE'),
        _series(metrics + '.train.l2', 'L2 (saliency)'),
        _series(metrics + '.train.updates_per_step', 'updates per step'),
        _series(status + '.milestone', 'milestone'))
    messages = fl.TabContainer(tabs=[
        fl.TabItem(title='env', content=fl.RawMessagesPanel(
            title='env status', config=fl.RawMessagesConfig(topic_path=status))),
        fl.TabItem(title='utterance', content=fl.RawMessagesPanel(
            title='last utterance',
            config=fl.RawMessagesConfig(topic_path=_topic(topics.UTTERANCE)))),
    ])
    left = fl.SplitContainer(direction='column', items=[
        fl.SplitItem(proportion=1, content=_image('frame', topics.OBSERVATION)),
        fl.SplitItem(proportion=1, content=images),
    ])
    right = fl.SplitContainer(direction='column', items=[
        fl.SplitItem(proportion=1, content=feedback),
        fl.SplitItem(proportion=1, content=learning),
        fl.SplitItem(proportion=1, content=messages),
    ])
    return fl.Layout(content=fl.SplitContainer(direction='row', items=[
        fl.SplitItem(proportion=2, content=left), fl.SplitItem(proportion=3, content=right)]))


def layout_topics() -> set:
    """Return every channel the layout's panels read (a message path's part before its '.')."""
    found = set()

    def visit(node) -> None:
        if isinstance(node, dict):
            for key, value in node.items():
                if key in ('imageTopic', 'topicPath', 'value') and isinstance(value, str):
                    found.add(value.split('.')[0])
                else:
                    visit(value)
        elif isinstance(node, list):
            for item in node:
                visit(item)

    visit(json.loads(build_layout().to_json()))
    return found


def layout_json(layout_format: str = 'foxglove') -> str:
    """Return the layout as the shipped file holds it (indented, one trailing newline)."""
    layout = json.loads(build_layout().to_json())
    if layout_format == 'lichtblick':
        layout = to_lichtblick(layout)
    return json.dumps(layout, indent=2) + '\n'


def main(argv: Optional[list] = None) -> int:
    parser = argparse.ArgumentParser(
        prog='graph_viewer_layout',
        description='Write the Foxglove layout of a teaching session (import it in Foxglove or '
                    'Lichtblick: Layouts, Import from file).')
    parser.add_argument('out', nargs='?', default=None,
                        help=f'the JSON file to write (default: the shipped one, {LAYOUT_FILE} '
                             f'or {LICHTBLICK_FILE.name})')
    parser.add_argument('--format', choices=('foxglove', 'lichtblick'), default='foxglove',
                        help="foxglove-sdk's format (Foxglove), or the one Lichtblick imports")
    args = parser.parse_args(argv)
    out = args.out or (LICHTBLICK_FILE if args.format == 'lichtblick' else LAYOUT_FILE)
    Path(out).write_text(layout_json(args.format))
    print(f'layout written to {out}', file=sys.stderr)
    return 0
