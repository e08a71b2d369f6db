"""Fit qogi's error model (qogi.pipeline.error_model; issue 28, item 3) on
the operating envelope's rows and check it on held-out seeds.

Reads one or more ``qogi envelope`` output folders (``cells.csv`` and each
rendering's ``batch/<name>/result.json``), takes every detected rate with a
positive mean, and fits on the rows of ``--fit-seeds``:

* the bias: the median of ln(rate / truth) as a linear function of
  ``[1, features]`` (least absolute deviations, by iteratively reweighted
  least squares);
* the spread: the 90 % quantile (pinball loss) of what each row needs
  beyond the budget's own half-width to be covered, about the bias, as
  exp(linear function of ``[1, features]``);
* the probability of detection at the scene: a logistic in
  ln(truth / stated limit) shifted by the scene's features, by maximum
  likelihood on every rate with a stated limit and a measured speed,
  detected or not (checked per scene of the grid: the observed detection
  fraction against the stated probability).

Then reports the coverage of the budget's interval and of the calibrated
one on the fit rows and on the rows of ``--held-seeds`` (per block of the
grid too), writes the model with its provenance (``-o``, default the
packaged ``python/qogi/data/error_model.json``) and, with ``--plot``, the
residuals against each feature.

The intervals refitted are always the budget's (a result quantified with a
model records its budget interval in ``error_model.ci90_budget_kg_h``).

Usage::

    .venv/bin/python scripts/fit_error_model.py ENV_DIR [ENV_DIR ...] \\
        --fit-seeds 0 1 --held-seeds 2 3 --plot docs/img/error-model.png
"""

from __future__ import annotations

import argparse
import csv
import datetime
import json
import math
import sys
from pathlib import Path
from typing import Dict, List, Sequence

import numpy as np

from qogi.pipeline.error_model import LOG_SPREAD_MAX, Z90


def load_rows(folders: Sequence[Path]) -> List[dict]:
    """One dict per rate of a release (truth > 0) the envelope quantified:
    block, scene, seed, surface, truth, mean, the budget's interval, the
    detection decision and limit, the scene's features (None without a
    measured speed) and the model's features (None where the model does not
    apply: not detected, not positive, no speed)."""
    from qogi.pipeline import error_model, selfchecks

    self_codes = set(selfchecks.CODES.values())
    out = []
    for folder in folders:
        cache: Dict[str, dict] = {}
        with open(folder / "cells.csv", newline="") as f:
            cells = list(csv.DictReader(f))
        for c in cells:
            if c["status"] != "ok" or not float(c["truth_kg_h"]) > 0:
                continue
            name = f"{c['scene']}-seed{c['seed']}"
            if name not in cache:
                cache[name] = json.loads((folder / "batch" / name / "result.json").read_text())
            d = cache[name]
            s = next(x for x in d["surfaces"] if x["name"] == c["surface"])
            r = s["species"]["CH4"]
            budget = (r.get("error_model") or {}).get("ci90_budget_kg_h") or r["ci90_kg_h"]
            lo, hi = (
                -math.inf if budget[0] is None else budget[0],
                math.inf if budget[1] is None else budget[1],
            )
            info = d["info"]
            method = (info.get("background_choice") or {}).get("method") or d["config"].get(
                "background", ""
            )
            codes = {w["code"] for w in d["warnings"] if w.get("surface") == c["surface"]}
            mean, truth = r["mean_kg_h"], float(c["truth_kg_h"])
            speed = (r.get("detection") or {}).get("velocity_m_s")
            facts = (
                info["pixel_m"],
                info["frame_rate_hz"],
                info["frames"] / info["frame_rate_hz"],
                method,
                bool(codes & self_codes),
                int(info.get("pair_stride") or 1),
            )
            where = error_model.scene_features(speed, *facts)
            feats = error_model.features(
                mean, r.get("detection_limit_kg_h"), r.get("detected"), where
            )
            out.append(
                {
                    "folder": str(folder),
                    "scene": c["scene"],
                    "block": c["block"],
                    "seed": int(c["seed"]),
                    "surface": c["surface"],
                    "truth": truth,
                    "mean": mean,
                    "lo": lo,
                    "hi": hi,
                    "detected": r.get("detected") is True,
                    "limit": r.get("detection_limit_kg_h"),
                    "where": where,
                    "features": feats if feats is not None and math.isfinite(hi) else None,
                }
            )
    return out


def pod_rows(rows: Sequence[dict]) -> List[dict]:
    """The rows the probability of detection is fitted and checked on: a
    stated detection limit and a measured speed within the flow's range
    (where a result states the probability), detected or not."""
    return [
        r
        for r in rows
        if r["where"] is not None
        and r["where"]["flow_range"] == 0
        and r["limit"]
        and r["limit"] > 0
    ]


def fit_pod(rows: Sequence[dict], ridge: float = 0.5, iterations: int = 200) -> dict:
    """The probability of detection's coefficients (maximum likelihood of
    the logistic ``logit PoD = a ln(truth / limit) - (c_0 + c . x)``, by
    Newton's method; the features' shifts ``c`` held back by ``ridge`` x
    their squares, a prior of a few logit units: a feature whose rows are
    all detected or all missed would otherwise run off to infinity)."""
    from qogi.pipeline.error_model import SCENE_FEATURES

    t = np.array([math.log(r["truth"] / r["limit"]) for r in rows])
    y = np.array([float(r["detected"]) for r in rows])
    X = np.array([[1.0] + [r["where"][k] for k in SCENE_FEATURES] for r in rows])
    A = np.column_stack([t, -X])
    penalty = np.zeros(A.shape[1])
    penalty[2:] = 2.0 * ridge
    th = np.zeros(A.shape[1])
    th[0] = 1.0
    for _ in range(iterations):
        p = 0.5 * (1.0 + np.tanh(0.5 * (A @ th)))
        w = p * (1.0 - p) + 1e-12
        g = A.T @ (y - p) - penalty * th
        H = A.T @ (A * w[:, None]) + np.diag(penalty + 1e-9)
        step = np.linalg.solve(H, g)
        th = th + step
        if np.max(np.abs(step)) < 1e-10:
            break
    if not th[0] > 0:
        raise ValueError(f"the probability of detection did not rise with the rate (slope {th[0]})")
    return {"slope": float(th[0]), "offset": [float(v) for v in th[1:]]}


def pod_check(model, rows: Sequence[dict]) -> dict:
    """Per scene of the grid (its surfaces and seeds pooled): the observed
    detection fraction against the mean probability the model states for
    its rows; how many scenes within 10 points, the largest gap and where."""
    cells: Dict[str, list] = {}
    for r in rows:
        p = model.probability(r["truth"], r["limit"], r["where"])
        cells.setdefault(r["scene"], []).append((float(r["detected"]), p, r["block"]))
    gaps = []
    for scene, v in sorted(cells.items()):
        a = np.array([x[:2] for x in v], float)
        gaps.append((abs(a[:, 0].mean() - a[:, 1].mean()), scene, a[:, 0].mean(), a[:, 1].mean()))
    g = np.array([x[0] for x in gaps]) if gaps else np.zeros(0)
    worst = max(gaps) if gaps else None
    return {
        "rows": len(rows),
        "scenes": len(gaps),
        "within_10_points": int((g <= 0.10).sum()),
        "largest_gap": float(g.max()) if len(g) else None,
        "largest_gap_at": None if worst is None else worst[1],
        "gaps": [
            {"scene": x[1], "observed": float(x[2]), "stated": float(x[3])}
            for x in sorted(gaps, reverse=True)
            if x[0] > 0.10
        ],
    }


def design(rows: Sequence[dict]) -> np.ndarray:
    from qogi.pipeline.error_model import FEATURES

    return np.array([[1.0] + [r["features"][k] for k in FEATURES] for r in rows])


def log_errors(rows: Sequence[dict]) -> np.ndarray:
    return np.array([math.log(r["mean"] / r["truth"]) for r in rows])


def needed_spread(rows: Sequence[dict], bias: np.ndarray) -> np.ndarray:
    """Per row, the least spread (1 sigma, ln) that covers its truth about
    ``ln(mean) - bias`` in quadrature with the budget's half-width on the
    truth's side (0 when the budget's interval covers it: the calibrated
    interval holds it; a side at or below zero covers every truth on it)."""
    e = log_errors(rows) - bias
    out = np.zeros(len(rows))
    for i, (r, ei) in enumerate(zip(rows, e)):
        if r["lo"] <= r["truth"] <= r["hi"]:
            continue
        if ei > 0:  # the truth below the centre: the low side
            if r["lo"] <= 0:
                continue
            side = math.log(r["mean"] / r["lo"]) / Z90 if r["lo"] < r["mean"] else 0.0
        else:
            side = math.log(r["hi"] / r["mean"]) / Z90 if r["hi"] > r["mean"] else 0.0
        out[i] = math.sqrt(max(0.0, (ei / Z90) ** 2 - side**2))
    return out


def fit_bias(X: np.ndarray, e: np.ndarray, iterations: int = 200) -> np.ndarray:
    """Least absolute deviations by iteratively reweighted least squares."""
    b = np.linalg.lstsq(X, e, rcond=None)[0]
    for _ in range(iterations):
        w = 1.0 / np.maximum(np.abs(e - X @ b), 1e-4)
        Xw = X * w[:, None]
        nb = np.linalg.solve(X.T @ Xw + 1e-9 * np.eye(X.shape[1]), Xw.T @ e)
        if np.max(np.abs(nb - b)) < 1e-9:
            return nb
        b = nb
    return b


def fit_spread(
    X: np.ndarray,
    need: np.ndarray,
    tau: float = 0.9,
    ridge: float = 0.01,
    free: Sequence[str] = (),
) -> np.ndarray:
    """The coefficients a of exp(X a), the ``tau`` quantile of ``need``
    (pinball loss, Nelder-Mead from a few starts), the features' own
    coefficients (not the constant's, nor those of the features in ``free``)
    held back by ``ridge`` x rows x their squares: most rows need nothing
    (the budget covers them), and the rest are too few to pin six free
    coefficients. A feature that marks a kind of scene (a percentile
    background) is left free: held back, its spread goes to the constant
    and widens every other scene's interval."""
    from scipy.optimize import minimize

    from qogi.pipeline.error_model import FEATURES

    n = len(need)
    held = np.array([0.0] + [0.0 if k in free else 1.0 for k in FEATURES])

    def loss(a):
        d = need - np.exp(np.clip(X @ a, -30.0, LOG_SPREAD_MAX))
        pinball = float(np.sum(np.maximum(tau * d, (tau - 1.0) * d)))
        return pinball + ridge * n * float(np.sum(held * a**2))

    best = None
    for start in (-0.5, -1.5, -3.0):
        a0 = np.zeros(X.shape[1])
        a0[0] = start
        r = minimize(
            loss,
            a0,
            method="Nelder-Mead",
            options=dict(maxiter=60000, maxfev=60000, xatol=1e-6, fatol=1e-10),
        )
        if best is None or r.fun < best.fun:
            best = r
    assert best is not None
    return best.x


def coverage(model, rows: Sequence[dict]) -> dict:
    """Budget's and calibrated coverage of ``rows`` (overall and per
    block), and the median calibrated upper factor hi / mean."""
    from qogi.pipeline.error_model import calibrated_interval

    per: Dict[str, list] = {}
    for r in rows:
        b, s = model.expected(r["features"])
        lo, hi = calibrated_interval(r["mean"], (r["lo"], r["hi"]), b, s)
        per.setdefault(r["block"], []).append(
            (r["lo"] <= r["truth"] <= r["hi"], lo <= r["truth"] <= hi, hi / r["mean"])
        )
    allv = [v for vs in per.values() for v in vs]

    def summary(vs):
        a = np.array(vs, float)
        return {
            "rows": len(vs),
            "budget": float(a[:, 0].mean()),
            "calibrated": float(a[:, 1].mean()),
            "upper_factor_median": float(np.median(a[:, 2])),
        }

    return {"all": summary(allv), "blocks": {k: summary(v) for k, v in sorted(per.items())}}


def plot(rows: Sequence[dict], model, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from qogi.pipeline.error_model import FEATURES

    e = log_errors(rows)
    bias = np.array([model.expected(r["features"])[0] for r in rows])
    spread = np.array([model.expected(r["features"])[1] for r in rows])
    fig, axes = plt.subplots(1, len(FEATURES), figsize=(3.2 * len(FEATURES), 3.2), sharey=True)
    for ax, k in zip(axes, FEATURES):
        x = np.array([r["features"][k] for r in rows])
        if k in ("self_check_failed", "percentile_background"):
            x = x + np.random.default_rng(0).uniform(-0.15, 0.15, x.size)
        ax.scatter(x, e - bias, s=8, alpha=0.6)
        o = np.argsort(x)
        ax.plot(x[o], Z90 * spread[o], "r.", ms=2)
        ax.plot(x[o], -Z90 * spread[o], "r.", ms=2)
        ax.axhline(0, color="k", lw=0.5)
        ax.set_xlabel(k)
        ax.set_ylim(-4, 4)
    axes[0].set_ylabel("ln(rate / truth) - bias")
    fig.suptitle(
        "held-out rows: ln(rate / truth) less the bias; red: +-1.645 x the spread the "
        "model adds to the budget"
    )
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def main(argv=None) -> int:
    from qogi._version import __version__
    from qogi.pipeline.error_model import FEATURES, SCENE_FEATURES, ErrorModel

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folders", nargs="+", type=Path, help="qogi envelope output folders")
    ap.add_argument("--fit-seeds", nargs="+", type=int, default=[0, 1])
    ap.add_argument("--held-seeds", nargs="+", type=int, default=[2, 3])
    ap.add_argument("--tau", type=float, default=0.9, help="the spread's quantile")
    ap.add_argument(
        "--ridge", type=float, default=0.01, help="the spread's features held back (0: free)"
    )
    ap.add_argument(
        "--free",
        nargs="*",
        default=["percentile_background"],
        help="features whose spread coefficient the ridge does not hold back",
    )
    ap.add_argument(
        "--pod-ridge",
        type=float,
        default=0.5,
        help="the probability of detection's feature shifts held back (logit units^-2)",
    )
    ap.add_argument(
        "--cross-seeds",
        action="store_true",
        help="also fit on each fit seed alone and report the coverage of the others",
    )
    ap.add_argument(
        "-o",
        "--output",
        type=Path,
        default=Path(__file__).resolve().parents[1] / "python/qogi/data/error_model.json",
    )
    ap.add_argument("--plot", type=Path, help="residuals of the held-out rows (PNG)")
    ap.add_argument("--dry-run", action="store_true", help="report, write nothing")
    a = ap.parse_args(argv)
    every = load_rows(a.folders)
    rows = [r for r in every if r["features"] is not None]
    fit = [r for r in rows if r["seed"] in a.fit_seeds]
    held = [r for r in rows if r["seed"] in a.held_seeds]
    pod_fit = [r for r in pod_rows(every) if r["seed"] in a.fit_seeds]
    pod_held = [r for r in pod_rows(every) if r["seed"] in a.held_seeds]
    if len(fit) < 4 * (len(FEATURES) + 1):
        print(f"fit_error_model: {len(fit)} fit rows are too few", file=sys.stderr)
        return 2
    X, e = design(fit), log_errors(fit)
    b = fit_bias(X, e)
    a_s = fit_spread(X, needed_spread(fit, X @ b), a.tau, a.ridge, a.free)
    if a.cross_seeds:
        for s in a.fit_seeds:
            one = [r for r in fit if r["seed"] == s]
            rest = [r for r in fit if r["seed"] != s]
            X1 = design(one)
            b1 = fit_bias(X1, log_errors(one))
            m1 = ErrorModel(
                tuple(b1),
                tuple(fit_spread(X1, needed_spread(one, X1 @ b1), a.tau, a.ridge, a.free)),
                {},
            )
            c = coverage(m1, rest)["all"]
            print(
                f"fit on seed {s} alone: the other fit seeds covered {100 * c['calibrated']:.0f} % "
                f"(budget {100 * c['budget']:.0f} %, {c['rows']} rows)"
            )
    draft = ErrorModel(
        tuple(map(float, b)), tuple(map(float, a_s)), {}, fit_pod(pod_fit, a.pod_ridge)
    )
    cov_fit = coverage(draft, fit)
    cov_held = coverage(draft, held) if held else None
    pod_cov_fit = pod_check(draft, pod_fit)
    pod_cov_held = pod_check(draft, pod_held) if pod_held else None
    grids = sorted({r["folder"] for r in rows})
    provenance = {
        "fitted_on": f"qogi envelope default grid, seeds {a.fit_seeds} ({len(fit)} detected rates)",
        "held_out": f"seeds {a.held_seeds} ({len(held)} detected rates)",
        "tau": a.tau,
        "ridge": a.ridge,
        "ridge_free": list(a.free),
        "qogi_version": __version__,
        "date": datetime.date.today().isoformat(),
        "coverage_fit": cov_fit,
        "coverage_held_out": cov_held,
        "pod_rows": (
            f"{len(pod_fit)} fitted, {len(pod_held)} held out "
            f"(a stated limit and a measured speed in the flow's range, detected or not)"
        ),
        "pod_ridge": a.pod_ridge,
        "pod_fit": pod_cov_fit,
        "pod_held_out": pod_cov_held,
        "script": "scripts/fit_error_model.py",
        "folders": len(grids),
    }
    model = ErrorModel(draft.bias, draft.log_spread, provenance, draft.pod)
    names = ["const", *FEATURES]
    print("| coefficient | bias (ln) | ln spread |\n|---|---|---|")
    for n, x, y in zip(names, model.bias, model.log_spread):
        print(f"| {n} | {x:+.3f} | {y:+.3f} |")
    for label, cov in (("fit", cov_fit), ("held out", cov_held)):
        if cov is None:
            continue
        print(f"\n{label}: | block | rows | budget covers | calibrated covers | hi/mean |")
        print("|---|---|---|---|---|")
        for blk, c in [*cov["blocks"].items(), ("all", cov["all"])]:
            print(
                f"| {blk} | {c['rows']} | {100 * c['budget']:.0f} % | "
                f"{100 * c['calibrated']:.0f} % | {c['upper_factor_median']:.2f} |"
            )
    assert model.pod is not None
    print(
        f"\nprobability of detection: logit = {model.pod['slope']:.3f} ln(Q / L) - ("
        + " + ".join(
            f"{c:+.3f}{'' if n == 'const' else ' ' + n}"
            for n, c in zip(["const", *SCENE_FEATURES], model.pod["offset"])
        )
        + ")"
    )
    for label, pc in (("fit", pod_cov_fit), ("held out", pod_cov_held)):
        if pc is None:
            continue
        print(
            f"{label}: {pc['within_10_points']} of {pc['scenes']} scenes within 10 points "
            f"({pc['rows']} rows), largest gap {100 * (pc['largest_gap'] or 0):.0f} points"
        )
        for gp in pc["gaps"]:
            print(
                f"   {gp['scene']}: observed {100 * gp['observed']:.0f} %, "
                f"stated {100 * gp['stated']:.0f} %"
            )
    if a.plot and held:
        plot(held, model, a.plot)
    if not a.dry_run:
        a.output.write_text(json.dumps(model.to_dict(), indent=1) + "\n")
        print(f"\nwrote {a.output}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
