"""End to end through the Python client (softshock_client) and its plots."""

import math
import os
import unittest

import grpc
import numpy as np

from softshock_client import SoftshockError, SpecError, plots
from softshock_harness import TERMINAL, DaemonTestCase, small_spec, state_name


class PythonClientTest(DaemonTestCase):
    def test_submit_wait_and_results(self):
        c = self.client()
        self.assertEqual(c.health(), "SERVING")
        seen = []
        job = c.submit(small_spec(end_time=3e-8), labels={"study": "py"})
        for update in c.watch(job.id):
            seen.append(state_name(update))
        self.assertEqual(seen[-1], "SUCCEEDED")
        # States only move forward: QUEUED* RUNNING* SUCCEEDED.
        order = {"QUEUED": 0, "RUNNING": 1, "SUCCEEDED": 2}
        self.assertEqual([order[s] for s in seen], sorted(order[s] for s in seen))

        got = c.get(job.id)
        self.assertEqual(state_name(got), "SUCCEEDED")
        self.assertEqual(dict(got.labels), {"study": "py"})

        # Every grid quantity the daemon lists, a reduction would take: here, every such figure
        # is a key of the summary of a run without damage, or a damage-only one.
        figures = c.summary_figures()
        summary = c.summary(job.id)
        for f in figures:
            if f["grid_quantity"] and not f["only_damage"]:
                self.assertIn(f["name"], summary, f)
        self.assertEqual(next(f for f in figures if f["name"] == "wall_time_s")["former_name"],
                         "wall_time")
        # The client's offline copy of the former names is the daemon's.
        from softshock_client.jobs import RENAMED_SUMMARY_NAMES
        self.assertEqual({f["former_name"]: f["name"] for f in figures if f["former_name"]},
                         RENAMED_SUMMARY_NAMES)
        self.assertEqual(got.attempt, 1)
        self.assertTrue(got.result_path.endswith(".h5"), got.result_path)

        summary = c.summary(job.id)
        self.assertIsInstance(summary["elements"], int)
        self.assertGreater(summary["steps"], 0)
        self.assertAlmostEqual(summary["end_time_s"], 3e-8, delta=1e-10)
        self.assertGreater(summary["groups"]["time_scale_s"], 0)
        # Where the time went: the element loop alone inside the run, and the meshing before it.
        self.assertGreater(summary["kernel_time_s"], 0)
        self.assertLess(summary["kernel_grind_ns"], summary["grind_ns"])
        self.assertIn(summary["mesh_cache"], ("hit", "miss"))
        self.assertTrue(0 <= summary["meshing_share"] < 1)
        self.assertTrue(0 < summary["diagnostics_share"] < 1)
        self.assertTrue(0 <= summary["output_share"] < 1)
        self.assertLess(summary["diagnostics_time_s"] + summary["output_time_s"],
                        summary["wall_time_s"])
        # Provenance: the solver revision that computed it (0 only for results from before).
        self.assertGreaterEqual(summary["solver_revision"], 1)

        series = c.series(job.id)
        self.assertIn("abar", series)
        self.assertEqual(series.units["time"], "s")
        n = series["time"].size
        self.assertGreaterEqual(n, 25)
        self.assertTrue(all(v.shape == (n,) for v in series.values()))
        self.assertTrue(np.all(np.diff(series["time"]) > 0))
        self.assertTrue(np.all(series["abar"] >= 0))
        thin = c.series(job.id, names=["abar"], every=4)
        self.assertEqual(sorted(thin), ["abar", "time"])
        self.assertEqual(thin["time"].size, math.ceil(n / 4))

        t, mode_numbers, amp = c.modes(job.id)
        self.assertEqual(amp.shape, (t.size, mode_numbers.size))
        self.assertEqual(mode_numbers[0], 0)
        t2, m2, a2 = c.modes(job.id, mode_min=2, mode_max=8, every=2)
        self.assertEqual(list(m2), list(range(2, 9)))
        self.assertEqual(a2.shape, (math.ceil(t.size / 2), 7))
        np.testing.assert_allclose(a2, amp[::2, 2:9])

        raster = c.field(job.id, "mean_stress", raster=(40, 30))
        self.assertEqual(raster.values.shape, (30, 40))
        self.assertEqual(raster.location, "raster")
        self.assertEqual(raster.units, "Pa")
        x0, x1, y0, y1 = raster.extent
        self.assertLess(x0, 0)
        self.assertGreater(x1, 0)
        self.assertAlmostEqual(x1 - x0, 2 * 9e-5, delta=0.3 * 9e-5)  # deformed disk's box
        outside = np.isnan(raster.values)
        self.assertTrue(outside[0, 0] and outside[-1, -1])  # corners lie outside the disk
        self.assertFalse(outside[15, 20])                  # the centre lies inside
        values, extent = raster  # unpacks like a (values, extent) pair
        self.assertIs(values, raster.values)

        disp = c.field(job.id, "displacement", raster=(8, 6), frame=1)
        self.assertEqual(disp.values.shape, (6, 8, 2))
        self.assertEqual(disp.frame, 1)
        nodal = c.field(job.id, "velocity", every=10)
        self.assertEqual(nodal.values.ndim, 2)
        self.assertEqual(nodal.values.shape[1], 2)
        self.assertIsNone(nodal.extent)
        at = c.field(job.id, "J", time=1.1e-8, every=1)
        self.assertAlmostEqual(at.time, 1e-8, delta=1e-12)  # nearest frame (every 5 ns)
        self.assertEqual(at.values.size, summary["elements"])

        self.assertEqual([j.id for j in c.list(label="study=py")], [job.id])

        # Plots: files exist and are real PNGs.
        out = os.path.join(self.tmp, "plots")
        paths = [
            plots.plot_abar([series, thin], os.path.join(out, "abar.png"),
                            labels=["all", "every 4"], time_scale=summary["groups"]["time_scale_s"]),
            plots.plot_mode_heatmap((t, mode_numbers, amp), os.path.join(out, "modes.png")),
            plots.plot_field_raster(raster.values, raster.extent, raster.name, raster.units,
                                    raster.time, os.path.join(out, "field.png")),
            plots.plot_field_raster(disp.values, disp.extent, disp.name, disp.units, disp.time,
                                    os.path.join(out, "disp.png"), frame=disp.frame),
        ]
        for p in paths:
            with open(p, "rb") as f:
                self.assertEqual(f.read(8), b"\x89PNG\r\n\x1a\n", p)
            self.assertGreater(os.path.getsize(p), 10_000, p)

    def test_submit_from_path_and_wait(self):
        c = self.client()
        path = self.write_json(small_spec(elements=300, end_time=1e-8))
        job = c.submit(path, wait=True)
        self.assertEqual(state_name(job), "SUCCEEDED")
        self.assertIn(state_name(job), TERMINAL)

    def test_errors(self):
        c = self.client()
        with self.assertRaises(SpecError) as e:
            c.submit({"geometry": {"disk": {"radius": 9e-5}}, "runn": {}})
        self.assertIn("runn", str(e.exception))
        with self.assertRaises(SoftshockError) as e:
            c.submit({"geometry": {"disk": {"radius": -1e-5}}})
        self.assertEqual(e.exception.code, grpc.StatusCode.INVALID_ARGUMENT)
        self.assertIn("geometry.disk.radius", e.exception.details)
        for call in (lambda: c.get("nosuchjob"), lambda: c.summary("nosuchjob"),
                     lambda: c.series("nosuchjob"), lambda: c.field("nosuchjob", "J"),
                     lambda: list(c.watch("nosuchjob"))):
            with self.assertRaises(SoftshockError) as e:
                call()
            self.assertEqual(e.exception.code, grpc.StatusCode.NOT_FOUND)

        job = c.submit(small_spec(elements=300, end_time=1e-8), wait=True)
        with self.assertRaises(SoftshockError) as e:
            c.field(job.id, "no_such_field")
        self.assertEqual(e.exception.code, grpc.StatusCode.INVALID_ARGUMENT)
        with self.assertRaises(SoftshockError) as e:
            c.field(job.id, "J", frame=10_000)
        self.assertIn(e.exception.code,
                      (grpc.StatusCode.OUT_OF_RANGE, grpc.StatusCode.INVALID_ARGUMENT))
        with self.assertRaises(SoftshockError) as e:
            c.list(page_size=-1)
        self.assertEqual(e.exception.code, grpc.StatusCode.INVALID_ARGUMENT)


if __name__ == "__main__":
    unittest.main()
