"""Tables 1-3 of Salti & Di Stefano, *On-line Support Vector Regression of the Transition Model for the Kalman Filter*.

``vidtrack reproduce svk-linear`` (section 7.1, Tables 1 and 2) and
``vidtrack reproduce svk-nonlinear`` (section 7.2, Table 3): a point on a
line, position and velocity measured with Gaussian noise ``R = r I``
(``r`` = 100 and 1000), tracked by the Support Vector Kalman, Kalman DR, CV,
CA and the IMMs with the CA pool (DR+CV+CA) and the CV pool (DR+CV), each
tuned responsive (``Q = 1e-2 R``) and smooth (``Q = 1e-4 R``).  The IMMs use
the uniform transition probability matrix.  The RMSE is that of the position.

Motion (reconstructed from the text; see the assumptions below):

* linear: ``dt = 0.5``, 160 samples each of constant acceleration (30
  m/s^2 from rest at the origin), constant position, constant velocity
  (1000 m/s); Tables 1-2 give the RMSE on the whole sequence, on each
  interval and on each interval's last 80 samples (starred);
* non-linear: ``dt = 0.01``, 160 samples of eq. 15, 160 of constant position
  and 160 of eq. 16, with ``t`` running on through the whole sequence (so
  the position jumps where eq. 16 takes over); Table 3 gives the RMSE on
  the whole sequence.

Assumptions (the paper does not state them): the non-linear ``dt`` and time
origin were chosen because they reproduce the seed's Kalman rows (Table 3)
closely; every filter starts at the first measurement with ``P0 = r I``
(acceleration 0 with variance ``r``); in the IMMs a model's unmodelled
derivatives get process variance ``unmodelled_q * r`` (default ``r``: the
model is agnostic about the derivatives it does not carry; with 0 they are
pinned at the model's zero rows and the IMMs react far slower to the jumps of
the motion than the seed's); the SVK bootstraps
with a constant-velocity model and ``Q0 = 1e-2 R`` for its first ``W``
samples and uses ``epsilon = 0.1`` (libsvm's default) in normalised units.
"""

from __future__ import annotations

import argparse
from typing import Callable

import numpy as np

from ..filters.imm import IMMEstimator, uniform_transition_matrix
from ..filters.kalman import MOTION_ORDERS, KalmanFilter, measured_axis_model
from ..filters.svk import SupportVectorKalman

DESCRIPTION = "Support Vector Kalman vs Kalman/IMM on 1-D motion (Salti & Di Stefano, Tables 1-3)"

SEGMENT = 160  #: samples per motion interval
STEADY = 80  #: the starred columns use each interval's last STEADY samples
DEFAULT_RUNS = 10  #: noise realisations averaged unless --runs
NOISE_LEVELS = (100.0, 1000.0)
INTERVALS = {"linear": ("CA", "Drift", "CV"), "nonlinear": ("Eq15", "Drift", "Eq16")}
DT = {"linear": 0.5, "nonlinear": 0.01}
DEFAULT_C = {"linear": 2.0 ** -10, "nonlinear": 2.0}  # section 7.1
FILTER_NAMES = (
    "SVK",
    "IMM CA Q=1e-2R", "IMM CA Q=1e-4R", "IMM CV Q=1e-2R", "IMM CV Q=1e-4R",
    "Kalman CA Q=1e-2R", "Kalman CA Q=1e-4R", "Kalman CV Q=1e-2R", "Kalman CV Q=1e-4R",
    "Kalman DR Q=1e-2R", "Kalman DR Q=1e-4R",
)
IMM_POOLS = {"CA": ("dr", "cv", "ca"), "CV": ("dr", "cv")}


# ----------------------------------------------------------------- motion


def linear_motion(dt: float = 0.5, n: int = SEGMENT, acceleration: float = 30.0,
                  velocity: float = 1000.0) -> tuple[np.ndarray, np.ndarray]:
    """True ``(position, velocity)`` of section 7.1: CA, then constant position, then CV."""
    t = np.arange(n) * dt
    p_ca, v_ca = 0.5 * acceleration * t ** 2, acceleration * t
    p_dr, v_dr = np.full(n, p_ca[-1]), np.zeros(n)
    p_cv, v_cv = p_ca[-1] + velocity * (t + dt), np.full(n, velocity)
    return np.concatenate([p_ca, p_dr, p_cv]), np.concatenate([v_ca, v_dr, v_cv])


def nonlinear_motion(dt: float = 0.01, n: int = SEGMENT) -> tuple[np.ndarray, np.ndarray]:
    """True ``(position, velocity)`` of section 7.2: eq. 15, constant position, eq. 16.

    ``x1(t) = 300 t + 300 sin(2 pi t) + 300 cos(2 pi t)`` (eq. 15) and
    ``x2(t) = 300 t - 300 sin(2 pi t) - 300 cos(2 pi t)`` (eq. 16), ``t = k dt``
    over the whole sequence.
    """
    w = 2.0 * np.pi
    t = np.arange(3 * n) * dt
    t1, t2 = t[:n], t[2 * n:]
    x1 = 300 * t1 + 300 * np.sin(w * t1) + 300 * np.cos(w * t1)
    v1 = 300 + 300 * w * (np.cos(w * t1) - np.sin(w * t1))
    x2 = 300 * t2 - 300 * np.sin(w * t2) - 300 * np.cos(w * t2)
    v2 = 300 - 300 * w * (np.cos(w * t2) - np.sin(w * t2))
    return np.concatenate([x1, np.full(n, x1[-1]), x2]), np.concatenate([v1, np.zeros(n), v2])


# ----------------------------------------------------------------- filters


def kalman(model: str, *, dt: float, q: float, r: float, order: int | None = None,
           unmodelled_q: float = 0.0) -> KalmanFilter:
    """A 1-D Kalman filter with position and velocity measured."""
    return KalmanFilter(*measured_axis_model(model, dt=dt, q=q, r=r, order=order, unmodelled_q=unmodelled_q))


def imm(pool: tuple[str, ...], *, dt: float, q: float, r: float, unmodelled_q: float) -> IMMEstimator:
    """IMM over ``pool`` embedded in a common state, uniform transition probabilities."""
    order = max(MOTION_ORDERS[m] for m in pool)
    filters = [kalman(m, dt=dt, q=q, r=r, order=order, unmodelled_q=unmodelled_q * r) for m in pool]
    return IMMEstimator(filters, uniform_transition_matrix(len(filters)))


def svk(*, dt: float, r: float, C: float, epsilon: float, window: int, n_folds: int) -> SupportVectorKalman:
    """SVK on ``[p, v]`` (a 2x2 learned model), bootstrapping with CV and ``Q0 = 1e-2 R``."""
    F, Q, H, R = measured_axis_model("cv", dt=dt, q=1e-2 * r, r=r)
    return SupportVectorKalman(H, R, F, Q, C=C, epsilon=epsilon, window=window, n_folds=n_folds)


def make_filters(args: argparse.Namespace, kind: str, r: float) -> dict[str, Callable[[], object]]:
    """Factories of every filter of the table, by name."""
    dt = DT[kind]
    C = DEFAULT_C[kind] if args.C is None else args.C
    makers: dict[str, Callable[[], object]] = {
        "SVK": lambda: svk(dt=dt, r=r, C=C, epsilon=args.epsilon, window=args.window, n_folds=args.folds)}
    for pool_name, pool in IMM_POOLS.items():
        for label, scale in (("1e-2", 1e-2), ("1e-4", 1e-4)):
            makers[f"IMM {pool_name} Q={label}R"] = (
                lambda pool=pool, scale=scale: imm(pool, dt=dt, q=scale * r, r=r, unmodelled_q=args.unmodelled_q))
    for model in ("ca", "cv", "dr"):
        for label, scale in (("1e-2", 1e-2), ("1e-4", 1e-4)):
            makers[f"Kalman {model.upper()} Q={label}R"] = (
                lambda model=model, scale=scale: kalman(model, dt=dt, q=scale * r, r=r))
    return makers


def state_size(filt) -> int:
    """Length of the state of a Kalman filter, an IMM or an SVK."""
    if hasattr(filt, "filters"):
        return state_size(filt.filters[0])
    return int(filt.H.shape[1])


def run_filter(filt, z: np.ndarray, r: float) -> np.ndarray:
    """Filtered positions: start at ``z[0]`` with ``P0 = r I``, then predict/update each sample."""
    n = state_size(filt)
    x0 = np.zeros(n)
    x0[:min(n, 2)] = z[0, :min(n, 2)]
    filt.initialize(x0, r * np.eye(n))
    out = np.empty(len(z))
    out[0] = filt.x_[0]
    for k in range(1, len(z)):
        filt.predict()
        filt.update(z[k])
        out[k] = filt.x_[0]
    return out


# ----------------------------------------------------------------- experiment


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--C", type=float, default=None,
                        help="SVR C (default: the paper's, 2^-10 linear, 2 non-linear)")
    parser.add_argument("--epsilon", type=float, default=0.1, help="SVR epsilon, normalised units (default 0.1)")
    parser.add_argument("--window", type=int, default=10, help="SVK training window W (default 10)")
    parser.add_argument("--folds", type=int, default=5, help="cross-validation folds for Q (default 5)")
    parser.add_argument("--unmodelled-q", type=float, default=1.0,
                        help="IMM: process variance of a model's unmodelled derivatives, in units of r (default 1)")


def squared_errors(r: float, makers: dict, rng: np.random.Generator,
                   truth: tuple[np.ndarray, np.ndarray]) -> dict[str, np.ndarray]:
    """One noise realisation: squared position error per sample, per filter."""
    p, v = truth
    z = np.stack([p, v], axis=1) + rng.normal(0.0, np.sqrt(r), size=(len(p), 2))
    return {name: (run_filter(make(), z, r) - p) ** 2 for name, make in makers.items()}


def summarise(kind: str, squared: dict[str, np.ndarray]) -> list[dict]:
    """RMSE rows of one realisation: whole sequence (and, linear, per interval and their last ``STEADY`` samples)."""
    rows = []
    for name in FILTER_NAMES:
        e2 = squared[name]
        row = {"filter": name, "whole": float(np.sqrt(e2.mean()))}
        if kind == "linear":
            for i, interval in enumerate(INTERVALS[kind]):
                seg = e2[i * SEGMENT:(i + 1) * SEGMENT]
                row[interval] = float(np.sqrt(seg.mean()))
                row[interval + "*"] = float(np.sqrt(seg[-STEADY:].mean()))
        rows.append(row)
    return rows


def average_rows(per_run: list[list[dict]]) -> list[dict]:
    """Column-wise mean over realisations of the per-run RMSE rows."""
    out = []
    for rows in zip(*per_run):
        keys = [k for k in rows[0] if k != "filter"]
        out.append({"filter": rows[0]["filter"], **{k: float(np.mean([r[k] for r in rows])) for k in keys}})
    return out


def run(args: argparse.Namespace, progress) -> dict:
    """Average, over ``--runs`` noise realisations, of each realisation's RMSE.

    The seed's tables are one realisation each; the mean of per-run RMSEs
    estimates what one realisation gives (pooling the squared errors of all
    runs first would weight the rare large transients of the motion switches
    more and give a slightly larger figure).
    """
    kind = "nonlinear" if args.experiment == "svk-nonlinear" else "linear"
    for name in ("window", "folds"):
        if getattr(args, name) < 2:
            from ..errors import UsageError
            raise UsageError(f"--{name} must be at least 2")
    runs = DEFAULT_RUNS if args.runs is None else args.runs
    truth = linear_motion(DT[kind]) if kind == "linear" else nonlinear_motion(DT[kind])
    rng = np.random.default_rng(args.seed)
    result: dict = {"experiment": args.experiment, "runs": runs, "seed": args.seed,
                    "aggregate": "mean over runs of each run's position RMSE"}
    per_run: dict[float, list] = {r: [] for r in NOISE_LEVELS}
    for _ in progress(range(runs), total=runs, desc=args.experiment):
        for r in NOISE_LEVELS:
            per_run[r].append(summarise(kind, squared_errors(r, make_filters(args, kind, r), rng, truth)))
    for r in NOISE_LEVELS:
        result[f"R{r:g}"] = average_rows(per_run[r])
    return result


def format_table(result: dict) -> str:
    linear = result.get("experiment") != "svk-nonlinear"
    columns = ["whole", "CA", "Drift", "CV", "CA*", "Drift*", "CV*"] if linear else ["whole"]
    titles = {"whole": "Whole"}
    lines = []
    for key in (k for k in result if k.startswith("R")):
        table = "Table 1" if key == "R100" else "Table 2"
        caption = (f"{table}: RMSE on linear motion, R = {key[1:]} I" if linear
                   else f"Table 3: RMSE on non-linear motion, R = {key[1:]} I")
        lines.append(f"{caption} ({result['runs']} runs, seed {result['seed']})")
        lines.append(f"{'Filter':<20}" + "".join(f"{titles.get(c, c):>10}" for c in columns))
        for row in result[key]:
            lines.append(f"{row['filter']:<20}" + "".join(f"{row[c]:>10.2f}" for c in columns))
        lines.append("")
    return "\n".join(lines).rstrip()
