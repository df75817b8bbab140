"""softshock-solve end to end: exit codes, the JSON summary, and the result file's state.

Run by ctest with SOFTSHOCK_SOLVE pointing at the binary (Debian's /usr/bin/python3, h5py).
"""
import json
import os
import subprocess
import tempfile
import unittest

import h5py

SOLVE = os.environ["SOFTSHOCK_SOLVE"]


def solve(spec, out, *extra):
    with tempfile.NamedTemporaryFile("w", suffix=".json", delete=False) as f:
        json.dump(spec, f)
    try:
        return subprocess.run([SOLVE, "--spec", f.name, "--out", out, *extra], capture_output=True,
                              text=True, timeout=300)
    finally:
        os.unlink(f.name)


class SoftshockSolve(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory()
        self.out = os.path.join(self.tmp.name, "out")

    def tearDown(self):
        self.tmp.cleanup()

    def test_small_run_writes_results_and_prints_summary(self):
        r = solve({"geometry": {"target_elements": 800},
                   "run": {"end_time": 4e-8, "output_interval": 1e-8}}, self.out)
        self.assertEqual(r.returncode, 0, r.stderr)
        summary = json.loads(r.stdout)
        self.assertEqual(summary["status"], "completed")
        self.assertAlmostEqual(summary["groups"]["pbar"], 1.0)
        self.assertAlmostEqual(summary["groups"]["tbar_pulse"], 0.1257, places=3)
        self.assertGreater(summary["elements"], 700)
        self.assertGreater(summary["energy_injected_J_per_m"], 0)
        for key in ("steps", "wall_time_s", "max_abar_first_cycle", "max_abar",
                    "dominant_mode_end", "shock_at_center_s", "rim_reflections_s"):
            self.assertIn(key, summary)
        with h5py.File(os.path.join(self.out, "result.h5"), "r") as h5:
            self.assertEqual(int(h5.attrs["complete"]), 1)
            self.assertEqual(h5["timeseries/time"].shape[0], 41)  # 0..40 ns every 1 ns
            self.assertEqual(len(h5["fields"]), 5)  # 0, 10, 20, 30, 40 ns
        self.assertTrue(os.path.exists(os.path.join(self.out, "result.xdmf")))
        self.assertFalse(os.path.exists(os.path.join(self.out, "result.h5.tmp")))

    def test_invalid_spec_exits_2_naming_the_field(self):
        r = solve({"geometry": {"disk": {"radius": -1e-5}}}, self.out)
        self.assertEqual(r.returncode, 2)
        self.assertIn("geometry.disk.radius", r.stderr)
        self.assertFalse(os.path.exists(self.out))
        r = solve({"material": {"shear_modulus": -5}}, self.out)
        self.assertEqual(r.returncode, 2)
        self.assertIn("material.shear_modulus", r.stderr)
        r = solve({"geometry": {"mesh_file": "/nonexistent.msh"}}, self.out)
        self.assertEqual(r.returncode, 2)
        self.assertIn("geometry.mesh_file", r.stderr)
        r = solve({"run": {"cfl": 1.5}}, self.out)
        self.assertEqual(r.returncode, 2)
        self.assertIn("run.cfl", r.stderr)
        # A host's limits (softshockd passes its own to jobs on Slurm).
        r = solve({}, self.out, "--max-elements", "100")
        self.assertEqual(r.returncode, 2)
        self.assertIn("geometry.target_elements: must be between 20 and 100", r.stderr)
        r = solve({"run": {"end_time": 2e-6}}, self.out, "--max-end-time", "1e-6")
        self.assertEqual(r.returncode, 2)
        self.assertIn("run.end_time", r.stderr)

    def test_inverting_run_exits_1_and_keeps_a_partial_file_marked_incomplete(self):
        # 100 kappa on a coarse mesh with no viscosity at CFL 0.95 crushes the rim at once.
        r = solve({"geometry": {"target_elements": 500}, "viscosity": {"c1": 0, "c2": 0},
                   "load": {"pressure": 2e11, "duration": 1e-7},
                   "run": {"end_time": 1e-7, "cfl": 0.95, "output_interval": 1e-8}}, self.out)
        self.assertEqual(r.returncode, 1)
        self.assertIn("element inversion", r.stderr)
        self.assertIn("in element", r.stderr)
        with h5py.File(os.path.join(self.out, "result.h5"), "r") as h5:
            self.assertEqual(int(h5.attrs["complete"]), 0)
            error = h5.attrs["error"]
            error = error.decode() if isinstance(error, bytes) else str(error)
            self.assertIn("element inversion", error)

    def test_usage_errors_exit_2(self):
        r = subprocess.run([SOLVE, "--spec"], capture_output=True, text=True)
        self.assertEqual(r.returncode, 2)
        r = subprocess.run([SOLVE, "--bogus"], capture_output=True, text=True)
        self.assertEqual(r.returncode, 2)


if __name__ == "__main__":
    unittest.main()
