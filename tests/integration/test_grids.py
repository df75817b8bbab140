"""End to end: parameter grids (submit -> wait -> reduction as table, CSV, PNG and numpy),
identical runs computed once, grid cancellation, result-database queries and the plots, through
the `softshock` CLI and the Python client against a real softshockd."""

import csv
import io
import os
import unittest

import grpc
import numpy as np
from matplotlib import image as mpimg

from softshock_client import SoftshockError, plots
from softshock_client.client import service_pb2
from softshock_harness import DaemonTestCase, long_spec, small_spec, state_name

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def small_grid(**extra) -> dict:
    """3 x 2 points of a 300-element disk to 20 ns: the CI-sized P-bar x t-bar_pulse study."""
    grid = {
        "base_spec": small_spec(elements=300, end_time=2e-8),
        "axes": [{"name": "pbar", "values": [0.5, 1.0, 1.5]},
                 {"name": "tbar_pulse", "linspace": {"start": 0.1, "stop": 0.2, "num": 2}}],
        "labels": {"study": "grid-it"},
    }
    grid.update(extra)
    return grid


class GridTest(DaemonTestCase):
    def assert_png(self, path: str) -> None:
        with open(path, "rb") as f:
            self.assertEqual(f.read(8), PNG_MAGIC, path)
        image = mpimg.imread(path)
        self.assertGreater(image.shape[0], 100)
        self.assertGreater(image.shape[1], 100)

    def submit_small_grid_cli(self) -> str:
        path = self.write_json(small_grid(), "grid.json")
        p = self.cli_ok("grid", "submit", path, "--wait", timeout=300)
        lines = p.stdout.strip().splitlines()
        self.assertIn("SUCCEEDED", lines[-1])
        return lines[0].strip()

    def test_submit_wait_reduce_dedup_and_query(self):
        grid_id = self.submit_small_grid_cli()
        status = self.cli_json("grid", "status", grid_id)
        self.assertEqual(status["state"], "SUCCEEDED")
        self.assertEqual(status["name"], f"grids/{grid_id}")
        self.assertEqual(status["shape"], [3, 2])
        self.assertEqual(status["counts"]["succeeded"], 6)
        self.assertAlmostEqual(status["progress"], 1.0)
        self.assertEqual([a["name"] for a in status["axes"]], ["pbar", "tbar_pulse"])

        # Table: a 3 x 2 matrix with the axis values as row and column heads.
        table = self.cli_ok("grid", "reduce", grid_id).stdout.splitlines()
        self.assertIn("max_abar_first_cycle", table[0])
        self.assertEqual(table[1].split()[-2:], ["0.1", "0.2"])
        self.assertEqual([line.split()[0] for line in table[2:]], ["0.5", "1", "1.5"])

        # CSV (long format) and the numpy matrix agree.
        rows = list(csv.DictReader(io.StringIO(
            self.cli_ok("grid", "reduce", grid_id, "--csv").stdout)))
        self.assertEqual(len(rows), 6)
        self.assertEqual(list(rows[0]), ["pbar", "tbar_pulse", "max_abar_first_cycle", "job_id",
                                         "state"])
        c = self.client()
        red = c.grid_reduction(grid_id)
        self.assertEqual(red.values.shape, (3, 2))
        self.assertEqual(red.axis_names, ["pbar", "tbar_pulse"])
        np.testing.assert_allclose(red.axis_values[0], [0.5, 1.0, 1.5])
        self.assertTrue(np.all(np.isfinite(red.values)) and np.all(red.values > 0))
        np.testing.assert_allclose(red.values.ravel(),
                                   [float(r["max_abar_first_cycle"]) for r in rows])
        self.assertEqual(list(red.job_ids.ravel()), [r["job_id"] for r in rows])
        self.assertTrue(all(s == "SUCCEEDED" for s in red.states.ravel()))
        # Each point carries its grid coordinates and runs the mapped parameters.
        job = c.get(rows[3]["job_id"])  # (pbar 1.0, tbar_pulse 0.2)
        self.assertEqual((job.grid_id, job.grid_index), (grid_id, 3))
        self.assertAlmostEqual(job.spec.load.pressure, 2e9)
        self.assertAlmostEqual(c.summary(job.id)["groups"]["tbar_pulse"], 0.2, places=9)

        for quantity, tbar in [("max_abar", None), ("abar_at", 0.2), ("energy_injected", None),
                               ("dominant_mode_end", None)]:
            r = c.grid_reduction(grid_id, quantity, tbar=tbar)
            self.assertEqual(r.values.shape, (3, 2), quantity)
            self.assertTrue(np.all(np.isfinite(r.values)), quantity)
        at_end = c.grid_reduction(grid_id, "abar_at", tbar=10.0)  # past the 20 ns runs
        self.assertTrue(np.all(np.isnan(at_end.values)))
        energy = c.grid_reduction(grid_id, "energy_injected")
        self.assertEqual(energy.units, "J/m")
        self.assertTrue(np.all(np.diff(energy.values, axis=0) > 0), "more pressure, more energy")

        png = os.path.join(self.tmp, "out", "grid.png")
        self.cli_ok("grid", "reduce", grid_id, "--quantity", "abar_at", "--tbar", "0.25",
                    "--png", png)
        self.assert_png(png)

        # Identical runs are computed once: the same grid again reuses every point.
        again = c.submit_grid(grid_file=self.write_json(small_grid(), "again.json"), wait=True)
        self.assertEqual(state_name(again), "SUCCEEDED")
        self.assertEqual(again.counts.reused, 6)
        again_red = c.grid_reduction(again.id)
        np.testing.assert_array_equal(again_red.values, red.values)
        reused = c.get(again_red.job_ids[1, 1])
        self.assertEqual(reused.reused_from, red.job_ids[1, 1])
        self.assertEqual(c.series(reused.id, names=["abar"])["abar"].size,
                         c.series(reused.reused_from, names=["abar"])["abar"].size)
        # A lone job opts in; 1 and 1.0, a default written out: all the same canonical spec.
        spec = small_spec(elements=300, end_time=2e-8)
        spec["load"] = {"pressure": 1.0e9 * 2, "duration": 0.1 * 90e-6 / (2e9 / 1000) ** 0.5}
        spec["viscosity"] = {"c1": 1}
        lone = c.submit(spec, reuse_result=True)
        self.assertEqual(state_name(lone), "SUCCEEDED")
        self.assertEqual(lone.reused_from, red.job_ids[1, 0])
        # recompute runs a point even though an identical run exists.
        fresh = c.submit_grid(small_spec(elements=300, end_time=2e-8),
                              [{"name": "pbar", "values": [0.5]}], recompute=True, wait=True)
        self.assertEqual(fresh.counts.reused, 0)
        self.assertEqual(fresh.counts.succeeded, 1)

        # Queries: ranges on groups and filters on summaries, sorted, paginated.
        hits = c.query(["pbar=0.75..1.5", "tbar_pulse<0.15", "max_abar_first_cycle>0"],
                       order_by="max_abar_first_cycle desc")
        self.assertGreaterEqual(len(hits), 2)
        for h in hits:
            self.assertTrue(0.75 <= h["pbar"] <= 1.5 and h["tbar_pulse"] < 0.15, h)
            self.assertGreater(h["summary"]["max_abar_first_cycle"], 0)
        ordered = [h["summary"]["max_abar_first_cycle"] for h in hits]
        self.assertEqual(ordered, sorted(ordered, reverse=True))
        in_grid = c.query(["gamma>6"], grid_id=grid_id)
        self.assertEqual(sorted(h["id"] for h in in_grid), sorted(red.job_ids.ravel()))
        request = service_pb2.QueryJobsRequest(order_by="pbar", page_size=4)
        request.filters.add(name="pbar", ge=0.0)
        seen = []
        while True:
            page = c._call(c._stub.QueryJobs, request)
            seen.extend(q.job.id for q in page.jobs)
            if not page.next_page_token:
                break
            request.page_token = page.next_page_token
        all_jobs = c.query(["pbar>=0"])
        self.assertEqual(sorted(seen), sorted(h["id"] for h in all_jobs))
        self.assertEqual(len(seen), len(set(seen)))
        q_csv = list(csv.DictReader(io.StringIO(self.cli_ok(
            "query", "--where", "pbar>=1.5", "--where", "max_abar>0", "--csv").stdout)))
        self.assertTrue(q_csv and all(float(r["pbar"]) >= 1.5 for r in q_csv))
        table = self.cli_ok("query", "--where", "gamma>6", "--grid", grid_id,
                            "--order-by", "max_abar desc").stdout
        self.assertEqual(len(table.strip().splitlines()), 7)

        # Plots from the CLI: A-bar(t) of several jobs, the mode heat map, a field snapshot.
        out = os.path.join(self.tmp, "out")
        ids = list(red.job_ids.ravel()[:3])
        self.cli_ok("series", *ids, "--png", os.path.join(out, "abar.png"))
        self.cli_ok("modes", ids[0], "--png", os.path.join(out, "modes.png"))
        self.cli_ok("field", ids[0], "--name", "mean_stress", "--time", "10ns",
                    "--png", os.path.join(out, "stress.png"))
        for name in ("abar.png", "modes.png", "stress.png"):
            self.assert_png(os.path.join(out, name))
        # ... and from Python, on the client's numpy arrays.
        series, time_scale = c.abar_series(ids)
        paths = [plots.plot_abar(series, os.path.join(out, "py_abar.png"), labels=ids,
                                 time_scale=time_scale),
                 plots.plot_mode_heatmap(c.modes(ids[0]), os.path.join(out, "py_modes.png"),
                                         time_scale=time_scale),
                 plots.plot_grid_heatmap(red, os.path.join(out, "py_grid.png"))]
        j = c.field(ids[0], "J", raster=(64, 64))
        paths.append(plots.plot_field_raster(j.values, j.extent, j.name, j.units, j.time,
                                             os.path.join(out, "py_J.png")))
        for p in paths:
            self.assert_png(p)

    def test_one_axis_grid_and_validation(self):
        c = self.client()
        grid = c.submit_grid(small_spec(elements=300, end_time=1e-8),
                             [{"name": "load.pressure", "geomspace": (1e9, 4e9, 3)}], wait=True)
        self.assertEqual(list(grid.shape), [3])
        red = c.grid_reduction(grid.id, "energy_injected")
        np.testing.assert_allclose(red.axis_values[0], [1e9, 2e9, 4e9])
        self.assert_png(plots.plot_grid_heatmap(red, os.path.join(self.tmp, "line.png")))
        self.assertEqual([g.id for g in c.list_grids()], [grid.id])

        bad = [
            ({"axes": []}, "axes"),
            ({"axes": [{"name": "no_such_group", "values": [1]}]}, "axes[0].name"),
            ({"axes": [{"name": "pbar", "values": []}]}, "axes[0]"),
            ({"axes": [{"name": "pbar", "linspace": {"start": 0.5, "stop": 1, "num": 0}}]},
             "axes[0].linspace.num"),
            ({"axes": [{"name": "gamma", "geomspace": {"start": -1, "stop": 1, "num": 3}}]},
             "axes[0].geomspace"),
            ({"axes": [{"name": n, "values": [1]} for n in ("pbar", "c1", "c2", "gamma")]},
             "axes"),
            ({"axes": [{"name": "pbar", "linspace": {"start": 0.1, "stop": 1, "num": 200}},
                       {"name": "gamma", "linspace": {"start": 5, "stop": 7, "num": 60}}]},
             "axes"),
        ]
        for grid_json, field in bad:
            request = dict(small_grid(), **grid_json)
            with self.assertRaises(SoftshockError, msg=field) as e:
                c.submit_grid(grid_file=self.write_json(request, "bad.json"))
            self.assertEqual(e.exception.code, grpc.StatusCode.INVALID_ARGUMENT, field)
            self.assertTrue(e.exception.details.startswith(field), e.exception.details)
        p = self.cli("grid", "submit", self.write_json(dict(small_grid(), axes=[]), "b.json"))
        self.assertEqual(p.returncode, 2, p.stderr)
        self.assertIn("INVALID_ARGUMENT", p.stderr)
        for call in (lambda: c.grid("nosuchgrid"), lambda: c.grid_reduction("nosuchgrid")):
            with self.assertRaises(SoftshockError) as e:
                call()
            self.assertEqual(e.exception.code, grpc.StatusCode.NOT_FOUND)
        with self.assertRaises(SoftshockError) as e:
            c.grid_reduction(grid.id, "abar_at")  # no t-bar
        self.assertEqual(e.exception.code, grpc.StatusCode.INVALID_ARGUMENT)
        with self.assertRaises(SoftshockError) as e:
            c.query(["no_such_column>1"])
        self.assertEqual(e.exception.code, grpc.StatusCode.INVALID_ARGUMENT)

    def test_cancel_grid(self):
        c = self.client()
        grid = c.submit_grid(long_spec(), [{"name": "pbar", "values": [0.9, 1.0, 1.1, 1.2]}])
        self.assertIn(state_name(grid), ("QUEUED", "RUNNING"))
        self.wait_for(lambda: c.grid(grid.id).counts.running > 0, 60, what="a running point")
        p = self.cli_ok("grid", "cancel", grid.id)
        self.assertIn("cancelled:", p.stdout)
        final = c.wait_grid(grid.id, timeout=60)
        self.assertEqual(state_name(final), "CANCELLED")
        self.assertTrue(final.cancelled)
        self.assertEqual(final.counts.queued + final.counts.running, 0)
        self.assertGreaterEqual(final.counts.cancelled, 2)
        red = c.grid_reduction(grid.id)
        cancelled = red.states == "CANCELLED"
        self.assertTrue(np.all(np.isnan(red.values[cancelled])))
        with self.assertRaises(SoftshockError) as e:
            c.cancel_grid(grid.id)
        self.assertEqual(e.exception.code, grpc.StatusCode.FAILED_PRECONDITION)
        p = self.cli("grid", "wait", grid.id)
        self.assertEqual(p.returncode, 1)


if __name__ == "__main__":
    unittest.main()
