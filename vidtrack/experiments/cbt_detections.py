"""Tracking from unassociated detections: CBT vs PMHT vs PDAF vs the raw detector (the paper's RC-car table).

The RC-car sequences of Felsberg & Larsson, "Learning Object Tracking in
Image Sequences" / "Channel-Based Tracking", are not available, so this
experiment builds their equivalent: two or more objects move smoothly in a
320x240 image; every frame a detector reports each object with probability
``p_detect`` (drop-outs), displaced by Gaussian noise and now and then by a
gross displacement, plus Poisson clutter uniform over the image; nothing
says which detection belongs to which object.

CBT (20 channels per axis, order 3, as in the paper) learns its transition
from one simulated sequence *without associations* (section 3.4): every
chain of detections from consecutive frames whose links are shorter than
``GATE`` px adds the outer product of its channel vectors to the
covariance-estimate counts of each axis (eq. 11, embedded) -- true chains,
clutter chains and object switches alike; the measurement matrix is the
identity (detections live in the state space).  Rows:

* ``CBT`` -- that correspondence-free covariance estimate;
* ``CBT associated`` -- the reference learned *with* associations: the same
  estimate from each object's own chains of detections (true labels, see
  :func:`learn_associated`);
* ``CBT Baum-Welch`` -- ``CBT`` refined by ``--iterations`` Baum-Welch
  iterations (eqs. 17-18) on the frames' per-axis set vectors, the
  correspondence-free learning the paper claims converges in about four
  iterations to a model as good as the associated one.  Every product of
  channel vectors is the square-root product (``--bw-product sqrt``, the
  paper's product for channel vectors, section 3.3) and the starting
  estimate is a Dirichlet prior of weight ``--bw-prior`` pseudo-frames per
  history column (MAP-EM; 0 is eq. 18's maximum likelihood, which
  re-estimates a history column the posterior hardly visits from next to
  no data: see ``history_mass`` of
  :class:`~vidtrack.learn.baum_welch.BaumWelchResult`);
* ``PMHT`` (:mod:`vidtrack.filters.pmht`) and ``PDAF``
  (:mod:`vidtrack.filters.pdaf`) with the same constant-velocity Kalman
  model; ``Detector`` -- the highest-scoring detection of each frame.

CBT is evaluated on another sequence, tracking object 0 (the "car in
front", whose detections score a little higher) from its true first
position; the estimate is the decoded strongest mode of the 2-D posterior.
The PDAF starts at the same position; the PMHT has one track per object,
started at the objects' true first positions, and (as the paper scores its
multi-target PMHT) each frame counts the track closest to object 0.  Frames
without detections do not count for the detector, as in the paper.  RMSE of
the position error with the paper's outlier caps: each frame's error is
replaced by the cap when larger (inf, 20, 5 px).

A multi-object run reports the modes too: a CBT started from the
first-frame empirical prior (all detections), updated with square-root
products, decodes every mode holding at least ``MULTI_THRESHOLD`` of the
mass; ``modes`` is the mean number per frame and ``rmse_all_objects`` the
error of each object to its nearest mode.

How close the table comes, and why Baum-Welch needs the square-root
products and the prior here, is in ``docs/reproduction.md`` (section
"Channel-Based Tracking").
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..channels import ChannelBasis, conditional_from_counts, encode
from ..filters.channels import PlanarCBT
from ..filters.kalman import motion_model
from ..filters.pdaf import PDAF
from ..filters.pmht import PMHT
from ..learn.baum_welch import baum_welch, chain_counts
from .paper import LEGEND, cell, claim, comparison, relative_difference

DESCRIPTION = ("RC-car-style table (CBT paper): CBT learned from unassociated detections (covariance estimate, "
               "Baum-Welch) vs CBT learned with associations, PMHT, PDAF, detector")

WIDTH, HEIGHT = 320.0, 240.0
CAPS = (np.inf, 20.0, 5.0)
#: Longest link (px) of a detection chain counted by the correspondence-free estimate.
GATE = 15.0
#: Baum-Welch on detection sets: Dirichlet prior weight of the starting (covariance) estimate, per history column.
BW_PRIOR = 0.1
#: PMHT: frames per sliding batch and EM iterations per batch.
PMHT_WINDOW = 10
PMHT_ITERATIONS = 5
#: Multi-object run: score temperature (scores barely matter) and the mass a decoded mode must hold.
MULTI_TEMPERATURE = 1.0
MULTI_THRESHOLD = 0.05


@dataclass(frozen=True)
class Scenario:
    """Simulation parameters (defaults used for the table)."""

    frames: int = 400
    objects: int = 2
    p_detect: float = 0.85
    sigma: float = 2.5
    gross_rate: float = 0.05
    gross_sigma: float = 20.0
    clutter_rate: float = 3.0
    accel: float = 0.35
    damping: float = 0.97
    spring: float = 0.003


def simulate(rng: np.random.Generator, sc: Scenario, *, labels: bool = False):
    """Object tracks ``(T, objects, 2)`` and per-frame detections ``(N_k, 3)`` ``[x, y, score]``.

    With ``labels``, also the true association of every detection (object
    index, -1 for clutter) per frame -- used only to learn the "associated"
    reference model, never by a tracker.  The random draws are the same
    either way.
    """
    centre = np.array([WIDTH / 2, HEIGHT / 2])
    pos = centre + rng.uniform(-0.3, 0.3, size=(sc.objects, 2)) * [WIDTH, HEIGHT]
    vel = rng.normal(0.0, 1.5, size=(sc.objects, 2))
    tracks = np.empty((sc.frames, sc.objects, 2))
    dets: list[np.ndarray] = []
    owners: list[np.ndarray] = []
    for k in range(sc.frames):
        if k:
            vel = sc.damping * vel + rng.normal(0.0, sc.accel, size=vel.shape) - sc.spring * (pos - centre)
            pos = np.clip(pos + vel, [8, 8], [WIDTH - 8, HEIGHT - 8])
        tracks[k] = pos
        rows, owner = [], []
        for i in range(sc.objects):
            if rng.random() < sc.p_detect:
                sigma = sc.gross_sigma if rng.random() < sc.gross_rate else sc.sigma
                score = np.clip(rng.normal(0.8 if i == 0 else 0.72, 0.1), 0.0, 1.0)
                rows.append([*(pos[i] + rng.normal(0.0, sigma, 2)), score])
                owner.append(i)
        for _ in range(rng.poisson(sc.clutter_rate)):
            rows.append([rng.uniform(0, WIDTH), rng.uniform(0, HEIGHT), np.clip(rng.normal(0.55, 0.15), 0, 1)])
            owner.append(-1)
        d = np.array(rows, dtype=float).reshape(-1, 3)
        order = rng.permutation(len(d))
        dets.append(d[order])  # no order carries an association
        owners.append(np.array(owner, dtype=int)[order])
    return (tracks, dets, owners) if labels else (tracks, dets)


def detection_channels(dets: list[np.ndarray], basis: ChannelBasis, axis: int) -> np.ndarray:
    """Per frame, the normalised sum of the encodings of all detections' ``axis`` coordinate ``(T, C)``."""
    out = np.zeros((len(dets), basis.n))
    for k, d in enumerate(dets):
        if len(d):
            out[k] = encode(d[:, axis], basis).sum(axis=0) / len(d)
    return out


def learn_cbt(dets: list[np.ndarray], bases, order: int, gate: float = GATE):
    """Correspondence-free covariance estimate (eq. 11) from gated chains of unassociated detections, per axis."""
    counts = chain_counts([d[:, :2] for d in dets], bases, order, gate)
    return [conditional_from_counts(c + 1e-6) for c in counts]


def learn_associated(dets: list[np.ndarray], owners: list[np.ndarray], bases, order: int, objects: int):
    """The reference model learned *with* known associations: eq. 11 on each object's own detection chains.

    Every run of ``order + 1`` consecutive frames in which object ``o`` was
    detected adds the outer product of its detections' channel vectors (the
    same counts as :func:`learn_cbt`, but only true chains: no clutter, no
    object switches; drop-outs break a chain).
    """
    total = [np.zeros((b.n,) * (order + 1)) for b in bases]
    for o in range(objects):
        own = [d[w == o, :2] for d, w in zip(dets, owners)]  # 0 or 1 detection per frame
        total = [t + c for t, c in zip(total, chain_counts(own, bases, order, np.inf))]
    return [conditional_from_counts(c + 1e-6) for c in total]


def refine_baum_welch(dets: list[np.ndarray], bases, G: list[np.ndarray], iterations: int, h_floor: float = 0.05,
                      product: str = "sqrt", prior_weight: float = BW_PRIOR):
    """Baum-Welch (eqs. 17-18) per axis on the frames' set channel vectors, starting from ``G``; ``H`` kept.

    ``product="sqrt"``: every product of channel vectors is the square-root
    product (section 3.3); ``prior_weight``: MAP re-estimation with the
    starting model as a Dirichlet prior (see
    :func:`vidtrack.learn.baum_welch.baum_welch`).  Returns the models, the
    largest change of ``G`` per iteration and the per-iteration
    log-likelihood, per axis.
    """
    out, changes, logliks = [], [], []
    for axis, (b, g) in enumerate(zip(bases, G)):
        res = baum_welch([detection_channels(dets, b, axis)], g, np.eye(b.n), iterations=iterations,
                         h_floor=h_floor, learn_H=False, product=product, prior_weight=prior_weight)
        out.append(res.G)
        changes.append(res.change)
        logliks.append(res.log_likelihood)
    return out, changes, logliks


def capped_rmse(errors: np.ndarray, cap: float) -> float:
    e = np.minimum(np.asarray(errors, float), cap)
    return float(np.sqrt(np.mean(e ** 2))) if e.size else float("nan")


def run_cbt(model: PlanarCBT, tracks: np.ndarray, dets: list[np.ndarray], score_temperature: float) -> np.ndarray:
    model.initialize_at(tracks[0, 0])
    errors = []
    for k in range(1, len(dets)):
        model.predict()
        d = dets[k]
        model.update(d[:, :2], weights=np.exp((d[:, 2] - 1.0) / score_temperature))
        est, _ = model.decode()
        errors.append(np.linalg.norm(est - tracks[k, 0]))
    return np.array(errors)


def run_cbt_all(model: PlanarCBT, tracks: np.ndarray, dets: list[np.ndarray], score_temperature: float,
                threshold: float) -> tuple[np.ndarray, float]:
    d0 = dets[0]
    model.initialize_empirical(d0[:, :2], np.exp((d0[:, 2] - 1.0) / score_temperature))
    errors, counts = [], []
    for k in range(1, len(dets)):
        model.predict()
        d = dets[k]
        model.update(d[:, :2], weights=np.exp((d[:, 2] - 1.0) / score_temperature))
        modes = model.modes(threshold)
        counts.append(len(modes))
        if modes:
            centres = np.array([m for m, _ in modes])
            for obj in tracks[k]:
                errors.append(np.min(np.linalg.norm(centres - obj, axis=1)))
    return np.array(errors), float(np.mean(counts))


def run_pdaf(tracks: np.ndarray, dets: list[np.ndarray], sc: Scenario) -> np.ndarray:
    F, Q, H = motion_model("cv", q=sc.accel ** 2, n_axes=2)
    pdaf = PDAF(F, Q, H, np.eye(2) * sc.sigma ** 2, p_detect=sc.p_detect,
                clutter_density=max(sc.clutter_rate, 0.1) / (WIDTH * HEIGHT))
    x0 = np.array([tracks[0, 0, 0], 0.0, tracks[0, 0, 1], 0.0])
    pdaf.initialize(x0, np.diag([4.0, 4.0, 4.0, 4.0]))
    errors = []
    for k in range(1, len(dets)):
        pdaf.predict()
        pdaf.update(dets[k][:, :2])
        errors.append(np.linalg.norm(H @ pdaf.x_ - tracks[k, 0]))
    return np.array(errors)


def run_pmht(tracks: np.ndarray, dets: list[np.ndarray], sc: Scenario, window: int = PMHT_WINDOW,
             iterations: int = PMHT_ITERATIONS) -> np.ndarray:
    """PMHT with one track per object, started at the objects' true first positions.

    Same constant-velocity Kalman model as the PDAF.  As the paper does for
    its (multi-target) PMHT, each frame scores the track closest to object 0.
    The estimate of frame ``k`` is the end of the batch ending at ``k``
    (causal, like CBT and PDAF).
    """
    F, Q, H = motion_model("cv", q=sc.accel ** 2, n_axes=2)
    pmht = PMHT(F, Q, H, np.eye(2) * sc.sigma ** 2, clutter_density=max(sc.clutter_rate, 0.1) / (WIDTH * HEIGHT),
                p_detect=sc.p_detect, area=WIDTH * HEIGHT, window=window, iterations=iterations)
    x0 = np.array([[t[0], 0.0, t[1], 0.0] for t in tracks[0]])
    pmht.initialize(x0, np.array([np.diag([4.0, 4.0, 4.0, 4.0])] * len(x0)))
    errors = []
    for k in range(1, len(dets)):
        positions = pmht.step(dets[k][:, :2]) @ H.T
        errors.append(np.min(np.linalg.norm(positions - tracks[k, 0], axis=1)))
    return np.array(errors)


def run_detector(tracks: np.ndarray, dets: list[np.ndarray]) -> np.ndarray:
    errors = []
    for k in range(1, len(dets)):
        if len(dets[k]):
            best = dets[k][np.argmax(dets[k][:, 2]), :2]
            errors.append(np.linalg.norm(best - tracks[k, 0]))
    return np.array(errors)


def add_arguments(parser) -> None:
    parser.add_argument("--frames", type=int, default=400, help="frames per simulated sequence (default 400)")
    parser.add_argument("--objects", type=int, default=2, help="moving objects (default 2)")
    parser.add_argument("--clutter", type=float, default=3.0, help="mean clutter detections per frame (default 3)")
    parser.add_argument("--channels", type=int, default=20, help="CBT channels per axis (default 20)")
    parser.add_argument("--order", type=int, default=3, help="CBT Markov order (default 3)")
    parser.add_argument("--iterations", type=int, default=4,
                        help="Baum-Welch iterations of the CBT Baum-Welch row (default 4; 0 = no such row)")
    parser.add_argument("--bw-product", choices=("sqrt", "plain"), default="sqrt",
                        help="Baum-Welch channel products (default sqrt, as section 3.3)")
    parser.add_argument("--bw-prior", type=float, default=BW_PRIOR,
                        help=f"Baum-Welch Dirichlet prior weight of the starting estimate (default {BW_PRIOR:g}; 0 = ML)")
    parser.add_argument("--no-pmht", action="store_true", help="skip the PMHT comparator (the slowest row)")


#: Row names of the ``rmse`` object, in table order.
ROWS = ("CBT", "CBT associated", "CBT Baum-Welch", "PMHT", "PDAF", "Detector")


def run(args, progress) -> dict:
    from ..errors import UsageError

    if args.frames < 10 or args.objects < 1 or args.clutter < 0 or args.channels < 4 or not 1 <= args.order <= 3 \
            or args.iterations < 0 or args.bw_prior < 0:
        raise UsageError("need --frames >= 10, --objects >= 1, --clutter >= 0, --channels >= 4, "
                         "1 <= --order <= 3, --iterations >= 0, --bw-prior >= 0")
    runs = args.runs or 1
    sc = Scenario(frames=args.frames, objects=args.objects, clutter_rate=args.clutter)
    bases = (ChannelBasis(0.0, WIDTH, args.channels), ChannelBasis(0.0, HEIGHT, args.channels))
    temperature = 0.1
    rng = np.random.default_rng(args.seed)
    errors: dict[str, list[np.ndarray]] = {name: [] for name in ROWS}
    all_errors, mode_counts, changes, logliks = [], [], [], []
    seconds = {"learn": 0.0, "CBT": 0.0, "PDAF": 0.0, "PMHT": 0.0, "baum_welch": 0.0}
    for _ in progress(range(runs), total=runs, desc="cbt-detections"):
        _, train_dets, train_owners = simulate(rng, sc, labels=True)
        tracks, test_dets = simulate(rng, sc)
        t0 = time.perf_counter()
        G = learn_cbt(train_dets, bases, args.order)
        seconds["learn"] += time.perf_counter() - t0
        model = PlanarCBT(bases, G, None, clutter=0.01)
        t0 = time.perf_counter()
        errors["CBT"].append(run_cbt(model, tracks, test_dets, temperature))
        seconds["CBT"] += time.perf_counter() - t0
        G_assoc = learn_associated(train_dets, train_owners, bases, args.order, sc.objects)
        errors["CBT associated"].append(run_cbt(PlanarCBT(bases, G_assoc, None, clutter=0.01), tracks, test_dets,
                                                temperature))
        t0 = time.perf_counter()
        errors["PDAF"].append(run_pdaf(tracks, test_dets, sc))
        seconds["PDAF"] += time.perf_counter() - t0
        if not args.no_pmht:
            t0 = time.perf_counter()
            errors["PMHT"].append(run_pmht(tracks, test_dets, sc))
            seconds["PMHT"] += time.perf_counter() - t0
        errors["Detector"].append(run_detector(tracks, test_dets))
        if args.iterations:
            t0 = time.perf_counter()
            G_bw, history, ll = refine_baum_welch(train_dets, bases, G, args.iterations, product=args.bw_product,
                                                  prior_weight=args.bw_prior)
            seconds["baum_welch"] += time.perf_counter() - t0
            changes.append(history)
            logliks.append(ll)
            errors["CBT Baum-Welch"].append(run_cbt(PlanarCBT(bases, G_bw, None, clutter=0.01), tracks, test_dets,
                                                    temperature))
        # several objects in one posterior: square-root products keep the modes' weights bounded
        # (with plain products the better-scoring object's mode absorbs the others within a few frames)
        e_all, n_modes = run_cbt_all(PlanarCBT(bases, G, None, clutter=0.01, product="sqrt"), tracks, test_dets,
                                     MULTI_TEMPERATURE, MULTI_THRESHOLD)
        all_errors.append(e_all)
        mode_counts.append(n_modes)
    rmse = {name: {cap_key(c): capped_rmse(np.concatenate(e), c) for c in CAPS}
            for name, e in errors.items() if e}
    result = {
        "rmse": rmse,
        "rmse_all_objects": {cap_key(c): capped_rmse(np.concatenate(all_errors), c) for c in CAPS},
        "modes": float(np.mean(mode_counts)),
        "runs": runs,
        "baum_welch_change": [[float(v) for v in axis] for axis in changes[0]] if changes else [],
        "baum_welch_log_likelihood": [[float(v) for v in axis] for axis in logliks[0]] if logliks else [],
        "setup": {"frames": sc.frames, "objects": sc.objects, "p_detect": sc.p_detect, "sigma": sc.sigma,
                  "gross_rate": sc.gross_rate, "gross_sigma": sc.gross_sigma, "clutter_rate": sc.clutter_rate,
                  "channels": args.channels, "order": args.order, "iterations": args.iterations, "gate": GATE,
                  "bw_product": args.bw_product, "bw_prior": args.bw_prior, "pmht_window": PMHT_WINDOW,
                  "pmht_iterations": PMHT_ITERATIONS, "image": [WIDTH, HEIGHT], "seed": args.seed},
        "seconds_per_run": {k: v / runs for k, v in seconds.items()},
    }
    result["vs_paper"] = [comparison("RC1", name, cap, rmse[name][cap], PAPER["RC1"].get(PAPER_ROW.get(name, name), (None,) * 3)[i])
                          for name in ROWS if name in rmse for i, cap in enumerate(CAP_KEYS)]
    result["claims"] = claims(result)
    return result


CAP_KEYS = ("inf", "20", "5")


def cap_key(cap: float) -> str:
    return "inf" if np.isinf(cap) else str(int(cap))


PAPER = {"RC1": {"CBT": (7.3, 6.6, 3.9), "PMHT": (13.1, 8.9, 3.2), "PDAF": (18.4, 9.1, 4.0), "Detector": (40.43, 10.54, 4.17)},
         "RC2": {"CBT": (6.7, 6.5, 3.9), "PMHT": (15.6, 7.1, 3.5), "PDAF": (23.3, 8.5, 3.9), "Detector": (42.72, 10.58, 4.23)}}
#: The paper's CBT row is its correspondence-free model (learned from unassociated detections).
PAPER_ROW = {"CBT Baum-Welch": "CBT"}


def claims(result: dict) -> list[dict]:
    """The paper's claims on this table, checked on ``result`` (RMSE(inf))."""
    r = {name: v["inf"] for name, v in result["rmse"].items()}
    out = []
    if "CBT Baum-Welch" in r:
        d = relative_difference(r["CBT Baum-Welch"], r["CBT associated"])
        out.append(claim("CBT learned by Baum-Welch from unassociated detections tracks within 10 % of CBT learned "
                         "with associations (RMSE(inf))", abs(d) <= 0.10,
                         f"Baum-Welch {r['CBT Baum-Welch']:.2f} vs associated {r['CBT associated']:.2f} px ({100 * d:+.1f} %)"))
        changes = result["baum_welch_change"]
        if changes:
            out.append(claim("Baum-Welch started from the covariance estimate converges in about four iterations",
                             all(axis[-1] < 0.25 * axis[0] for axis in changes),
                             "largest change of G per iteration, x: " + ", ".join(f"{v:.3f}" for v in changes[0])
                             + "; y: " + ", ".join(f"{v:.3f}" for v in changes[1])))
    rivals = [n for n in ("PDAF", "PMHT") if n in r]
    mine = [n for n in ("CBT associated", "CBT Baum-Welch") if n in r]
    worst, best = max(r[n] for n in mine), min(r[n] for n in rivals)
    out.append(claim(f"CBT (associated and Baum-Welch) below {' and '.join(rivals)} on RMSE(inf)", worst < best,
                     ", ".join(f"{n} {r[n]:.2f}" for n in (*mine, *rivals)) + " px"))
    return out


def format_table(result: dict) -> str:
    s = result["setup"]
    lines = [f"Tracking from unassociated detections: RMSE (px) of object 0 with outlier caps, {result['runs']} run(s) "
             f"of {s['frames']} frames; {s['objects']} objects, P_D {s['p_detect']}, clutter {s['clutter_rate']}/frame; "
             f"CBT {s['channels']} channels/axis, order {s['order']}; seed {s['seed']}",
             "CBT: covariance estimate from gated chains of unassociated detections (gate "
             f"{s['gate']:g} px); CBT associated: the same estimate from each object's own chains (known associations); "
             f"CBT Baum-Welch: CBT refined by {s['iterations']} Baum-Welch iterations ({s['bw_product']} products, "
             f"prior weight {s['bw_prior']:g}); PMHT: window {s['pmht_window']}, {s['pmht_iterations']} EM iterations",
             f"{LEGEND}; paper = the paper's RC1 table (its CBT is the correspondence-free one)",
             f"{'method':<16}" + "".join(f"{'(' + c + ')':>22}" for c in CAP_KEYS)]
    for name in ROWS:
        if name not in result["rmse"]:
            continue
        paper = PAPER["RC1"].get(PAPER_ROW.get(name, name), (None,) * 3)
        lines.append(f"{name:<16}" + "".join(cell(result["rmse"][name][c], paper[i]) for i, c in enumerate(CAP_KEYS)))
    if result.get("baum_welch_change"):
        lines.append("Baum-Welch largest change of G per iteration (x | y): "
                     + ", ".join(f"{v:.3f}" for v in result["baum_welch_change"][0]) + " | "
                     + ", ".join(f"{v:.3f}" for v in result["baum_welch_change"][1]))
    a = result["rmse_all_objects"]
    lines.append(f"CBT from the empirical first-frame prior: {result['modes']:.2f} modes/frame decoded; every object to its "
                 f"nearest mode RMSE (inf/20/5) {a['inf']:.2f} / {a['20']:.2f} / {a['5']:.2f}")
    t = result["seconds_per_run"]
    lines.append(f"time per run: learning {t['learn']:.1f} s, Baum-Welch {t['baum_welch']:.1f} s, CBT {t['CBT']:.1f} s, "
                 f"PDAF {t['PDAF']:.2f} s, PMHT {t['PMHT']:.1f} s")
    lines += [f"claim {'holds' if c['holds'] else 'does NOT hold'}: {c['claim']} -- {c['detail']}" for c in result["claims"]]
    return "\n".join(lines)
