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


def palette(names) -> dict[str, tuple[int, int, int]]:
    """A distinct colour per tracker, ``{name: (r, g, b)}`` 0-255 (matplotlib's tab10, or tab20 past 10).

    The plots and the HTML report colour a tracker the same way.
    """
    import matplotlib

    names = list(names)
    cmap = matplotlib.colormaps["tab10" if len(names) <= 10 else "tab20"]
    return {name: tuple(int(round(255 * c)) for c in cmap(i % cmap.N)[:3]) for i, name in enumerate(names)}


def _mpl_colour(colours, name):
    return None if not colours or name not in colours else tuple(c / 255 for c in colours[name])


def _write(fig, path: Path) -> Path:
    """Lay out and write ``fig`` to ``path`` (its folder made); an unwritable path is an :class:`OutputError`."""
    try:
        fig.tight_layout()
        path.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(path)
    except OSError as exc:
        raise OutputError(f"cannot write {path}: {exc.strerror or exc}") from None
    return path


def _plot(path: Path, x: np.ndarray, series: dict[str, np.ndarray], *, title: str, xlabel: str,
          ylabel: str, label, colours=None) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5.5, 4.2), dpi=110)
    try:
        ranked = sorted(series.items(), key=lambda item: -np.nan_to_num(label(item[1])))
        for name, y in ranked:
            ax.plot(x, y, linewidth=2, label=f"{name} [{label(y):.3f}]", color=_mpl_colour(colours, name))
        ax.set(title=title, xlabel=xlabel, ylabel=ylabel, xlim=(x[0], x[-1]), ylim=(0, 1.02))
        ax.grid(True, alpha=0.3)
        if series:
            ax.legend(loc="best", fontsize=8)
        return _write(fig, path)
    finally:
        plt.close(fig)


def success_plot(path: str | Path, curves: Mapping[str, np.ndarray], *, title: str = "Success plot",
                 colours=None) -> Path:
    """Success rate against the IoU threshold, one curve per tracker, AUC in the legend.

    The thresholds are evenly spaced from 0 to 1, as many as the curves have
    points (OTB's 21, GOT-10k's 101).

    ``colours`` (optional) maps a tracker to its ``(r, g, b)`` 0-255 (see :func:`palette`).
    """
    lengths = {len(y) for y in curves.values()}
    grid = np.linspace(0.0, 1.0, lengths.pop()) if len(lengths) == 1 else SUCCESS_THRESHOLDS  # the benchmark's grid
    return _plot(Path(path), grid, dict(curves), title=title, xlabel="Overlap threshold",
                 ylabel="Success rate", label=lambda y: float(np.mean(y)), colours=colours)


def precision_plot(path: str | Path, curves: Mapping[str, np.ndarray], *, title: str = "Precision plot",
                   colours=None) -> Path:
    """Precision against the centre-error threshold, one curve per tracker, precision@20 in the legend."""
    at20 = int(np.flatnonzero(PRECISION_THRESHOLDS == 20)[0])
    return _plot(Path(path), PRECISION_THRESHOLDS, dict(curves), title=title,
                 xlabel="Location error threshold (px)", ylabel="Precision", label=lambda y: float(y[at20]),
                 colours=colours)


def write_plots(out: str | Path, curves: Mapping[tuple[str, str], tuple[np.ndarray, np.ndarray]],
                filters: list[str], sequences: list[str]) -> list[Path]:
    """``OUT/success.png`` and ``OUT/precision.png`` (mean over sequences), and per sequence
    ``OUT/plots/<Sequence>_success.png`` and ``_precision.png``."""
    out = Path(out)
    written = []
    means = mean_curves(curves, filters)
    n = len(sequences)
    colours = palette(filters)
    written.append(success_plot(out / "success.png", {f: c[0] for f, c in means.items()},
                                title=f"Success plot ({n} sequence{'s' * (n != 1)})", colours=colours))
    written.append(precision_plot(out / "precision.png", {f: c[1] for f, c in means.items()},
                                  title=f"Precision plot ({n} sequence{'s' * (n != 1)})", colours=colours))
    if n > 1:
        for sequence in sequences:
            mine = {f: curves[(f, sequence)] for f in filters if (f, sequence) in curves}
            written.append(success_plot(out / "plots" / f"{sequence}_success.png",
                                        {f: c[0] for f, c in mine.items()}, title=f"Success plot: {sequence}",
                                        colours=colours))
            written.append(precision_plot(out / "plots" / f"{sequence}_precision.png",
                                          {f: c[1] for f, c in mine.items()}, title=f"Precision plot: {sequence}",
                                          colours=colours))
    return written


def attribute_plot(path: str | Path, by_attribute: Mapping[str, Mapping[str, Mapping]], *,
                   title: str = "Success AUC by attribute", colours=None) -> Path:
    """Grouped bars: per OTB attribute, each tracker's mean success AUC over the sequences carrying it.

    ``by_attribute`` is :func:`vidtrack.eval.attributes.by_attribute`'s
    output; the tick labels give each tag's sequence count.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .attributes import tag_order

    path = Path(path)
    tags = tag_order({t for per in by_attribute.values() for t in per})
    names = list(by_attribute)
    fig, ax = plt.subplots(figsize=(max(5.5, 0.75 * len(tags) * max(1, len(names)) ** 0.5 + 2), 4.2), dpi=110)
    try:
        width = 0.8 / max(1, len(names))
        x = np.arange(len(tags))
        for i, name in enumerate(names):
            heights = [by_attribute[name].get(t, {}).get("auc") for t in tags]
            ax.bar(x - 0.4 + width * (i + 0.5), [np.nan if h is None else h for h in heights], width, label=name,
                   color=_mpl_colour(colours or palette(names), name))
        counts = [max(per[t]["sequences"] for per in by_attribute.values() if t in per) for t in tags]
        ax.set_xticks(x, [f"{t}\n({n})" for t, n in zip(tags, counts)])
        ax.set(title=title, ylabel="Mean success AUC", ylim=(0, 1.15), xlim=(-0.6, len(tags) - 0.4))
        ax.set_yticks(np.linspace(0, 1, 6))
        ax.grid(True, axis="y", alpha=0.3)
        if names:
            ax.legend(loc="upper center", fontsize=7, ncol=min(5, len(names)), frameon=False)
        return _write(fig, path)
    finally:
        plt.close(fig)


def reliability_plot(path: str | Path | None, summary: Mapping[str, Mapping[str, Mapping]], *,
                     title: str = "Reliability diagram", colours=None) -> Path | bytes:
    """The confidence's reliability diagram: per bin, the fraction of frames with IoU > 0.5 against the confidence.

    One line per tracker from its pooled ``mean["reliability"]`` bins
    (:func:`vidtrack.eval.confidence.reliability`), the ECE in the legend; the
    diagonal is a perfectly calibrated confidence.  Writes ``path``, or with
    ``path`` None returns the PNG's bytes.
    """
    import io

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = [n for n in summary if isinstance(summary[n].get("mean", {}).get("reliability"), Mapping)]
    colours = colours or palette(list(summary))
    fig, ax = plt.subplots(figsize=(5.5, 4.2), dpi=110)
    try:
        ax.plot([0, 1], [0, 1], color="0.6", linestyle="--", linewidth=1, label="calibrated")
        for name in names:
            mean = summary[name]["mean"]
            bins = mean["reliability"]
            x = np.array([np.nan if v is None else v for v in bins["confidence"]], float)
            y = np.array([np.nan if v is None else v for v in bins["fraction"]], float)
            used = np.asarray(bins["count"]) > 0
            ece = mean.get("ece")
            label = name if ece is None or not np.isfinite(ece) else f"{name} [ECE {ece:.3f}]"
            ax.plot(x[used], y[used], marker="o", markersize=3, linewidth=1.5, label=label,
                    color=_mpl_colour(colours, name))
        ax.set(title=title, xlabel="Confidence", ylabel="Fraction of frames with IoU > 0.5", xlim=(0, 1),
               ylim=(0, 1.02))
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper left", fontsize=7)
        if path is not None:
            return _write(fig, Path(path))
        fig.tight_layout()
        buffer = io.BytesIO()
        fig.savefig(buffer, format="png")
        return buffer.getvalue()
    finally:
        plt.close(fig)
