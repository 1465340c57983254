"""PNG figures of the reproductions: truth vs estimates, like the papers' figures.

Only this module (and :mod:`vidtrack.experiments.nh_1d`'s ``--plot``)
imports matplotlib, with the non-interactive ``Agg`` backend.  Each function
runs the experiment's own filters on one extra realisation drawn from its own
random stream (so the tables do not change when figures are asked for) and
returns the paths it wrote.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def svk_trajectories(args, kind: str, truth: tuple[np.ndarray, np.ndarray], make_filters, out_dir) -> list[str]:
    """Salti & Di Stefano's Fig. 4 (and Figs. 9-10 for the non-linear motion), at ``R = 100 I``.

    Top: SVK against the Kalman and IMM filters tuned for smoothness
    (``Q = 1e-4 R``); bottom: against those tuned for responsiveness
    (``Q = 1e-2 R``).  Returns the PNG path.
    """
    from .svk_tables import run_filter

    plt = _pyplot()
    r = 100.0
    p, v = truth
    rng = np.random.default_rng([args.seed, 7])
    z = np.stack([p, v], axis=1) + rng.normal(0.0, np.sqrt(r), size=(len(p), 2))
    makers = make_filters(args, kind, r)
    estimates = {name: run_filter(make(), z, r) for name, make in makers.items()}
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
        ax.set_title(f"{kind} motion, R = 100 I: SVK vs filters tuned Q = {tuning} R", fontsize=10)
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
