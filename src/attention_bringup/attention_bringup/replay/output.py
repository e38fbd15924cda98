"""What a replay prints and draws: its summary lines and its learning curve. Pure."""

import csv
from pathlib import Path
from typing import List, Mapping

from attention_common.run_files import METRICS_CSV


def summary_lines(summary: Mapping) -> List[str]:
    agreement = summary.get('agreement')
    last = summary.get('agreement_last_quarter')
    same = summary.get('feedback_same_step') or {}
    share = _share
    return [
        f'{summary.get("steps", 0)} steps replayed in {summary.get("wall_time_s", 0):.0f} s; '
        f'{summary.get("unanswered", 0)} unanswered',
        f"greedy actions agree with the session's on {share(agreement)} of the steps "
        f'({share(last)} in the last quarter; chance {share(summary.get("chance_agreement"))})',
        f'{summary.get("receipts", 0)} feedback/utterances logged by the learner; feedback on '
        f'the same step as in the session: {same.get("same", 0)} of {same.get("compared", 0)}',
        f'{summary.get("status", "?")}: exit codes {summary.get("exit_codes")}',
    ]


def study_table(summaries: List[Mapping]) -> str:
    """Return a markdown table of one session replayed per condition."""
    lines = ['| condition | steps | agreement | last quarter | feedback learned | '
             'same step | loss |', '|---|---|---|---|---|---|---|']
    for s in summaries:
        metrics = s.get('metrics') or {}
        same = s.get('feedback_same_step') or {}
        lines.append(
            f'| {s["condition"]} | {s.get("steps", 0)} | {_share(s.get("agreement"))} | '
            f'{_share(s.get("agreement_last_quarter"))} | {metrics.get("feedback/count", "-")} '
            f'| {same.get("same", 0)}/{same.get("compared", 0)} | '
            f'{metrics.get("train/loss", "-")} |')
    return '\n'.join(lines)


def _share(value) -> str:
    return '-' if value is None else f'{value:.3f}'


def read_losses(path: Path) -> List[tuple]:
    """Return (steps acted, train/loss) of each metrics.csv row ([] without the file)."""
    if not path.exists():
        return []
    rows = []
    with open(path, newline='') as file:
        for row in csv.DictReader(file):
            try:
                rows.append((float(row['act/count']), float(row['train/loss'])))
            except (KeyError, TypeError, ValueError):
                continue
    return rows


def plot_replay(summary: Mapping, path: Path, title: str) -> bool:
    """Agreement with the session per window of steps, and the learner's loss."""
    curve = summary.get('curve') or []
    if not curve:
        return False
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    figure, (top, bottom) = plt.subplots(2, 1, figsize=(8, 6))
    top.plot([p['step'] for p in curve], [p['agreement'] for p in curve], marker='o',
             color='C0', label="greedy action = the session's")
    chance = summary.get('chance_agreement')
    if chance:
        top.axhline(chance, color='0.6', linestyle='--', label='chance')
    top.set_ylim(0, 1)
    top.set_xlabel('replayed step')
    top.set_ylabel('agreement (window)')
    top.legend(loc='upper left', fontsize='small')
    losses = read_losses(path.parent / METRICS_CSV)
    if losses:
        bottom.plot([t for t, _ in losses], [v for _, v in losses], color='C1')
    bottom.set_xlabel('steps the learner acted on')
    bottom.set_ylabel('train/loss')
    figure.suptitle(title)
    figure.tight_layout()
    figure.savefig(path, dpi=100)
    plt.close(figure)
    return True
