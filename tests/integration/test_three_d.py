"""3-D jobs through the service (issue 33, items 1-2): a cylinder submitted with the CLI and the
Python client, its summary, a planar slice of a field (CLI --slice with CSV and PNG, Python with
its plane's axes and xarray), the decimated surface, a grid over the thickness, a mesh of
tetrahedra uploaded and run, and admission control refusing an oversized 3-D spec by name."""

import csv
import io
import math
import os

import numpy as np

from softshock_harness import DaemonTestCase, SoftshockError, state_name

RUN = {"endTime": 1.5e-8, "outputInterval": 5e-9, "historyInterval": 1e-9}


def cylinder(thickness=6e-6, elements=3000, faces="SLIDING"):
    return {"geometry": {"cylinder": {"radius": 9e-5, "thickness": thickness, "faces": faces},
                         "targetElements": elements}, "run": dict(RUN)}


class ThreeDimensionalJobTest(DaemonTestCase):
    workers = 2

    def test_cylinder_job_summary_slice_and_surface(self):
        spec = self.write_json(cylinder(), "cylinder.json")
        job_id = self.cli_ok("submit", spec, "--wait").stdout.split()[0]
        summary = self.cli_json("summary", job_id)
        self.assertGreater(int(summary["elements"]), 2000)
        # The summary says it is 3-D and over which thickness its per-metre figures are.
        self.assertEqual(int(summary["dimension"]), 3)
        self.assertAlmostEqual(float(summary["thickness_m"]), 6e-6, delta=1e-12)

        # The mid-plane slice (the default z = 0) as CSV: cells inside the disk carry values,
        # the corners of the square raster lie outside it (NaN).
        p = self.cli_ok("field", job_id, "--name", "mean_stress", "--slice", "z=0",
                        "--raster", "32x32", "--csv", "-")
        rows = list(csv.DictReader(io.StringIO(p.stdout)))
        self.assertEqual(list(rows[0].keys()), ["u", "v", "x", "y", "z", "value"])
        self.assertEqual(len(rows), 32 * 32)
        inside = [r for r in rows if r["value"] != "nan"]
        self.assertGreater(len(inside), 0.6 * 32 * 32)  # pi / 4 of the square
        self.assertLess(len(inside), 0.9 * 32 * 32)
        for r in inside:
            self.assertAlmostEqual(float(r["z"]), 0.0, delta=1e-12)
            self.assertLess(math.hypot(float(r["x"]), float(r["y"])), 9.2e-5)
        # An oblique plane through the centre, and a PNG of the slice.
        png = os.path.join(self.tmp, "slice.png")
        self.cli_ok("field", job_id, "--name", "J", "--slice", "0,0,0:1,0,0", "--png", png)
        self.assertGreater(os.path.getsize(png), 1000)
        p = self.cli("field", job_id, "--name", "J", "--slice", "z=1e-3")
        self.assertEqual(p.returncode, 2, p.stderr)
        self.assertIn("slice: the plane does not cut the deformed body", p.stderr)

        c = self.client()
        f = c.field(job_id, "displacement", slice=((0, 0, 0), (0, 0, 1)), raster=(24, 24))
        self.assertEqual(f.dimension, 3)
        self.assertEqual(f.values.shape, (24, 24, 3))  # three components in 3-D
        self.assertEqual(f.slice_u, (1.0, 0.0, 0.0))
        self.assertEqual(f.slice_v, (0.0, 1.0, 0.0))
        da = f.to_xarray()
        self.assertEqual(da.dims, ("y", "x", "component"))
        # The pulse pushes the rim inwards: radial displacement negative where it is known.
        ux, uy = f.values[..., 0], f.values[..., 1]
        X, Y = np.meshgrid(da.x.values, da.y.values)
        ur = (ux * X + uy * Y) / np.hypot(X, Y)
        self.assertLess(np.nanmean(ur), 0)

        s = c.field(job_id, "J", surface=400)
        self.assertEqual(s.location, "surface")
        self.assertLessEqual(len(s.triangles), 400)
        self.assertEqual(s.vertices.shape[1], 3)
        self.assertEqual(len(s.values), len(s.triangles))  # an element field: per triangle
        self.assertTrue(np.all(s.triangles < len(s.vertices)))
        self.assertLess(np.abs(s.vertices[:, 2]).max(), 3.2e-6)  # within the layer
        p = self.cli_ok("field", job_id, "--name", "velocity", "--surface", "300", "--csv", "-")
        rows = list(csv.DictReader(io.StringIO(p.stdout)))
        self.assertEqual(list(rows[0].keys()), ["x", "y", "z", "value_x", "value_y", "value_z"])

        # 2-D-only requests on a 2-D job are refused by name.
        disk = c.submit({"geometry": {"targetElements": 400}, "run": dict(RUN)}, wait=True)
        with self.assertRaises(SoftshockError) as err:
            c.field(disk.id, "J", surface=100)
        self.assertIn("surface: is for 3-D results", err.exception.details)

    def test_grid_over_thickness_and_faces_and_admission(self):
        c = self.client()
        grid = c.submit_grid(cylinder(elements=2000),
                             axes=[{"name": "geometry.cylinder.thickness",
                                    "values": [4e-6, 8e-6]}], wait=True)
        self.assertEqual(grid.counts.succeeded, 2, grid)
        # BONDED faces hold the gel: less energy left than sliding ones, per unit thickness.
        sliding = c.submit(cylinder(elements=2000), wait=True)
        bonded = c.submit(cylinder(elements=2000, faces="BONDED"), wait=True)
        self.assertEqual(state_name(bonded), "SUCCEEDED")
        self.assertLess(c.summary(bonded.id)["energy_after_pulse"],
                        c.summary(sliding.id)["energy_after_pulse"])
        # Admission: a 3-D run far beyond the steps allowed is refused, naming the field.
        with self.assertRaises(SoftshockError) as err:
            huge = cylinder(elements=1_500_000)
            huge["run"]["endTime"] = 9e-6
            c.submit(huge)
        self.assertEqual(err.exception.code.name, "INVALID_ARGUMENT")
        self.assertIn("run.end_time", err.exception.details)

    def test_uploaded_tetrahedral_mesh_runs(self):
        import gmsh
        path = os.path.join(self.tmp, "box.msh")
        gmsh.initialize([], readConfigFiles=False)
        try:
            gmsh.option.setNumber("General.Terminal", 0)
            gmsh.model.occ.addBox(0, 0, 0, 2e-5, 2e-5, 1e-5)
            gmsh.model.occ.synchronize()
            gmsh.option.setNumber("Mesh.MeshSizeMax", 4e-6)
            gmsh.model.mesh.generate(3)
            gmsh.write(path)
        finally:
            gmsh.finalize()
        c = self.client()
        mesh = c.upload_mesh(path)
        self.assertGreater(mesh.elements, 100)
        job = c.submit({"geometry": {"meshId": mesh.id},
                        "load": {"pressure": 1e8, "duration": 2e-9}, "run": dict(RUN)}, wait=True)
        self.assertEqual(state_name(job), "SUCCEEDED", job)
        self.assertEqual(c.summary(job.id)["elements"], mesh.elements)
        f = c.field(job.id, "J", slice=((1e-5, 1e-5, 5e-6), (0, 1, 0)), raster=(16, 8))
        self.assertTrue(np.isfinite(f.values).any())
