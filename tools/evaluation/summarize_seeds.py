#!/usr/bin/env python3
"""Summarises the evaluator's reports over the seeds of a preset.

    summarize_seeds.py SEEDS_DIR N CONFIGURATION [CONFIGURATION ...]

reads SEEDS_DIR/<configuration>/seed<k>/report.json (k = 1..N; missing ones
are skipped and counted), as tools/evaluate_seeds.sh writes them, and prints

- one row per configuration: success rates (the spec's, drift-free,
  attainable), error statistics, false fixes, time and bandwidth;
- one row per seed and air agent: its final fix against groundtruth.yaml and
  against the odometry worlds' relation, how far the odometries themselves
  drifted, and for a run that fails, why: no fix, the odometries' own drift
  (the estimate passes against their relation), or the estimate.

A CONFIGURATION may be given as NAME|ARGS (evaluate_seeds.sh's form); only
NAME is used.
"""

import json
import os
import statistics
import sys

# The spec's success bound (../shared/spec/report.md).
BOUND_M = 0.3
BOUND_DEG = 3.0


def within(error):
    """True if an {"translation_*", "yaw_*"} error pair is within the bound."""
    t = error.get("translation_error_m", error.get("translation_m"))
    y = error.get("yaw_error_deg", error.get("yaw_deg"))
    return t is not None and y is not None and t <= BOUND_M and y <= BOUND_DEG


def verdict(agent):
    """Why a run passed or failed, for one air agent's block of a report."""
    final = agent.get("final") or {}
    if final.get("translation_error_m") is None:
        return "fails: no fix"
    ok = within(final)
    df = (agent.get("drift_free") or {}).get("final")
    drift = agent.get("truth_drift_final")
    if df is None or drift is None:
        return "passes" if ok else "fails"
    df_ok, attainable = within(df), within(drift)
    if ok:
        return "passes" if attainable else "passes: drift and estimate error partly cancel"
    if not df_ok:
        return "fails: estimate off the odometries' relation"
    if not attainable:
        return "fails: odometries drifted beyond the bound"
    return "fails: drift and estimate error add up"


def fmt(x, digits=3):
    return "-" if x is None else f"{x:.{digits}f}"


def pair(block, t_key="translation_error_m", y_key="yaw_error_deg"):
    if not block or block.get(t_key) is None:
        return "-"
    return f"{block[t_key]:.3f} / {block[y_key]:.2f}"


def load(seeds_dir, name, n):
    """[(seed, report)] of the runs that wrote a report."""
    runs = []
    for seed in range(1, n + 1):
        path = os.path.join(seeds_dir, name, f"seed{seed}", "report.json")
        if os.path.exists(path):
            with open(path) as f:
                runs.append((seed, json.load(f)))
    return runs


def summary_row(name, runs):
    ok = ok_df = ok_att = false_fixes = 0
    t, y, dt, dy, du, ms, mbps = [], [], [], [], [], [], []
    for _, r in runs:
        ok += bool(r.get("success"))
        ok_df += bool(r.get("success_drift_free"))
        ok_att += bool(r.get("success_attainable"))
        ms.append(r["timing_ms"]["estimate"]["median"])
        for a in r["agents"].values():
            mbps.append(a["bandwidth_mbps"]["mean"])
            false_fixes += a.get("false_fixes") or 0
            if a.get("final", {}).get("translation_error_m") is None:
                continue
            t.append(a["final"]["translation_error_m"])
            y.append(a["final"]["yaw_error_deg"])
            if "drift_free" in a:
                dt.append(a["drift_free"]["translation_error_m"]["median"])
                dy.append(a["drift_free"]["yaw_error_deg"]["median"])
                if "translation_error_at_ugv_m" in a["drift_free"]:
                    du.append(a["drift_free"]["translation_error_at_ugv_m"]["median"])

    def f(xs, k):
        return f"{k(xs):.3f}" if xs else "-"

    n = len(runs)
    return (f"| {name} | {ok}/{n} | {ok_df}/{n} | {ok_att}/{n} "
            f"| {f(t, statistics.median)} / {f(t, statistics.mean)} "
            f"| {f(y, statistics.median)} / {f(y, statistics.mean)} "
            f"| {f(dt, statistics.median)} / {f(dy, statistics.median)} "
            f"| {f(du, statistics.median)} | {false_fixes} "
            f"| {f(ms, statistics.median)} | {f(mbps, statistics.mean)} |")


def seed_rows(name, runs):
    rows = []
    for seed, r in runs:
        for agent_name, a in sorted(r["agents"].items()):
            drift_free = a.get("drift_free") or {}
            rows.append(
                f"| {name} | {seed} | {agent_name} | {fmt(a.get('time_to_first_fix_s'), 1)} "
                f"| {a.get('fixes', 0)} | {pair(a.get('final'))} "
                f"| {pair(drift_free.get('final'))} "
                f"| {pair(a.get('truth_drift_final'), 'translation_m', 'yaw_deg')} "
                f"| {a.get('false_fixes') or 0} "
                f"| {fmt(r['timing_ms']['estimate']['median'], 1)} | {verdict(a)} |")
    return rows


def main(argv):
    if len(argv) < 4:
        print(__doc__.strip(), file=sys.stderr)
        return 2
    seeds_dir, n = argv[1], int(argv[2])
    names = [v.split("|")[0] for v in argv[3:]]
    per_name = [(name, load(seeds_dir, name, n)) for name in names]

    print(f"\n{os.path.basename(os.path.normpath(seeds_dir))}: {n} seeds")
    print("| configuration | SR | SR drift-free | SR attainable "
          "| translation error (m) median / mean | yaw error (deg) median / mean "
          "| drift-free (m / deg) median | drift-free at the UGV (m) | false fixes "
          "| time per estimate (ms) median | Mbps mean |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for name, runs in per_name:
        print(summary_row(name, runs))
    print("SR: final fix within 0.3 m and 3 deg of groundtruth.yaml; SR drift-free: the same test "
          "against the odometry worlds' relation at the final estimate's time; SR attainable: runs "
          "an estimate equal to that relation would pass, i.e. where the odometries' own drift "
          "from groundtruth.yaml stays within the bound")
    print("errors: each run's final fix against groundtruth.yaml; drift-free: median over the "
          "run's fixes against the odometry worlds' relation at the estimate's time (at the UGV: "
          "where the fix maps the UGV camera, rather than the ground world's origin)")

    print("\nper seed (final fix; m / deg):")
    print("| configuration | seed | agent | first fix (s) | fixes | against groundtruth.yaml "
          "| against the odometries' relation | odometries' drift from groundtruth.yaml "
          "| false fixes | time per estimate (ms) median | verdict |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for name, runs in per_name:
        for row in seed_rows(name, runs):
            print(row)
    missing = [(name, n - len(runs)) for name, runs in per_name if len(runs) < n]
    for name, k in missing:
        print(f"{name}: {k} of {n} seeds wrote no report (see the evaluate_{name}_<seed>.log files)")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
