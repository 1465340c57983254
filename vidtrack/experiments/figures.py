"""PNG figures of the reproductions: truth vs estimates, like the papers' figures.

The only module of the experiments that imports matplotlib (with the
non-interactive ``Agg`` backend, on first use).  Each function draws what an
experiment computed -- the experiments run their filters on extra
realisations from their own random streams, so the tables do not change when
figures are asked for -- and returns the paths it wrote.  Nothing here runs
a filter or imports an experiment.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def svk_trajectories(p: np.ndarray, estimates: dict[str, np.ndarray], kind: str, r: float, out_dir) -> list[str]:
    """Salti & Di Stefano's Fig. 4 (and Figs. 9-10 for the non-linear motion): truth ``p`` and the estimates.

    Top: SVK against the Kalman and IMM filters tuned for smoothness
    (``Q = 1e-4 R``); bottom: against those tuned for responsiveness
    (``Q = 1e-2 R``).  ``estimates`` maps the table's filter names to their
    positions on one realisation at ``R = r I``.  Returns the PNG path.
    """
    plt = _pyplot()
    fig, axes = plt.subplots(2, 1, figsize=(11, 8), sharex=True)
    for ax, tuning in zip(axes, ("1e-4", "1e-2")):
        ax.plot(p, "k--", lw=2, label="truth")
        ax.plot(estimates["SVK"], "c", lw=1.5, label="SVK")
        for name, est in estimates.items():
            if name != "SVK" and f"Q={tuning}R" in name:
                ax.plot(est, lw=1, label=name)
        span = p.max() - p.min()
        ax.set_ylim(p.min() - 0.1 * span, p.max() + 0.1 * span)
        ax.set_ylabel("position")
        ax.set_title(f"{kind} motion, R = {r:g} I: SVK vs filters tuned Q = {tuning} R", fontsize=10)
        ax.legend(fontsize=7, ncol=3)
    axes[-1].set_xlabel("sample")
    fig.tight_layout()
    path = Path(out_dir) / f"svk-{kind}-trajectories.png"
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return [str(path)]


def carlin_trajectories(x: np.ndarray, estimates: dict[str, np.ndarray], out_dir) -> list[str]:
    """Carlin's experiment: the true state of one test sequence and every method's estimate."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(11, 4.5))
    k = np.arange(1, len(x))
    ax.plot(k, x[1:], "k--", lw=2, label="truth")
    for name, est in estimates.items():
        ax.plot(k, est, lw=1, marker=".", ms=3, label=name)
    ax.set_ylim(x.min() - 10.0, x.max() + 10.0)  # an EKF divergence would flatten everything else
    ax.set_xlabel("k")
    ax.set_ylabel("x_k")
    ax.set_title("Carlin's experiment (univariate growth model): truth vs estimates, one test sequence", fontsize=10)
    ax.legend(fontsize=8, ncol=3)
    fig.tight_layout()
    path = Path(out_dir) / "cbt-carlin-trajectories.png"
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return [str(path)]


def nh_paths(plotted: dict[float, dict], rho: float, path: str) -> str:
    """Chaudhuri, Freund & Hsu's Figs. 2-3: true, NH and Bayes paths of five runs per noise level.

    ``plotted`` maps ``sigma_o`` to the paths of :func:`vidtrack.experiments.nh_1d.simulate`
    (``"truth"``, ``"NH"``, ``"Bayes"``: lists of per-run paths) at outlier fraction ``rho``.
    Returns ``path``.
    """
    plt = _pyplot()
    fig, axes = plt.subplots(len(plotted), 5, figsize=(16, 3.2 * len(plotted)), squeeze=False)
    for row, (sigma_o, paths) in enumerate(sorted(plotted.items())):
        for k in range(min(5, len(paths["truth"]))):
            ax = axes[row, k]
            ax.plot(paths["truth"][k], "k--", label="true")
            ax.plot(paths["NH"][k], "b", label="NH")
            ax.plot(paths["Bayes"][k], "r", label="Bayes")
            ax.set_title(f"sigma_o={sigma_o:g}, rho={rho:g}, run {k + 1}", fontsize=9)
            truth = np.asarray(paths["truth"][k])
            ax.set_ylim(truth.min() - 120, truth.max() + 120)
    axes[0, 0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path
