"""softshock-solve end to end: exit codes, the JSON summary, and the result file's state.

Run by ctest with SOFTSHOCK_SOLVE pointing at the binary (Debian's /usr/bin/python3, h5py).
"""
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
import unittest

import h5py

SOLVE = os.environ["SOFTSHOCK_SOLVE"]


def solve(spec, out, *extra, env=None):
    with tempfile.NamedTemporaryFile("w", suffix=".json", delete=False) as f:
        json.dump(spec, f)
    try:
        # No mesh cache unless a test asks for one: tests stay out of the user's ~/.cache.
        cache = [] if "--mesh-cache" in extra else ["--no-mesh-cache"]
        return subprocess.run([SOLVE, "--spec", f.name, "--out", out, *extra, *cache],
                              capture_output=True, text=True, timeout=300,
                              env=None if env is None else {**os.environ, **env})
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
        # A real run's XDMF as ParaView's default reader needs it, and as meshio reads it.
        checks = os.path.join(os.environ["SOFTSHOCK_SOURCE_DIR"], "tests", "integration")
        xdmf = os.path.join(self.out, "result.xdmf")
        r = subprocess.run([sys.executable, os.path.join(checks, "check_xdmf_structure.py"), xdmf],
                           capture_output=True, text=True)
        self.assertEqual(r.returncode, 0, r.stderr)
        with h5py.File(os.path.join(self.out, "result.h5"), "r") as h5:
            shape = [str(len(h5["mesh/nodes"])), str(len(h5["mesh/triangles"]))]
            times = [repr(float(h5["fields"][k].attrs["time"])) for k in sorted(h5["fields"])]
        r = subprocess.run([sys.executable, os.path.join(checks, "check_xdmf_meshio.py"), xdmf]
                           + shape + times, capture_output=True, text=True)
        self.assertEqual(r.returncode, 0, r.stderr)

    def test_checkpoints_continue_a_killed_or_terminated_run_bitwise(self):
        """--checkpoint-dir: a run killed (SIGKILL) after a checkpoint, or stopped by SIGTERM (as
        Slurm preempts), continues when the same command runs again, and its result equals the
        uninterrupted run's in every dataset bit for bit; the folder goes when it finishes."""
        spec = {"geometry": {"target_elements": 6000},
                "run": {"end_time": 3e-7, "output_interval": 2e-8, "history_interval": 1e-9}}
        reference = os.path.join(self.tmp.name, "reference")
        r = solve(spec, reference)
        self.assertEqual(r.returncode, 0, r.stderr)
        compare = os.path.join(os.environ["SOFTSHOCK_SOURCE_DIR"], "scripts", "compare_results.py")
        spec_path = os.path.join(self.tmp.name, "spec.json")
        with open(spec_path, "w") as f:
            json.dump(spec, f)
        for sig in (signal.SIGKILL, signal.SIGTERM):
            with self.subTest(signal=sig.name):
                out = os.path.join(self.tmp.name, "out-" + sig.name)
                ckpt = os.path.join(self.tmp.name, "ckpt-" + sig.name)
                argv = [SOLVE, "--spec", spec_path, "--out", out, "--no-mesh-cache", "--quiet",
                        "--checkpoint-dir", ckpt, "--checkpoint-interval", "0.05"]
                p = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
                state = os.path.join(ckpt, "state.ckpt")
                deadline = time.monotonic() + 120
                while not os.path.exists(state) and p.poll() is None and time.monotonic() < deadline:
                    time.sleep(0.002)
                self.assertIsNone(p.poll(), "the run ended before its first checkpoint")
                p.send_signal(sig)
                p.communicate(timeout=60)
                self.assertNotEqual(p.returncode, 0)
                self.assertTrue(os.path.exists(state))
                r = subprocess.run(argv, capture_output=True, text=True, timeout=300)
                self.assertEqual(r.returncode, 0, r.stderr)
                self.assertIn("continues from its checkpoint at t = ", r.stderr)
                self.assertNotIn("checkpoint not used", r.stderr)
                same = subprocess.run([sys.executable, compare, os.path.join(reference, "result.h5"),
                                       os.path.join(out, "result.h5")],
                                      capture_output=True, text=True)
                self.assertEqual(same.returncode, 0, same.stdout + same.stderr)
                self.assertFalse(os.path.exists(ckpt), "the checkpoint folder outlived the run")

    def test_python_reader_reads_format_versions_1_and_2_alike(self):
        from softshock_client.results import ResultFile
        r = solve({"geometry": {"target_elements": 300},
                   "run": {"end_time": 2e-8, "output_interval": 1e-8}}, self.out)
        self.assertEqual(r.returncode, 0, r.stderr)
        h5_path = os.path.join(self.out, "result.h5")
        with ResultFile(h5_path) as res:
            self.assertEqual(res.format_version, 2)
            u2 = res.field("displacement")
            nodes, _ = res.mesh()
        self.assertEqual(u2.shape, (len(nodes), 2))
        self.assertGreater(abs(u2).max(), 0)
        # Rewrite the vectors as format_version 1 stored them (N x 2).
        with h5py.File(h5_path, "r+") as h5:
            h5.attrs["format_version"] = 1
            for k in h5["fields"]:
                for name in ("displacement", "velocity"):
                    xy = h5["fields"][k][name][:, :2]
                    del h5["fields"][k][name]
                    h5["fields"][k][name] = xy
        with ResultFile(h5_path) as res:
            self.assertEqual(res.format_version, 1)
            self.assertTrue((res.field("displacement") == u2).all())
        with h5py.File(h5_path, "r+") as h5:
            h5.attrs["format_version"] = 3
        with self.assertRaisesRegex(ValueError, "format_version 3"):
            ResultFile(h5_path)

    def test_mesh_cache_reuses_the_mesh_and_the_summary_says_where_time_went(self):
        # Gmsh's mesher (the default disk mesher, concentric rings, needs no Gmsh at all).
        spec = {"geometry": {"target_elements": 600, "mesher": "FRONTAL_DELAUNAY"},
                "run": {"end_time": 2e-8}}
        cache = os.path.join(self.tmp.name, "meshes")
        first = solve(spec, self.out, "--mesh-cache", cache)
        self.assertEqual(first.returncode, 0, first.stderr)
        # A hit never loads the Gmsh module: pointed at nothing, the run still succeeds...
        no_gmsh = {"SOFTSHOCK_GMSH_MESHER": os.path.join(self.tmp.name, "no-such-module.so")}
        second = solve(spec, self.out + "2", "--mesh-cache", cache, env=no_gmsh)
        self.assertEqual(second.returncode, 0, second.stderr)
        # ... while a run that must mesh says why it cannot.
        third = solve(spec, self.out + "3", env=no_gmsh)
        self.assertEqual(third.returncode, 1)
        self.assertIn("SOFTSHOCK_GMSH_MESHER", third.stderr)
        a, b = json.loads(first.stdout), json.loads(second.stdout)
        self.assertEqual((a["mesh_cache"], b["mesh_cache"]), ("miss", "hit"))
        self.assertEqual(len([n for n in os.listdir(cache) if n.endswith(".mesh")]), 1)
        for key in ("max_abar", "energy_injected_J_per_m", "steps"):
            self.assertEqual(a[key], b[key], key)  # same mesh, same arithmetic
        with h5py.File(os.path.join(self.out, "result.h5"), "r") as f1, \
                h5py.File(os.path.join(self.out + "2", "result.h5"), "r") as f2:
            self.assertEqual(f1["mesh/nodes"][()].tobytes(), f2["mesh/nodes"][()].tobytes())
            self.assertEqual(f1["mesh/triangles"][()].tobytes(),
                             f2["mesh/triangles"][()].tobytes())
        for s in (a, b):
            self.assertGreater(s["kernel_time_s"], 0)
            self.assertLess(s["kernel_time_s"], s["wall_time_s"])
            self.assertAlmostEqual(s["kernel_grind_ns"],
                                   s["kernel_time_s"] / (s["steps"] * s["elements"]) * 1e9)
            self.assertGreater(s["grind_ns"], s["kernel_grind_ns"])
            self.assertTrue(0 < s["meshing_share"] < 1)
            # The rest of the run: history samples and frame fields, frames handed to the writer
            # (two frames here, 0 and 20 ns), disjoint parts of its wall time.
            self.assertGreater(s["diagnostics_time_s"], 0)
            self.assertGreater(s["output_time_s"], 0)
            self.assertLess(s["kernel_time_s"] + s["diagnostics_time_s"] + s["output_time_s"],
                            s["wall_time_s"])
            self.assertAlmostEqual(s["output_share"], s["output_time_s"] / s["wall_time_s"])
            self.assertAlmostEqual(s["diagnostics_share"],
                                   s["diagnostics_time_s"] / s["wall_time_s"])
        self.assertLess(b["meshing_time_s"], a["meshing_time_s"])

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
        # The cause by name, the daemon's job reason (a Slurm job reads it from the result file).
        self.assertEqual(json.loads(r.stdout)["failure"], "ELEMENT_INVERSION")
        with h5py.File(os.path.join(self.out, "result.h5"), "r") as h5:
            self.assertEqual(int(h5.attrs["complete"]), 0)
            error = h5.attrs["error"]
            error = error.decode() if isinstance(error, bytes) else str(error)
            self.assertIn("element inversion", error)
            summary = h5.attrs["summary"]
            summary = json.loads(summary.decode() if isinstance(summary, bytes) else summary)
            self.assertEqual(summary["status"], "failed")
            self.assertEqual(summary["failure"], "ELEMENT_INVERSION")

    def test_usage_errors_exit_2(self):
        r = subprocess.run([SOLVE, "--spec"], capture_output=True, text=True)
        self.assertEqual(r.returncode, 2)
        r = subprocess.run([SOLVE, "--bogus"], capture_output=True, text=True)
        self.assertEqual(r.returncode, 2)

    def test_executables_do_not_load_libraries_from_the_working_directory(self):
        # A RUNPATH with an empty entry (CMake pads the build tree's with one) makes the loader
        # search the current directory: a file there named like a linked library is loaded.
        # Plant a bogus copy of every library each executable links, then start it from there.
        binaries = [SOLVE] + [os.environ[k] for k in ("SOFTSHOCKD", "SOFTSHOCK") if k in os.environ]
        for binary in binaries:
            with self.subTest(binary=os.path.basename(binary)):
                ldd = subprocess.run(["ldd", binary], capture_output=True, text=True, check=True,
                                     cwd="/")
                names = [line.split()[0] for line in ldd.stdout.splitlines()
                         if "=>" in line and "/" in line.split("=>")[1]]
                self.assertTrue(names, ldd.stdout)
                for name in names:
                    with open(os.path.join(self.tmp.name, name), "w") as f:
                        f.write("not a library\n")
                r = subprocess.run([binary, "--bogus"], capture_output=True, text=True,
                                   cwd=self.tmp.name, timeout=60)
                self.assertNotIn("error while loading shared libraries", r.stderr)
                self.assertEqual(r.returncode, 2, r.stderr)


if __name__ == "__main__":
    unittest.main()
