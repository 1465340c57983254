"""OTB-style success and precision plots (matplotlib, Agg backend: no display needed)."""

from __future__ import annotations

from pathlib import Path
from typing import Mapping

import numpy as np

from ..errors import OutputError
from .metrics import PRECISION_THRESHOLDS, SUCCESS_THRESHOLDS


def mean_curves(curves: Mapping[tuple[str, str], tuple[np.ndarray, np.ndarray]],
                filters: list[str]) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Per filter, the mean over its sequences of the success and precision curves.

    As in the OTB toolkit's overall plots, each sequence weighs the same; the
    mean success curve's mean is the mean of the per-sequence AUCs.
    """
    means = {}
    for name in filters:
        mine = [c for (f, _), c in curves.items() if f == name]
        if mine:
            means[name] = (np.nanmean([c[0] for c in mine], axis=0), np.nanmean([c[1] for c in mine], axis=0))
    return means


def _plot(path: Path, x: np.ndarray, series: dict[str, np.ndarray], *, title: str, xlabel: str,
          ylabel: str, label) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5.5, 4.2), dpi=110)
    try:
        ranked = sorted(series.items(), key=lambda item: -np.nan_to_num(label(item[1])))
        for name, y in ranked:
            ax.plot(x, y, linewidth=2, label=f"{name} [{label(y):.3f}]")
        ax.set(title=title, xlabel=xlabel, ylabel=ylabel, xlim=(x[0], x[-1]), ylim=(0, 1.02))
        ax.grid(True, alpha=0.3)
        if series:
            ax.legend(loc="best", fontsize=8)
        fig.tight_layout()
        path.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(path)
    except OSError as exc:
        raise OutputError(f"cannot write {path}: {exc.strerror or exc}") from None
    finally:
        plt.close(fig)
    return path


def success_plot(path: str | Path, curves: Mapping[str, np.ndarray], *, title: str = "Success plot") -> Path:
    """Success rate against the IoU threshold, one curve per tracker, AUC in the legend."""
    return _plot(Path(path), SUCCESS_THRESHOLDS, dict(curves), title=title, xlabel="Overlap threshold",
                 ylabel="Success rate", label=lambda y: float(np.mean(y)))


def precision_plot(path: str | Path, curves: Mapping[str, np.ndarray], *, title: str = "Precision plot") -> Path:
    """Precision against the centre-error threshold, one curve per tracker, precision@20 in the legend."""
    at20 = int(np.flatnonzero(PRECISION_THRESHOLDS == 20)[0])
    return _plot(Path(path), PRECISION_THRESHOLDS, dict(curves), title=title,
                 xlabel="Location error threshold (px)", ylabel="Precision", label=lambda y: float(y[at20]))


def write_plots(out: str | Path, curves: Mapping[tuple[str, str], tuple[np.ndarray, np.ndarray]],
                filters: list[str], sequences: list[str]) -> list[Path]:
    """``OUT/success.png`` and ``OUT/precision.png`` (mean over sequences), and per sequence
    ``OUT/plots/<Sequence>_success.png`` and ``_precision.png``."""
    out = Path(out)
    written = []
    means = mean_curves(curves, filters)
    n = len(sequences)
    written.append(success_plot(out / "success.png", {f: c[0] for f, c in means.items()},
                                title=f"Success plot ({n} sequence{'s' * (n != 1)})"))
    written.append(precision_plot(out / "precision.png", {f: c[1] for f, c in means.items()},
                                  title=f"Precision plot ({n} sequence{'s' * (n != 1)})"))
    if n > 1:
        for sequence in sequences:
            mine = {f: curves[(f, sequence)] for f in filters if (f, sequence) in curves}
            written.append(success_plot(out / "plots" / f"{sequence}_success.png",
                                        {f: c[0] for f, c in mine.items()}, title=f"Success plot: {sequence}"))
            written.append(precision_plot(out / "plots" / f"{sequence}_precision.png",
                                          {f: c[1] for f, c in mine.items()}, title=f"Precision plot: {sequence}"))
    return written
