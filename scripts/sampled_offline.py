#!/usr/bin/env python3
"""Separates a sampled run's two sources of error, using per-unit files (sampled_units.csv).

A sampled run's error on a frame's cycles is the sum of two things: the sample (which units it
measured) and the simulation of those units (warm-up, the caches as loaded for skipped tiles).
A run with every unit measured (--set sim.sample_period_units=1) writes the frame's per-unit
truth; against it:

  resample TRUTH.csv [--periods 10,20,100] [--seeds 200]
      draws the sampled runs' own design (one unit at random in each run of P units) from the
      truth and estimates the frame's cycles with the same regression and jackknife interval as
      sim/sampling/estimators.cpp (re-implemented here, independently), seed after seed: the sample's own
      error, mean absolute and signed, and the intervals' coverage, with no simulation error.
      Also the residual of the regression fitted on every unit, over the mean unit's cycles.
      --reference REF.csv pairs it with a reference design's per-unit truth of the same frame
      (rtsim run --reference: the reference's cycles in each unit are fitted first, and the
      functional capacity misses are not), and cuts the strata from the units in order of the
      reference's cycles, as rtsim does (--frame-order: from the frame's neighbouring units);
      --order-by RUN.csv cuts them in order of that table's cycles (rtsim run --sample-order).

  compare TRUTH.csv RUN_DIR [RUN_DIR ...]
      for each sampled run, its measured units' cycles and counters against the same units in
      the truth: what the simulation of the sample adds (a unit measured in a sampled run should
      take what it took in the full run).

docs/sampling.md says what these showed on the 24 frames of bench_sampled.py.
"""
import argparse
import csv
import json
import math
import os
import random
import statistics
import sys

# The regression's auxiliaries, in order: the skip design's units carry new_line_rays (the rays
# that fetched their new lines), which sim/sampling/sampler.cpp fits in place of new_lines.
AUX = ["work", "new_lines", "node_steps", "rays"]


def aux_of(rows):
    aux = [("new_line_rays" if a == "new_lines" and "new_line_rays" in rows[0] else a)
           for a in AUX]
    # The skip design's fifth auxiliary where the L2 is LRU and no reference design is used: the
    # units' capacity misses as counted functionally, fitted where at least 4 measured units had
    # some (sample_design below applies that rule to a sample).
    if "functional_capacity_misses" in rows[0]:
        aux.append("functional_capacity_misses")
    return aux


MIN_UNITS_WITH_CAPACITY_MISSES = 4  # sim/sampling/sampler.cpp, report
MIN_UNITS_PER_AUX = 4  # sim/sampling/estimators.cpp: auxiliary k only with 4 k informative units
MAX_WEIGHT_SHIFT = 10.0


def load(path):
    with open(path) as f:
        return [{k: float(v) for k, v in r.items()} for r in csv.DictReader(f)]


def solve(m, v):
    """Gaussian elimination with partial pivoting; None if singular."""
    n = len(v)
    a = [row[:] + [v[i]] for i, row in enumerate(m)]
    for c in range(n):
        p = max(range(c, n), key=lambda r: abs(a[r][c]))
        if abs(a[p][c]) < 1e-300:
            return None
        a[c], a[p] = a[p], a[c]
        for r in range(n):
            if r != c:
                f = a[r][c] / a[c][c]
                for k in range(c, n + 1):
                    a[r][k] -= f * a[c][k]
    return [a[i][n] / a[i][i] for i in range(n)]


def t975(df):
    """Student's t 97.5% quantile (Cornish-Fisher expansion; within 0.1% for df >= 3; tables'
    values below)."""
    if df < 3:
        return {1: 12.7062, 2: 4.3027}[df]
    z = 1.959963985
    g1 = (z ** 3 + z) / 4
    g2 = (5 * z ** 5 + 16 * z ** 3 + 3 * z) / 96
    g3 = (3 * z ** 7 + 19 * z ** 5 + 17 * z ** 3 - 15 * z) / 384
    return z + g1 / df + g2 / df ** 2 + g3 / df ** 3


def regression_total(y, X, totals, N):
    """Total of y over N units from n measured, by regression through the origin weighted by
    1 / x_0, auxiliaries admitted in order, the weights' shift bounded, jackknife variance."""
    n, K = len(y), len(X)
    w = [1.0 / X[0][i] if X[0][i] > 0 else 1.0 for i in range(n)]
    # Units where every auxiliary is zero (tiles without rays) inform no fit.
    informative = sum(any(X[k][i] != 0 for k in range(K)) for i in range(n))

    def normal(cols):
        m = [[sum(w[i] * X[a][i] * X[b][i] for i in range(n)) for b in cols] for a in cols]
        v = [sum(w[i] * X[a][i] * y[i] for i in range(n)) for a in cols]
        return m, v

    fitted = []
    for j in range(K):
        diag = sum(w[i] * X[j][i] ** 2 for i in range(n))
        if j > 0 and (informative < MIN_UNITS_PER_AUX * j or diag <= 0):
            continue
        pivot = diag
        if fitted:
            m, _ = normal(fitted)
            cross = [sum(w[i] * X[a][i] * X[j][i] for i in range(n)) for a in fitted]
            z = solve(m, cross)
            if z is None:
                continue
            pivot -= sum(c * zz for c, zz in zip(cross, z))
        if not pivot > 1e-9 * diag:
            if j == 0:
                break
            continue
        fitted.append(j)
    if not fitted:
        return 0.0, math.inf
    while len(fitted) > 1:
        m, _ = normal(fitted)
        lam = solve(m, [totals[a] for a in fitted])
        wild = lam is None or any(
            abs(sum(l * X[a][i] for l, a in zip(lam, fitted)) * w[i] * n / N - 1)
            > MAX_WEIGHT_SHIFT for i in range(n))
        if not wild:
            break
        fitted.pop()
    m, v = normal(fitted)
    coef = solve(m, v)

    def total(c):
        return sum(cc * totals[a] for cc, a in zip(c, fitted))

    T, p = total(coef), len(fitted)
    fpc = max(0.0, 1 - n / N)
    if fpc == 0:
        return T, 0.0
    if informative <= p:
        return T, math.inf
    reps = []
    for i in range(n):
        mi = [[m[a][b] - w[i] * X[fa][i] * X[fb][i] for b, fb in enumerate(fitted)]
              for a, fa in enumerate(fitted)]
        vi = [v[a] - w[i] * X[fa][i] * y[i] for a, fa in enumerate(fitted)]
        c = solve(mi, vi)
        if c is None:
            reps = None
            break
        reps.append(total(c))
    if reps:
        mean = sum(reps) / n
        var = fpc * (n - 1) / n * sum((r - mean) ** 2 for r in reps)
    else:
        ss = sum((y[i] - sum(c * X[a][i] for c, a in zip(coef, fitted))) ** 2 for i in range(n))
        var = N * N * fpc * ss / (n - p) / n
    return T, t975(informative - p) * math.sqrt(var)


def sample_design(sample, aux, totals):
    """The measured units' auxiliaries and their totals, as sim/sampling/sampler.cpp fits them: the
    capacity misses only where at least 4 measured units had some."""
    keep = [k for k, a in enumerate(aux)
            if a != "functional_capacity_misses"
            or sum(r[a] > 0 for r in sample) >= MIN_UNITS_WITH_CAPACITY_MISSES]
    return [[r[aux[k]] for r in sample] for k in keep], [totals[k] for k in keep]


def stratified_pick(N, P, seed):
    rng = random.Random(seed)
    return [s * P + rng.randrange(min(P, N - s * P)) for s in range((N + P - 1) // P)]


def population_residual_pct(rows, aux):
    """Residual standard deviation of the auxiliaries' fit over every unit, over the mean unit's
    cycles: what no sample of these auxiliaries can explain (one zero in every unit, as a primary
    frame's capacity misses, is left out, as the estimator leaves it out)."""
    aux = [a for a in aux if any(r[a] for r in rows)]
    n, K = len(rows), len(aux)
    X = [[r[a] for r in rows] for a in aux]
    y = [r["cycles"] for r in rows]
    w = [1 / r[aux[0]] if r[aux[0]] > 0 else 1 for r in rows]
    m = [[sum(w[i] * X[a][i] * X[b][i] for i in range(n)) for b in range(K)] for a in range(K)]
    v = [sum(w[i] * X[a][i] * y[i] for i in range(n)) for a in range(K)]
    c = solve(m, v)
    e = [y[i] - sum(c[k] * X[k][i] for k in range(K)) for i in range(n)]
    return statistics.stdev(e) / (sum(y) / n) * 100


def cycles_by_unit(path, n):
    """A per-unit table's cycles, indexed by unit (every unit of a frame of n units)."""
    rows = load(path)
    by_unit = {int(r["unit"]): r["cycles"] for r in rows}
    if sorted(by_unit) != list(range(n)):
        sys.exit(f"sampled_offline: {path}: not the {n} units of the truth's frame")
    return [by_unit[u] for u in range(n)]


def resample(args):
    rows = sorted(load(args.truth), key=lambda r: r["unit"])
    N = len(rows)
    truth = sum(r["cycles"] for r in rows)
    aux = aux_of(rows)
    order = list(range(N))  # the units the strata are cut from, in turn
    if args.reference:
        # A paired run fits the reference's cycles first; its units carry their capacity misses.
        ref = cycles_by_unit(args.reference, N)
        for r, c in zip(rows, ref):
            r["reference_cycles"] = c
        aux = ["reference_cycles"] + [a for a in aux if a != "functional_capacity_misses"]
        if not args.frame_order:
            order = sorted(range(N), key=lambda u: (ref[u], u))
    if args.order_by:
        by = cycles_by_unit(args.order_by, N)
        order = sorted(range(N), key=lambda u: (by[u], u))
    totals = [sum(r[a] for r in rows) for a in aux]
    print(f"{args.truth}: {N} units, {sum(r['rays'] > 0 for r in rows)} with rays; residual of "
          f"the fit over every unit {population_residual_pct(rows, aux):.1f}% of the mean unit")
    for P in [int(p) for p in args.periods.split(",")]:
        errs, hws, covered = [], [], 0
        for seed in range(1, args.seeds + 1):
            idx = [order[k] for k in stratified_pick(N, P, seed)]
            X, Xt = sample_design([rows[i] for i in idx], aux, totals)
            T, hw = regression_total([rows[i]["cycles"] for i in idx], X, Xt, N)
            errs.append((T - truth) / truth * 100)
            hws.append(hw / truth * 100)
            covered += abs(T - truth) <= hw
        print(f"  1 in {P}: mean abs error {statistics.mean(map(abs, errs)):.2f}%, signed "
              f"{statistics.mean(errs):+.2f}%, sd {statistics.pstdev(errs):.2f}%, half-width "
              f"{statistics.median(hws):.2f}% (median), coverage {100 * covered / args.seeds:.0f}%")


def compare(args):
    truth = {int(r["unit"]): r for r in load(args.truth)}
    cols = args.columns.split(",")
    print("run: " + ", ".join(f"{c}: measured units sampled vs full" for c in cols))
    for d in args.runs:
        rows = load(os.path.join(d, "sampled_units.csv"))
        with open(os.path.join(d, "stats.json")) as f:
            sampling = json.load(f)["sampling"]
        est, drain = sampling["total_cycles"]["value"], sampling["drain_cycles"]
        # The frame's cycles: the truth run's own (its units and the drain after them).
        truth_stats = os.path.join(os.path.dirname(args.truth), "stats.json")
        with open(truth_stats) as f:
            full = json.load(f)["total_cycles"]
        parts = []
        for c in cols:
            s = sum(r[c] for r in rows)
            t = sum(truth[int(r["unit"])][c] for r in rows)
            parts.append(f"{s:.0f} vs {t:.0f} ({100 * (s - t) / t:+.2f}%)" if t else f"{s:.0f} vs 0")
        # The same units' truths through the same estimator: the sample's own error; what the
        # run's estimate adds to it is the simulation's (the drain after the last hand-out is
        # the run's in both).
        idx = [int(r["unit"]) for r in rows]
        units = list(truth.values())
        aux = aux_of(units)
        totals = [sum(r[a] for r in units) for a in aux]
        X, Xt = sample_design([truth[u] for u in idx], aux, totals)
        T, _ = regression_total([truth[u]["cycles"] for u in idx], X, Xt, len(units))
        print(f"{d}: estimate {100 * (est - full) / full:+.2f}% = sample "
              f"{100 * (T + drain - full) / full:+.2f}% + simulation "
              f"{100 * (est - T - drain) / full:+.2f}%; "
              + ", ".join(parts))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("resample")
    r.add_argument("truth")
    r.add_argument("--periods", default="10,20,100")
    r.add_argument("--seeds", type=int, default=200)
    r.add_argument("--reference", help="a reference design's sampled_units.csv of every unit")
    r.add_argument("--frame-order", action="store_true",
                   help="with --reference: strata of neighbouring units, not by its cycles")
    r.add_argument("--order-by", help="strata cut from the units in order of this table's cycles")
    c = sub.add_parser("compare")
    c.add_argument("truth")
    c.add_argument("runs", nargs="+")
    c.add_argument("--columns", default="cycles,l1.misses,l2.misses")
    args = ap.parse_args(argv)
    need = [args.truth] + [p for p in (getattr(args, "reference", None),
                                       getattr(args, "order_by", None)) if p]
    need += [p for d in getattr(args, "runs", []) for p in
             (os.path.join(d, "sampled_units.csv"), os.path.join(d, "stats.json"))]
    if args.cmd == "compare":
        need.append(os.path.join(os.path.dirname(args.truth), "stats.json"))
    for p in need:
        if not os.path.isfile(p):
            sys.exit(f"sampled_offline: {p}: no such file (a sampled run writes sampled_units.csv "
                     "beside its stats.json)")
    resample(args) if args.cmd == "resample" else compare(args)


if __name__ == "__main__":
    main()
