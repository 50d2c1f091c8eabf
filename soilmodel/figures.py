"""Saving a matplotlib figure: the one helper of every figure the library writes (fit, diagnosis, planning)."""

from __future__ import annotations

from .errors import DataError

__all__ = ["save_figure"]


def save_figure(fig, path: str, *, dpi: int = 120) -> str:
    """Save ``fig`` to ``path`` (format from the extension) and close it; returns ``path``.

    Raises
    ------
    DataError
        The path cannot be written (naming it; the command line checks it before the work).
    """
    import matplotlib.pyplot as plt

    try:
        fig.savefig(path, dpi=dpi)
    except OSError as e:
        raise DataError(f"cannot write the figure: {e.strerror or e}", file=path) from None
    finally:
        plt.close(fig)
    return path
