"""The reports' figures: matplotlib without a display, and one way to save a figure."""

from pathlib import Path


def pyplot():
    """Return ``matplotlib.pyplot`` on the Agg backend (imported only when a report draws)."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    return plt


def save(figure, path: Path, dpi: int = 100) -> None:
    """Lay the figure out, write it to ``path`` and close it."""
    figure.tight_layout()
    figure.savefig(path, dpi=dpi)
    pyplot().close(figure)
