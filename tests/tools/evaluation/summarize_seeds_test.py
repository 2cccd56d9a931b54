#!/usr/bin/env python3
"""tools/evaluation/summarize_seeds.py: success counts and per-seed verdicts
from report.json files laid out as tools/evaluate_seeds.sh writes them."""

import io
import json
import os
import sys
import tempfile
import unittest
from contextlib import redirect_stdout

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "..", "..", "tools", "evaluation"))
import summarize_seeds  # noqa: E402


def agent(final_m, drift_free_m, drift_m, fixes=10, false_fixes=0):
    """One air agent's block of a report; yaw errors are well within 3 deg."""
    a = {
        "bandwidth_mbps": {"mean": 0.6, "max_1s": 0.6},
        "false_fixes": false_fixes,
        "fixes": fixes,
        "time_to_first_fix_s": 3.0 if final_m is not None else None,
        "final": {},
    }
    if final_m is not None:
        a["final"] = {"translation_error_m": final_m, "yaw_error_deg": 0.2}
        a["drift_free"] = {
            "final": {"translation_error_m": drift_free_m, "yaw_error_deg": 0.1},
            "translation_error_m": {"median": drift_free_m},
            "yaw_error_deg": {"median": 0.1},
            "translation_error_at_ugv_m": {"median": 0.05},
        }
        a["truth_drift_final"] = {"translation_m": drift_m, "yaw_deg": 0.1}
    return a


def report(a):
    final = a["final"].get("translation_error_m")
    df = a.get("drift_free", {}).get("final", {}).get("translation_error_m")
    drift = a.get("truth_drift_final", {}).get("translation_m")
    return {
        "success": final is not None and final <= 0.3,
        "success_drift_free": df is not None and df <= 0.3,
        "success_attainable": drift is not None and drift <= 0.3,
        "timing_ms": {"estimate": {"median": 80.0}},
        "agents": {"uav1": a},
    }


class SummarizeSeedsTest(unittest.TestCase):
    def test_verdicts(self):
        v = summarize_seeds.verdict
        self.assertEqual(v(agent(0.10, 0.08, 0.05)), "passes")
        self.assertEqual(v(agent(None, None, None)), "fails: no fix")
        self.assertEqual(v(agent(0.55, 0.07, 0.58)), "fails: odometries drifted beyond the bound")
        self.assertEqual(v(agent(0.40, 0.50, 0.10)), "fails: estimate off the odometries' relation")
        self.assertEqual(v(agent(0.35, 0.20, 0.20)), "fails: drift and estimate error add up")
        self.assertEqual(v(agent(0.12, 0.52, 0.44)), "passes: drift and estimate error partly cancel")
        # The yaw bound counts too: 0.1 m but 4 deg off is a failure.
        a = agent(0.10, 0.08, 0.05)
        a["final"]["yaw_error_deg"] = 4.0
        self.assertTrue(summarize_seeds.verdict(a).startswith("fails"))

    def test_table(self):
        runs = [agent(0.10, 0.08, 0.05), agent(0.55, 0.07, 0.58), None, agent(None, None, None)]
        with tempfile.TemporaryDirectory() as d:
            for seed, a in enumerate(runs, start=1):
                if a is None:
                    continue  # a run that wrote no report
                out = os.path.join(d, "full", f"seed{seed}")
                os.makedirs(out)
                with open(os.path.join(out, "report.json"), "w") as f:
                    json.dump(report(a), f)
            buf = io.StringIO()
            with redirect_stdout(buf):
                rc = summarize_seeds.main(["summarize_seeds.py", d, "4", "full|--no-stage1"])
        self.assertEqual(rc, 0)
        lines = buf.getvalue().splitlines()
        summary = [l for l in lines if l.startswith("| full | ") and "/3 |" in l]
        self.assertEqual(len(summary), 1, buf.getvalue())
        cells = [c.strip() for c in summary[0].strip("|").split("|")]
        self.assertEqual(cells[1:4], ["1/3", "2/3", "1/3"])  # SR, drift-free, attainable
        per_seed = [l for l in lines if l.startswith("| full | ") and "uav1" in l]
        self.assertEqual(len(per_seed), 3)
        self.assertTrue(per_seed[0].endswith("| passes |"))
        self.assertIn("0.550 / 0.20", per_seed[1])
        self.assertTrue(per_seed[1].endswith("| fails: odometries drifted beyond the bound |"))
        self.assertTrue(per_seed[2].endswith("| fails: no fix |"))
        self.assertIn("full: 1 of 4 seeds wrote no report", buf.getvalue())

    def test_usage(self):
        with redirect_stdout(io.StringIO()), open(os.devnull, "w") as null:
            old, sys.stderr = sys.stderr, null
            try:
                self.assertEqual(summarize_seeds.main(["summarize_seeds.py"]), 2)
            finally:
                sys.stderr = old


if __name__ == "__main__":
    unittest.main()
