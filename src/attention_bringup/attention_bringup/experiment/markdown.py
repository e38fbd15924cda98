"""The report writer's pieces: tables, numbers, p-values and durations as markdown text."""

import os
from pathlib import Path
from typing import Any, List, Mapping, Optional, Sequence


def table(header: Sequence[str], rows: Sequence[Sequence[Any]]) -> List[str]:
    """Return a markdown table's lines."""
    return (['| ' + ' | '.join(header) + ' |', '|' + '---|' * len(header)]
            + ['| ' + ' | '.join(str(cell) for cell in row) + ' |' for row in rows])


def num(value: Optional[float], digits: int = 2, missing: str = 'n/a',
        whole_ints: bool = False) -> str:
    """Return ``value`` with ``digits`` decimals (an int as it is with ``whole_ints``)."""
    if value is None:
        return missing
    if whole_ints and isinstance(value, int):
        return str(value)
    return f'{value:.{digits}f}'


COUNT_WORDS = ('no', 'one', 'two', 'three', 'four', 'five', 'six', 'seven', 'eight', 'nine')


def counted(n: int, noun: str) -> str:
    """Return 'five comparisons', 'one comparison', '12 comparisons'."""
    word = COUNT_WORDS[n] if 0 <= n < len(COUNT_WORDS) else str(n)
    return f'{word} {noun}' + ('' if n == 1 else 's')


def percent(share: Optional[float], digits: int = 0) -> str:
    """Return a share as '42 %' (``digits`` decimals); 'n/a' for None."""
    return 'n/a' if share is None else f'{100 * share:.{digits}f} %'


def p_value(p: Optional[float], missing: str = 'n/a') -> str:
    """Return a p-value to 3 decimals, '< 0.001' below that."""
    if p is None:
        return missing
    return '< 0.001' if p < 0.001 else f'{p:.3f}'


def mean_interval(estimate: Mapping, digits: int = 2) -> str:
    """Return 'mean [low, high]' of a stored estimate ('mean' alone without an interval)."""
    if estimate['mean'] is None:
        return 'n/a'
    if estimate['low'] is None:
        return f'{estimate["mean"]:.{digits}f}'
    return (f'{estimate["mean"]:.{digits}f} [{estimate["low"]:.{digits}f}, '
            f'{estimate["high"]:.{digits}f}]')


def image(alt: str, path: Path, report: Path) -> str:
    """Return the markdown of a figure, linked relative to the report's folder."""
    return f'![{alt}]({os.path.relpath(Path(path).resolve(), Path(report).resolve().parent)})'


def minutes(seconds: float) -> str:
    """Return '42 min' or '1 h 05 min'."""
    rounded = int(round(seconds / 60))
    return f'{rounded // 60} h {rounded % 60:02d} min' if rounded >= 60 else f'{rounded} min'


def minutes_seconds(seconds: float) -> str:
    """Return '4 min 05 s' or '1 h 05 min'."""
    seconds = int(round(seconds))
    hours, rest = divmod(seconds, 3600)
    return f'{hours} h {rest // 60:02d} min' if hours else f'{rest // 60} min {rest % 60:02d} s'


def table_text(header: Sequence[str], rows: Sequence[Sequence[Any]]) -> str:
    """Return a markdown table as one string."""
    return '\n'.join(table(header, rows))


def write(path: Path, text: str) -> None:
    """Write a report to ``path``, making its folder if need be."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
