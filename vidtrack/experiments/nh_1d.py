"""Table 1 of "An Online Learning-based Framework for Tracking" (Chaudhuri, Freund & Hsu, UAI 2010).

Section 5's one-dimensional simulation: the state ``z_t`` lives on the grid
``G = {-500, ..., 500}``; the measurement at time ``t`` is the whole vector
``M(x, t) = H(x, z_t) + n_t(x)``, ``x in G``, with ``H`` the square pulse of
half-width ``W = 50`` around ``z_t`` and ``n_t(x)`` i.i.d. from
``(1 - rho) N(0, sigma_o^2) + rho N(0, (10 sigma_o)^2)``.  Four trackers
read the same measurements:

* **NH** -- the SMC NormalHedge tracker (Algorithms 2-3,
  :func:`vidtrack.filters.normalhedge.nh_tracking_step`, exactly: no
  pruning) with ``N = 100`` actions, ``alpha = 0.02``,
  ``Sigma_* = 400``, ``F`` the identity and the clipped loss
  ``l_o(x) = -sum_{|g - x| <= W} q(M(g, t))``,
  ``q(y) = min(1 + sigma_o, max(y, -sigma_o))``;
* **Bayes** -- the exact grid filter (:mod:`vidtrack.filters.grid_bayes`)
  with a Gaussian random walk ``sigma_d = 2``, the Gaussian likelihood
  ``M(g, t) ~ N(H(g, x), sigma_o^2)`` with the true ``sigma_o`` and the
  prior ``z_1 = 0``; estimate = posterior mean;
* **PF** -- the particle filter as the paper ran it (it cites de Freitas'
  2000 Matlab code): ``N = 100`` particles, the same model, resampled every
  step, each weighted by the float64 likelihood of the whole 1001-point
  measurement, ``exp(-sum_g (M(g) - H(g, x))^2 / 2 sigma_o^2)``.  The
  exponent is about 500 at ``rho = 0``, 1000 at ``rho = 0.01`` and 3000 at
  ``rho = 0.05``, and float64 underflows below ``e^-745``: with outliers the
  likelihood of every particle is 0, the weights stay uniform and the PF
  goes blind (:func:`float64_likelihood_as_log`).  De Freitas' demos add
  ``1e-99`` to each weight; that floor is left out;
* **PF-log** -- the same SIR filter
  (:func:`vidtrack.filters.particle.sir_step_batch`) with its weights
  computed in logs, i.e. numerically sound; it never goes blind.

Per run the RMSE over the ``T = 200`` steps is computed; the table reports
its mean and standard deviation over the runs.

The true path (``--true-path``): the paper does not give it.  ``ramp``
(the default) is one path for every run, speed 1 for the first ``T/2``
steps, then at rest (RMS 81.5 for ``T = 200``); ``random`` draws a new
path per run, segments of 20-60 steps, each at rest or moving at a constant
velocity uniform in ``[-1, 1]``.  The trackers see the same noise in a run;
the Gaussian log-likelihood of a whole measurement vector is
``sum_{|g - x| <= W} (2 M(g) - 1) / (2 sigma_o^2)`` up to a constant; NH's
continuous action states use the grid points inside ``[x - W, x + W]``.
NH's initial actions are drawn from ``N(z_1, Sigma_*)`` by default
(``--nh-init prior``: the knowledge of ``z_1 = 0`` that Bayes and the PFs
are given); Algorithm 2's "randomly drawn from X" is ``--nh-init uniform``
(uniform on ``[-500, 500]``).

Why these readings, and how close the table comes, are in
``docs/reproduction.md`` (section "NormalHedge").
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from scipy import sparse

from ..errors import UsageError
from ..filters.grid_bayes import gaussian_transition, grid_predict, grid_update_log
from ..filters.normalhedge import nh_tracking_step
from ..filters.particle import sir_step_batch
from .figures import nh_paths
from .paper import claim, comparison, relative_difference

DESCRIPTION = "NormalHedge vs Bayes vs PF on the 1-D pulse simulation (Chaudhuri et al. 2010, Table 1)"

HALF_GRID = 500
WIDTH = 50
GRID = np.arange(-HALF_GRID, HALF_GRID + 1, dtype=float)
DEFAULT_RHOS = (0.0, 0.01, 0.05, 0.1, 0.15, 0.2, 0.4)
DEFAULT_SIGMAS = (1.0, 8.0)
FILTERS = ("NH", "Bayes", "PF", "PF-log")


# ------------------------------------------------------------------- the world


def true_paths(n_runs: int, T: int, rng: np.random.Generator) -> np.ndarray:
    """``(n_runs, T)`` true states: piecewise stationary / constant velocity ``|v| <= 1``, ``z_1 = 0``."""
    paths = np.zeros((n_runs, T))
    for r in range(n_runs):
        velocity = np.zeros(T)
        t = 1
        while t < T:
            length = int(rng.integers(20, 61))
            v = 0.0 if rng.random() < 0.5 else float(rng.uniform(-1.0, 1.0))
            velocity[t:t + length] = v
            t += length
        paths[r] = np.cumsum(velocity)
    return np.clip(paths, -HALF_GRID + WIDTH, HALF_GRID - WIDTH)


def paper_path(T: int) -> np.ndarray:
    """``z_t = min(t, T/2)``: speed 1 for the first half, then at rest (``--true-path ramp``, the default)."""
    return np.minimum(np.arange(T, dtype=float), T // 2)


def measurements(z: np.ndarray, sigma_o: float, rho: float, rng: np.random.Generator) -> np.ndarray:
    """``M(x, t)`` for every grid point, shape ``(n_runs, |G|)``: pulse plus mixture noise."""
    pulse = (np.abs(GRID[None, :] - z[:, None]) <= WIDTH).astype(float)      # H(x, z_t)
    outlier = rng.random(pulse.shape) < rho
    scale = np.where(outlier, 10.0 * sigma_o, sigma_o)
    return pulse + scale * rng.standard_normal(pulse.shape)


def clipped(m: np.ndarray, sigma_o: float) -> np.ndarray:
    """``q(y) = min(1 + sigma_o, max(y, -sigma_o))``."""
    return np.clip(m, -sigma_o, 1.0 + sigma_o)


def window_sums(values: np.ndarray, states: np.ndarray) -> np.ndarray:
    """``sum_{g in G, |g - x| <= W} values[g]`` for every state ``x``.

    values : (R, |G|) per-grid-point values; states : (R, K) real positions.
    Uses prefix sums, so the cost does not depend on ``W``.
    """
    prefix = np.concatenate([np.zeros((values.shape[0], 1)), np.cumsum(values, axis=1)], axis=1)
    lo = np.clip(np.ceil(states - WIDTH), -HALF_GRID, HALF_GRID + 1).astype(int) + HALF_GRID
    hi = np.clip(np.floor(states + WIDTH), -HALF_GRID - 1, HALF_GRID).astype(int) + HALF_GRID + 1
    hi = np.maximum(hi, lo)
    return np.take_along_axis(prefix, hi, axis=1) - np.take_along_axis(prefix, lo, axis=1)


def gaussian_loglik_weights(m: np.ndarray, sigma_o: float) -> np.ndarray:
    """Per-point terms of the Gaussian log-likelihood: ``log p(M | x) = sum_{|g-x|<=W} (2M(g) - 1) / 2 sigma_o^2 + const``."""
    return (2.0 * m - 1.0) / (2.0 * sigma_o ** 2)


def banded_random_walk(sigma_d: float, cutoff: float = 1e-12) -> sparse.csr_matrix:
    """The grid filter's Gaussian random-walk transition as a sparse banded matrix."""
    T = gaussian_transition(GRID, sigma_d)
    T[T < cutoff] = 0.0
    T /= T.sum(axis=0, keepdims=True)
    return sparse.csr_matrix(T)


# -------------------------------------------------------------- one condition


def simulate(sigma_o: float, rho: float, n_runs: int, seed, *, T: int = 200, n_actions: int = 100,
             alpha: float = 0.02, sigma_star2: float = 400.0, sigma_d: float = 2.0, n_particles: int = 100,
             nh_init: str = "prior", true_path: np.ndarray | None = None, keep_paths: int = 0) -> dict:
    """Run the four trackers on ``n_runs`` simulations of one ``(sigma_o, rho)``.

    ``true_path`` (length ``T``) is used for every run when given; otherwise
    each run draws its own with :func:`true_paths`.

    Returns ``{"rmse": {name: (n_runs,)}, "paths": {...}}`` where ``paths``
    holds the true and estimated paths of the first ``keep_paths`` runs.
    """
    world_rng = np.random.default_rng([seed, 0])
    nh_rng = np.random.default_rng([seed, 1])
    pf_rngs = {"PF": np.random.default_rng([seed, 2]), "PF-log": np.random.default_rng([seed, 3])}
    if true_path is None:
        z = true_paths(n_runs, T, world_rng)
    else:
        z = np.broadcast_to(np.asarray(true_path, dtype=float)[:T], (n_runs, T))
    est = {name: np.zeros((n_runs, T)) for name in FILTERS}

    # NH: N actions, R = 0, w = 1/N (Algorithm 2); drawn uniformly on the
    # state space ("uniform") or from N(z_1, Sigma_*) ("prior": the knowledge
    # of z_1 the Bayes filter and the PFs get).
    sigma_star = float(np.sqrt(sigma_star2))
    if nh_init == "uniform":
        nh_states = nh_rng.uniform(-HALF_GRID, HALF_GRID, size=(n_runs, n_actions, 1))
    elif nh_init == "prior":
        nh_states = z[:, :1, None] + sigma_star * nh_rng.standard_normal((n_runs, n_actions, 1))
    else:
        raise UsageError(f"unknown NH initialisation {nh_init!r}; valid: prior, uniform")
    nh_regrets = np.zeros((n_runs, n_actions))
    nh_weights = np.full((n_runs, n_actions), 1.0 / n_actions)
    # Bayes: prior all mass on z_1 = 0.
    transition = banded_random_walk(sigma_d)
    posterior = np.zeros((len(GRID), n_runs))
    posterior[HALF_GRID] = 1.0
    # PFs: every particle at z_1 = 0.
    particles = {name: np.zeros((n_runs, n_particles)) for name in pf_rngs}
    pf_weights = {name: np.full((n_runs, n_particles), 1.0 / n_particles) for name in pf_rngs}

    def propagate(x, rng):  # x_k = x_{k-1} + N(0, sigma_d^2)
        return x + sigma_d * rng.standard_normal(x.shape)

    for t in range(T):
        m = measurements(z[:, t], sigma_o, rho, world_rng)
        q = clipped(m, sigma_o)
        ll_terms = gaussian_loglik_weights(m, sigma_o)

        out = nh_tracking_step(nh_states, nh_regrets, nh_weights, lambda s, q=q: -window_sums(q, s[..., 0]),
                               nh_rng, alpha=alpha, sigma_star=sigma_star)
        nh_states, nh_regrets, nh_weights = out["next_states"], out["regrets"], out["weights"]
        est["NH"][:, t] = out["estimate"][:, 0]

        if t > 0:  # z_1 is known exactly: the first estimate is the prior's
            posterior = np.asarray(grid_predict(posterior, transition))
            loglik = window_sums(ll_terms, np.broadcast_to(GRID, (n_runs, len(GRID)))).T
            for r in range(n_runs):
                posterior[:, r] = grid_update_log(posterior[:, r], loglik[:, r])
            particles["PF-log"], pf_weights["PF-log"], _ = sir_step_batch(
                particles["PF-log"], pf_weights["PF-log"], propagate, lambda x, ll=ll_terms: window_sums(ll, x),
                pf_rngs["PF-log"])
            particles["PF"], pf_weights["PF"], _ = sir_step_batch(
                particles["PF"], pf_weights["PF"], propagate, float64_likelihood_as_log(m, ll_terms, sigma_o),
                pf_rngs["PF"], resample_below=ALWAYS_RESAMPLE)
        est["Bayes"][:, t] = GRID @ posterior
        for name in pf_rngs:
            est[name][:, t] = np.sum(particles[name] * pf_weights[name], axis=1)

    rmse = {name: np.sqrt(np.mean((est[name] - z) ** 2, axis=1)) for name in FILTERS}
    paths = {"truth": z[:keep_paths].tolist(), **{name: est[name][:keep_paths].tolist() for name in FILTERS}}
    return {"rmse": rmse, "paths": paths}


ALWAYS_RESAMPLE = 2.0  # sir_step_batch resamples when N_eff < this * N: always, as de Freitas' code does


def float64_likelihood_as_log(m: np.ndarray, ll_terms: np.ndarray, sigma_o: float):
    """The paper's PF weights: ``exp(-sum_g (M(g) - H(g, x))^2 / 2 sigma_o^2)`` evaluated in float64.

    Returned as the log of that float64 number, so an underflowed likelihood
    is ``-inf``; when every particle underflows, :func:`sir_step_batch` keeps
    the weights uniform (what a guarded ``w / sum(w)`` does).  The exponent is
    the full sum of squares, ``sum_g M(g)^2 / 2 sigma_o^2`` minus the window
    terms of :func:`gaussian_loglik_weights`, so it differs from the log-space
    PF's only in the underflow.
    """
    offset = np.sum(m * m, axis=1, keepdims=True) / (2.0 * sigma_o ** 2)

    def log_of_float64_likelihood(x):
        with np.errstate(divide="ignore", under="ignore"):
            return np.log(np.exp(window_sums(ll_terms, x) - offset))

    return log_of_float64_likelihood


# ------------------------------------------------------------------ protocol


def _float_list(text: str) -> list[float]:
    try:
        values = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise UsageError(f"expected comma-separated numbers, got {text!r}") from None
    if not values:
        raise UsageError("expected at least one number")
    return values


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--rhos", default=",".join(str(r) for r in DEFAULT_RHOS),
                        help="outlier fractions rho (default 0,0.01,0.05,0.1,0.15,0.2,0.4)")
    parser.add_argument("--sigmas", default="1,8", help="noise levels sigma_o (default 1,8)")
    parser.add_argument("--steps", type=int, default=200, help="time steps T (default 200)")
    parser.add_argument("--nh-init", choices=("prior", "uniform"), default="prior",
                        help="NH's initial actions: N(z_1, Sigma_*) (default) or uniform on [-500, 500]")
    parser.add_argument("--true-path", choices=("ramp", "random"), default="ramp",
                        help="ramp: speed 1 for T/2 steps then at rest, one path for every run, the path the "
                             "paper's PF rows imply (default); random: a new piecewise path per run")
    parser.add_argument("--plot", metavar="FILE", help="plot true/NH/Bayes paths of 5 runs (like Figs 2-3)")
    parser.add_argument("--plot-rho", type=float, default=0.2, help="rho of the plotted runs (default 0.2)")


def run(args, progress) -> dict:
    n_runs = args.runs or 100
    rhos = _float_list(args.rhos)
    sigmas = _float_list(args.sigmas)
    if any(not 0.0 <= r <= 1.0 for r in rhos):
        raise UsageError("--rhos must lie in [0, 1]")
    if any(s <= 0 for s in sigmas):
        raise UsageError("--sigmas must be positive")
    if args.steps < 2:
        raise UsageError("--steps must be at least 2")
    plot_path = getattr(args, "plot", None)
    if plot_path:
        from ..sinks.base import open_text_output  # fail early on an unwritable path
        open_text_output(plot_path).close()
    shared_path = paper_path(args.steps) if args.true_path == "ramp" else None
    conditions = [(s, r) for s in sigmas for r in rhos]
    rows, plotted = [], {}
    start = time.perf_counter()
    for index, (sigma_o, rho) in enumerate(progress(conditions, total=len(conditions), desc="nh-1d")):
        keep = 5 if plot_path and abs(rho - args.plot_rho) < 1e-12 else 0
        result = simulate(sigma_o, rho, n_runs, [args.seed, index], T=args.steps, keep_paths=keep,
                          nh_init=args.nh_init, true_path=shared_path)
        row = {"sigma_o": sigma_o, "rho": rho}
        for name in FILTERS:
            values = result["rmse"][name]
            row[name] = {"mean": float(np.mean(values)), "sd": float(np.std(values, ddof=1)) if n_runs > 1 else 0.0}
        rows.append(row)
        if keep:
            plotted[sigma_o] = result["paths"]
    out = {"experiment": "nh-1d", "runs": n_runs, "seed": args.seed, "steps": args.steps,
           "nh_init": args.nh_init, "true_path": args.true_path,
           "seconds": round(time.perf_counter() - start, 1), "rows": rows}
    if plot_path:
        if not plotted:
            raise UsageError(f"--plot-rho {args.plot_rho} is not one of --rhos")
        out["plot"] = nh_paths(plotted, args.plot_rho, plot_path)
    out["vs_paper"] = paper_comparisons(out)
    out["claims"] = claims(out)
    return out


#: Table 1 of the paper (mean, sd of the RMSE over 100 simulations): PAPER[sigma_o][rho][filter].  Typed from the
#: paper as the targets; the paper has no PF-log column and no rho = 0.4 row.
PAPER = {
    1.0: {0.00: {"NH": (3.18, 0.33), "Bayes": (1.17, 0.09), "PF": (1.23, 0.11)},
          0.01: {"NH": (3.21, 0.34), "Bayes": (1.90, 0.25), "PF": (3.98, 1.06)},
          0.05: {"NH": (3.26, 0.34), "Bayes": (3.99, 0.52), "PF": (81.70, 1.74)},
          0.10: {"NH": (3.31, 0.35), "Bayes": (6.40, 0.84), "PF": (81.70, 1.74)},
          0.15: {"NH": (3.42, 0.34), "Bayes": (8.38, 1.10), "PF": (81.70, 1.74)},
          0.20: {"NH": (3.52, 0.41), "Bayes": (10.28, 1.24), "PF": (81.70, 1.74)}},
    8.0: {0.00: {"NH": (10.93, 2.52), "Bayes": (10.98, 2.33), "PF": (14.35, 5.16)},
          0.01: {"NH": (11.26, 3.43), "Bayes": (12.76, 3.07), "PF": (44.29, 16.7)},
          0.05: {"NH": (12.03, 3.47), "Bayes": (19.75, 6.70), "PF": (81.70, 1.74)},
          0.10: {"NH": (12.25, 2.93), "Bayes": (27.33, 10.9), "PF": (81.70, 1.74)},
          0.15: {"NH": (13.38, 3.07), "Bayes": (32.78, 13.1), "PF": (81.70, 1.74)},
          0.20: {"NH": (14.15, 3.88), "Bayes": (43.99, 26.8), "PF": (81.70, 1.74)}},
}


def paper_value(sigma_o: float, rho: float, name: str) -> tuple[float, float] | None:
    """The paper's ``(mean, sd)`` for one cell, or None."""
    for r, cells in PAPER.get(float(sigma_o), {}).items():
        if abs(r - rho) < 1e-9:
            return cells.get(name)
    return None


def paper_comparisons(result: dict) -> list[dict]:
    return [comparison(f"Table 1 sigma_o={row['sigma_o']:g}", f"rho={row['rho']:g}", name, row[name]["mean"], ref[0])
            for row in result["rows"] for name in FILTERS
            if (ref := paper_value(row["sigma_o"], row["rho"], name)) is not None]


def claims(result: dict) -> list[dict]:
    """Table 1's claims: NH beats Bayes once outliers appear (rho >= 0.05), and the means within their spread."""
    out = []
    for sigma_o in sorted({row["sigma_o"] for row in result["rows"]}):
        rows = [r for r in result["rows"] if r["sigma_o"] == sigma_o and r["rho"] >= 0.05 and paper_value(sigma_o, r["rho"], "NH")]
        if rows:
            wins = [r for r in rows if r["NH"]["mean"] < r["Bayes"]["mean"]]
            out.append(claim(f"sigma_o = {sigma_o:g}: NH has a lower RMSE than Bayes at every rho >= 0.05",
                             len(wins) == len(rows), f"{len(wins)}/{len(rows)} rows"))
        cells = [(r, n, paper_value(sigma_o, r["rho"], n)) for r in result["rows"] if r["sigma_o"] == sigma_o
                 for n in ("NH", "Bayes", "PF")]
        cells = [(r, n, ref) for r, n, ref in cells if ref is not None]
        if cells:
            # standard error of the difference of two means: paper over 100 runs, vidtrack over result["runs"]
            def se(r, n, ref):
                return np.sqrt(ref[1] ** 2 / 100 + r[n]["sd"] ** 2 / max(result["runs"], 1))

            outside = [f"{n} rho={r['rho']:g}" for r, n, ref in cells if abs(r[n]["mean"] - ref[0]) > 2 * se(r, n, ref)]
            out.append(claim(f"sigma_o = {sigma_o:g}: every NH/Bayes/PF mean within 2 standard errors of the paper's",
                             not outside, f"{len(cells) - len(outside)}/{len(cells)} cells"
                             + (f"; outside: {', '.join(outside)}" if outside else "")))
    return out


def format_table(result: dict) -> str:
    lines = [f"Table 1 (Chaudhuri et al. 2010): RMSE over T={result['steps']} steps, "
             f"mean ± sd over {result['runs']} runs (seed {result['seed']}, NH init {result['nh_init']}, "
             f"{result['true_path']} true path, {result['seconds']} s)",
             "PF: the paper's particle filter (float64 likelihood; blind once it underflows); "
             "PF-log: the same filter in logs",
             "cells: vidtrack mean ± sd [paper mean, relative difference of the means]"]
    for sigma_o in sorted({row["sigma_o"] for row in result["rows"]}):
        label = "Low" if sigma_o <= 1 else "High"
        lines.append(f"{label} Noise (sigma_o = {sigma_o:g})")
        lines.append(f"{'rho':>6}  " + "  ".join(f"{name:>32}" for name in FILTERS))
        for row in result["rows"]:
            if row["sigma_o"] != sigma_o:
                continue
            cells = []
            for n in FILTERS:
                ref = paper_value(sigma_o, row["rho"], n)
                d = None if ref is None else relative_difference(row[n]["mean"], ref[0])
                tail = f" [{ref[0]:.2f}, {100 * d:+.1f}%]" if d is not None else " [-]"
                cells.append(f"{row[n]['mean']:7.2f} ± {row[n]['sd']:6.2f}{tail}")
            lines.append(f"{row['rho']:6.2f}  " + "  ".join(f"{c:>32}" for c in cells))
    for c in result.get("claims", []):
        lines.append(f"claim {'holds' if c['holds'] else 'does NOT hold'}: {c['claim']} -- {c['detail']}")
    return "\n".join(lines)
