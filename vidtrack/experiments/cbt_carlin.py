"""Carlin's experiment: Channel-Based Tracking vs EKF, grid filter and SIR particle filter.

The table of Felsberg & Larsson, "Learning Object Tracking in Image
Sequences" / "Channel-Based Tracking", comparing CBT with the algorithms of
Arulampalam et al.'s particle-filter tutorial ("A Tutorial on Particle
Filters for Online Nonlinear/Non-Gaussian Bayesian Tracking") on the
univariate nonstationary growth model::

    x_k = x_{k-1}/2 + 25 x_{k-1} / (1 + x_{k-1}^2) + 8 cos(1.2 k) + v_{k-1},  var(v) = 10
    z_k = x_k^2 / 20 + n_k,                                                 var(n) = 1

CBT: second-order model embedded in a first-order one, 12 cos² channels for
the state and 12 for the observation, trained on ``--train`` sequences with
known states (covariance estimate eq. 11 for ``F`` and the measurement
matrix for ``h``); the ``8 cos(1.2 k)`` term is given (the paper models it:
it is not stationary) and applied as a translation of the predicted channel
vector, everything else is learned.  Estimates are the decoded strongest
mode of the posterior marginal (eq. 8).

Comparators with the true model, sharing vidtrack's filter code: the EKF
(:mod:`vidtrack.filters.ekf`), the approximate grid-based filter with 50
points (:mod:`vidtrack.filters.grid_bayes`) and the SIR particle filter with
50 particles, resampled every step (:mod:`vidtrack.filters.particle`).

An extra row, ``CBT+BW``, refines the learned model by Baum-Welch (eqs.
17-19, :func:`vidtrack.learn.baum_welch.baum_welch`) from the training
observations alone (no states), starting from the covariance estimates, as
the paper does for data without ground truth.  By default only ``F`` is
re-estimated, with the covariance estimate as a Dirichlet prior of weight
:data:`BW_PRIOR` per history column (MAP-EM); ``--bw-learn-h --bw-prior 0``
re-estimates ``F`` and ``h`` by maximum likelihood as the paper writes it,
``--bw-product sqrt`` uses square-root products.  The claim checked is that
the refined model is not worse than the covariance estimate (the paired
difference of the RMSE at most two standard errors).

Setup (where the paper is silent): ``T = 50`` steps, ``x_0 = 0.1`` known to
every method (the filters' prior is ``N(0.1, 2)``), the grid on ``[-30, 30]``,
the CBT channel ranges spanning the 1st-99th percentiles of the training
data, RMSE per run over ``k = 1..T`` averaged over the runs.  How close the
table comes is in ``docs/reproduction.md`` (section "Channel-Based Tracking").
"""

from __future__ import annotations

import time

import numpy as np

from ..channels import ChannelBasis, decode, encode, history_prior, shift_matrix
from ..filters.channels import ChannelBayesFilter
from ..filters.ekf import ExtendedKalmanFilter
from ..filters.grid_bayes import GridBayesFilter, gaussian_transition
from ..filters.particle import sir_step, systematic_resample
from ..learn.baum_welch import baum_welch, embedded_covariance, measurement_matrix
from .figures import carlin_trajectories
from .paper import LEGEND, cell, claim, comparison

DESCRIPTION = "Carlin's experiment (CBT paper table): RMSE of CBT vs EKF, grid filter, SIR PF"

#: Baum-Welch: Dirichlet prior weight of the covariance estimate, per history column (MAP-EM; 0: eq. 18's ML).
BW_PRIOR = 10.0
Q_VAR = 10.0
R_VAR = 1.0
X0 = 0.1
P0 = 2.0
#: CBT channel ranges span the training data between these percentiles (the rest is clipped to the ends).
RANGE_PERCENTILE = 1.0


def drive(k: int) -> float:
    """The known time-dependent term ``8 cos(1.2 k)``."""
    return 8.0 * np.cos(1.2 * k)


def growth(x, k: int):
    """``f_k(x) = x/2 + 25 x / (1 + x^2) + 8 cos(1.2 k)``."""
    x = np.asarray(x, dtype=float)
    return 0.5 * x + 25.0 * x / (1.0 + x * x) + drive(k)


def growth_jacobian(x, k: int):
    x = np.asarray(x, dtype=float)
    return 0.5 + 25.0 * (1.0 - x * x) / (1.0 + x * x) ** 2


def observe(x):
    """``h(x) = x^2 / 20``."""
    return np.asarray(x, dtype=float) ** 2 / 20.0


def simulate(rng: np.random.Generator, steps: int) -> tuple[np.ndarray, np.ndarray]:
    """One sequence: states ``x_0..x_T`` and observations ``z_0..z_T`` (``z_0`` unused, NaN)."""
    x = np.empty(steps + 1)
    z = np.full(steps + 1, np.nan)
    x[0] = X0
    for k in range(1, steps + 1):
        x[k] = growth(x[k - 1], k) + rng.normal(0.0, np.sqrt(Q_VAR))
        z[k] = observe(x[k]) + rng.normal(0.0, np.sqrt(R_VAR))
    return x, z


# ------------------------------------------------------------------ CBT


def train_cbt(train: list[tuple[np.ndarray, np.ndarray]], channels: int = 12, order: int = 2):
    """Learn ``(G, H)`` and the channel bases from sequences with known states.

    The history is padded with ``x_{-1} = x_0`` so the first prediction has a
    learned column.  ``G`` predicts the stationary part ``u_k = x_k - 8 cos(1.2 k)``.
    """
    xs = np.concatenate([x for x, _ in train])
    zs = np.concatenate([z[1:] for _, z in train])
    bx = ChannelBasis(*np.percentile(xs, [RANGE_PERCENTILE, 100 - RANGE_PERCENTILE]).tolist(), channels)
    bz = ChannelBasis(*np.percentile(zs, [RANGE_PERCENTILE, 100 - RANGE_PERCENTILE]).tolist(), channels)
    seqs, targets, zc, xc = [], [], [], []
    for x, z in train:
        padded = np.concatenate([[x[0]] * (order - 1), x])
        k = np.arange(-(order - 1), len(x))
        seqs.append(encode(padded, bx))
        targets.append(encode(padded - drive(k), bx))
        zc.append(encode(z[1:], bz))
        xc.append(encode(x[1:], bx))
    G = embedded_covariance(seqs, order, targets)  # eq. 11, embedded
    H = measurement_matrix(np.concatenate(zc), np.concatenate(xc))
    return G, H, bx, bz


def run_cbt(z: np.ndarray, G: np.ndarray, H: np.ndarray, bx: ChannelBasis, bz: ChannelBasis) -> np.ndarray:
    """Track one sequence with :class:`~vidtrack.filters.channels.ChannelBayesFilter`; the decoded ``x_1..x_T``."""
    cbt = ChannelBayesFilter(G, H)
    cbt.initialize(history_prior(encode(X0, bx), cbt.order))  # the known x_0 over the padded history
    out = np.empty(len(z) - 1)
    for k in range(1, len(z)):
        cbt.predict(drive(k) / bx.spacing)  # w_{k|k-1} = F w_{k-1|k-1} (stationary part), translated by the drive
        cbt.update(cbt.likelihood(encode(z[k], bz)))  # eq. 10 with h(z_k) = H' c(z_k)
        t, _ = decode(cbt.marginal())  # eq. 8 on the current position's marginal
        out[k - 1] = bx.from_channel(t)
    return out


def refine_cbt(train, G, H, bx: ChannelBasis, bz: ChannelBasis, iterations: int, *, product: str = "plain",
               prior_weight: float = 0.0, learn_H: bool = True):
    """Baum-Welch (eqs. 17-19, plain products) of ``(G, H)`` from the training *observations* only.

    Frames: the padded ``x_{-1}``, ``x_0`` (known, no observation) and
    ``x_1..x_T`` with ``z``; the known drive is a per-frame translation of the
    predicted position.
    """
    order = G.ndim - 1
    z_channels, shifts = [], []
    for _, z in train:
        z_channels.append(np.vstack([np.zeros((order, bz.n)), encode(z[1:], bz)]))
        shifts.append([None] * order + [shift_matrix(bx.n, drive(k) / bx.spacing) for k in range(1, len(z))])
    W0 = history_prior(encode(X0, bx), order)  # the known x_0 over the padded history
    return baum_welch(z_channels, G, H, iterations=iterations, W0=[W0] * len(train), shifts=shifts, tol=0.0,
                      product=product, prior_weight=prior_weight, learn_H=learn_H)


# ------------------------------------------------------------------ comparators


def run_ekf(z: np.ndarray) -> np.ndarray:
    ekf = ExtendedKalmanFilter(growth, growth_jacobian, observe, lambda x: x / 10.0, Q_VAR, R_VAR)
    ekf.initialize([X0], [[P0]])
    out = np.empty(len(z) - 1)
    for k in range(1, len(z)):
        ekf.predict(k)
        ekf.update([z[k]])
        out[k - 1] = ekf.x_[0]
    return out


def run_grid(z: np.ndarray, points: int = 50, half_width: float = 30.0) -> np.ndarray:
    grid = np.linspace(-half_width, half_width, points)
    prior = np.exp(-0.5 * (grid - X0) ** 2 / P0)
    out = np.empty(len(z) - 1)
    gf = GridBayesFilter(grid, np.eye(points))
    gf.initialize(prior)
    for k in range(1, len(z)):
        gf.transition = gaussian_transition(grid, np.sqrt(Q_VAR), means=growth(grid, k))
        gf.predict()
        gf.update_log(-0.5 * (z[k] - observe(grid)) ** 2 / R_VAR)
        out[k - 1] = gf.mean()
    return out


def run_sir(z: np.ndarray, rng: np.random.Generator, particles: int = 50) -> np.ndarray:
    p = X0 + np.sqrt(P0) * rng.standard_normal(particles)
    w = np.full(particles, 1.0 / particles)
    out = np.empty(len(z) - 1)
    for k in range(1, len(z)):
        def propagate(x, r, k=k):  # x_k = f_k(x_{k-1}) + v
            return growth(x, k) + r.normal(0.0, np.sqrt(Q_VAR), size=x.shape)

        def loglik(x, k=k):  # log p(z_k | x_k), up to a constant
            return -0.5 * (z[k] - observe(x)) ** 2 / R_VAR

        p, w, _ = sir_step(p, w, propagate, loglik, rng, resample_below=0.0)
        out[k - 1] = float(w @ p)  # estimate before resampling
        idx = systematic_resample(w, rng)  # SIR: resample every step
        p, w = p[idx], np.full(particles, 1.0 / particles)
    return out


# ------------------------------------------------------------------ protocol


def add_arguments(parser) -> None:
    parser.add_argument("--steps", type=int, default=50, help="time steps per sequence (default 50)")
    parser.add_argument("--train", type=int, default=100, help="training sequences for CBT (default 100)")
    parser.add_argument("--channels", type=int, default=12, help="CBT channels for state and observation (default 12)")
    parser.add_argument("--order", type=int, default=2, help="CBT Markov order (default 2)")
    parser.add_argument("--baum-welch", type=int, default=4, metavar="N",
                        help="also report CBT refined by N Baum-Welch iterations on the observations alone (default 4, 0: no)")
    parser.add_argument("--bw-product", choices=("plain", "sqrt"), default="plain",
                        help="Baum-Welch channel products (default plain)")
    parser.add_argument("--bw-prior", type=float, default=BW_PRIOR,
                        help=f"Baum-Welch Dirichlet prior weight of the covariance estimate (default {BW_PRIOR:g}; 0: ML, eq. 18)")
    parser.add_argument("--bw-learn-h", action="store_true",
                        help="Baum-Welch also re-estimates the measurement matrix (eq. 19; default: kept)")


def run(args, progress) -> dict:
    from ..errors import UsageError

    runs = args.runs or 100
    if args.steps < 2 or args.train < 1 or args.channels < 4 or not 1 <= args.order <= 3:
        raise UsageError("need --steps >= 2, --train >= 1, --channels >= 4 and 1 <= --order <= 3")
    rng = np.random.default_rng(args.seed)
    train = [simulate(rng, args.steps) for _ in range(args.train)]
    start = time.perf_counter()
    G, H, bx, bz = train_cbt(train, args.channels, args.order)
    seconds = {"CBT training": time.perf_counter() - start}
    errors: dict[str, list[float]] = {"CBT": [], "EKF": [], "Grid": [], "SIR PF": []}
    bw = None
    if args.baum_welch:
        start = time.perf_counter()
        if args.bw_prior < 0:
            raise UsageError("--bw-prior must be >= 0")
        bw = refine_cbt(train, G, H, bx, bz, args.baum_welch, product=args.bw_product, prior_weight=args.bw_prior,
                        learn_H=args.bw_learn_h)
        seconds["Baum-Welch"] = time.perf_counter() - start
        errors["CBT+BW"] = []
    timing = {name: 0.0 for name in errors}
    for _ in progress(range(runs), total=runs, desc="cbt-carlin"):
        x, z = simulate(rng, args.steps)
        for name, fn in (("CBT", lambda z=z: run_cbt(z, G, H, bx, bz)), ("EKF", lambda z=z: run_ekf(z)),
                         ("Grid", lambda z=z: run_grid(z)), ("SIR PF", lambda z=z: run_sir(z, rng)),
                         ("CBT+BW", lambda z=z: run_cbt(z, bw.G, bw.H, bx, bz))):
            if name not in errors:
                continue
            t0 = time.perf_counter()
            est = fn()
            timing[name] += time.perf_counter() - t0
            errors[name].append(float(np.sqrt(np.mean((est - x[1:]) ** 2))))
    seconds.update({name: t / runs for name, t in timing.items()})
    main = ("CBT", "EKF", "Grid", "SIR PF")
    result = {
        "rmse": {name: float(np.mean(errors[name])) for name in main},
        "rmse_std": {name: float(np.std(e)) for name, e in errors.items()},
        "runs": runs,
        "setup": {"steps": args.steps, "x0": X0, "prior_var": P0, "train_sequences": args.train,
                  "channels": args.channels, "order": args.order, "grid_points": 50, "particles": 50,
                  "state_range": [bx.lo, bx.hi], "observation_range": [bz.lo, bz.hi], "seed": args.seed},
        "seconds_per_run": seconds,
    }
    if bw is not None:
        result["rmse_extra"] = {"CBT+BW": float(np.mean(errors["CBT+BW"]))}
        result["baum_welch"] = {"iterations": args.baum_welch, "log_likelihood": bw.log_likelihood,
                                "max_change_of_F": bw.change, "product": args.bw_product, "prior_weight": args.bw_prior,
                                "learn_H": args.bw_learn_h}
        diff = np.array(errors["CBT+BW"]) - np.array(errors["CBT"])
        result["baum_welch"]["paired_difference"] = {"mean": float(diff.mean()),
                                                     "se": float(diff.std(ddof=1) / np.sqrt(len(diff))) if len(diff) > 1 else 0.0}
    result["vs_paper"] = [comparison("Carlin", name, "RMSE", result["rmse"][name], PAPER[name]) for name in PAPER]
    result["claims"] = claims(result)
    if getattr(args, "figure_dir", None):
        fig_rng = np.random.default_rng([args.seed, 7])  # its own stream: the table does not change
        x, z = simulate(fig_rng, args.steps)
        estimates = {"CBT": run_cbt(z, G, H, bx, bz), "EKF": run_ekf(z), "Grid": run_grid(z),
                     "SIR PF": run_sir(z, fig_rng)}
        if bw is not None:
            estimates["CBT+BW"] = run_cbt(z, bw.G, bw.H, bx, bz)
        result["figures"] = carlin_trajectories(x, estimates, args.figure_dir)
    return result


def claims(result: dict) -> list[dict]:
    """The paper's claims on Carlin's experiment, checked on ``result``."""
    r = result["rmse"]
    out = [claim("CBT has a lower RMSE than the EKF, the grid filter and the SIR particle filter (paper: 5.43 vs "
                 "23.19 / 6.09 / 5.54)", all(r["CBT"] < r[n] for n in ("EKF", "Grid", "SIR PF")),
                 ", ".join(f"{n} {r[n]:.2f}" for n in ("CBT", "EKF", "Grid", "SIR PF")))]
    if "rmse_extra" in result:
        bw, d = result["baum_welch"], result["baum_welch"]["paired_difference"]
        out.append(claim("CBT refined by Baum-Welch from the observations alone is not worse than CBT from the "
                         "covariance estimate (paired difference at most 2 standard errors)", d["mean"] <= 2 * d["se"],
                         f"{result['rmse_extra']['CBT+BW']:.2f} vs {r['CBT']:.2f} (paired difference "
                         f"{d['mean']:+.3f} ± {d['se']:.3f} s.e.; {bw['iterations']} iterations, {bw['product']} products, "
                         f"prior {bw['prior_weight']:g}, H {'learned' if bw['learn_H'] else 'kept'})"))
    return out


PAPER = {"EKF": 23.19, "Grid": 6.09, "SIR PF": 5.54, "CBT": 5.43}
LABELS = {"EKF": "Extended Kalman filter", "Grid": "Approximate grid-based filter (50 points)",
          "SIR PF": "SIR particle filter (50 particles)", "CBT": "Channel Based Tracking (12 channels, learned)"}


def format_table(result: dict) -> str:
    s = result["setup"]
    lines = [f"Carlin's experiment: RMSE over {result['runs']} runs of {s['steps']} steps "
             f"(x0 = {s['x0']}, prior N(x0, {s['prior_var']}); CBT order {s['order']}, {s['channels']} channels, "
             f"trained on {s['train_sequences']} sequences; seed {s['seed']})",
             LEGEND,
             f"{'Algorithm':<46} {'RMSE (paper, diff)':>22} {'std':>6} {'ms/run':>8}"]
    for name in ("EKF", "Grid", "SIR PF", "CBT"):
        ms = 1000 * result["seconds_per_run"][name]
        lines.append(f"{LABELS[name]:<46} {cell(result['rmse'][name], PAPER[name])} {result['rmse_std'][name]:6.2f} "
                     f"{ms:8.1f}")
    if "rmse_extra" in result:
        bw = result["baum_welch"]
        ms = 1000 * result["seconds_per_run"]["CBT+BW"]
        label = f"CBT + {bw['iterations']} Baum-Welch it. (observations only)"
        lines.append(f"{label:<46} {cell(result['rmse_extra']['CBT+BW'], None)} {result['rmse_std']['CBT+BW']:6.2f} "
                     f"{ms:8.1f}")
        lines.append("Baum-Welch log-likelihood per iteration: "
                     + ", ".join(f"{v:.1f}" for v in bw["log_likelihood"])
                     + "; max change of F: " + ", ".join(f"{v:.3f}" for v in bw["max_change_of_F"]))
    for c in result.get("claims", []):
        lines.append(f"claim {'holds' if c['holds'] else 'does NOT hold'}: {c['claim']} -- {c['detail']}")
    return "\n".join(lines)
