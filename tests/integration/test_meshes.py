"""Meshes uploaded by remote clients, end to end: a rounded square meshed by the client's own
Gmsh (python3-gmsh), submitted with the CLI and the Python client as a local geometry.mesh_file
(uploaded, content-addressed, run, summarised), a grid over it, listing, deletion refused while
a job waits on the mesh, bad uploads and references rejected with the field named, and hostile
uploads (a file that crashes Gmsh, counts that would exhaust memory) refused while the daemon
and its running job go on."""

import glob
import hashlib
import json
import os

from softshock_harness import DaemonTestCase, SoftshockError, long_spec, state_name

RUN = {"endTime": 2e-8, "outputInterval": 1e-8, "historyInterval": 1e-9}


def mesh_rounded_square(path, side=1.2e-4, corner=3e-5, size=1e-5):
    import gmsh
    gmsh.initialize([], readConfigFiles=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("rounded_square")
        gmsh.model.occ.addRectangle(-side / 2, -side / 2, 0, side, side, roundedRadius=corner)
        gmsh.model.occ.synchronize()
        gmsh.option.setNumber("Mesh.MeshSizeMax", size)
        gmsh.model.mesh.generate(2)
        gmsh.write(path)
    finally:
        gmsh.finalize()


class MeshUploadTest(DaemonTestCase):
    workers = 1

    def setUp(self):
        super().setUp()
        self.shapes = os.path.join(self.tmp, "client-side")
        os.makedirs(self.shapes)
        self.msh = os.path.join(self.shapes, "square.msh")
        mesh_rounded_square(self.msh)
        with open(self.msh, "rb") as f:
            self.sha = hashlib.sha256(f.read()).hexdigest()

    def test_client_meshed_square_uploaded_run_and_summarised(self):
        spec = self.write_json({"geometry": {"meshFile": "square.msh"}, "run": RUN},
                               "client-side/spec.json")
        p = self.cli_ok("submit", spec, "--wait")
        self.assertIn(f"uploaded {self.msh} as meshes/{self.sha}", p.stderr)
        job_id = p.stdout.split()[0]
        summary = self.cli_json("summary", job_id)
        meshes = self.cli_json("mesh", "list")["meshes"]
        self.assertEqual([m["id"] for m in meshes], [self.sha])  # content-addressed
        self.assertEqual(int(summary["elements"]), int(meshes[0]["elements"]))
        self.assertEqual(meshes[0]["fileName"], "square.msh")
        job = self.cli_json("status", job_id)
        self.assertEqual(job["spec"]["geometry"]["meshFile"], f"uploads/{self.sha}.msh")

        # Idempotent: the CLI, the Python client and the submit path all give the same mesh.
        self.assertEqual(self.cli_ok("mesh", "upload", self.msh).stdout.strip(), self.sha)
        c = self.client()
        self.assertEqual(c.upload_mesh(self.msh).id, self.sha)
        again = c.submit(spec, wait=True, reuse_result=True)
        self.assertEqual(state_name(again), "SUCCEEDED")
        self.assertEqual(again.reused_from, job_id)  # same bytes, same spec hash
        self.assertEqual(len(c.list_meshes()), 1)

        # A grid over the uploaded mesh (the base spec's file is relative to the grid file).
        grid = self.write_json({"baseSpec": {"geometry": {"meshFile": "square.msh"}, "run": RUN},
                                "axes": [{"name": "load.pressure", "values": [1e9, 2e9]}]},
                               "client-side/grid.json")
        self.cli_ok("grid", "submit", grid, "--wait")

    def test_delete_refused_while_a_job_waits_on_the_mesh(self):
        c = self.client()
        blocker = c.submit(long_spec())  # occupies the only worker
        self.wait_running(c, blocker.id)

        mesh = c.upload_mesh(self.msh)
        waiting = c.submit({"geometry": {"meshId": mesh.id}, "run": RUN})
        self.assertEqual(state_name(c.get(waiting.id)), "QUEUED")
        p = self.cli("mesh", "delete", mesh.id)
        self.assertEqual(p.returncode, 1, p.stderr)
        self.assertIn(f"is used by job jobs/{waiting.id}", p.stderr)
        self.assertIn("FAILED_PRECONDITION", p.stderr)
        c.cancel(waiting.id)
        c.cancel(blocker.id)
        deleted = self.cli_ok("mesh", "delete", f"meshes/{mesh.id}").stdout
        self.assertEqual(deleted, f"deleted: meshes/{mesh.id}\n")  # says what went, not nothing
        self.assertEqual(c.list_meshes(), [])
        p = self.cli("mesh", "delete", mesh.id)
        self.assertEqual(p.returncode, 1)
        self.assertIn("NOT_FOUND", p.stderr)
        with self.assertRaises(SoftshockError) as err:
            c.submit({"geometry": {"meshId": mesh.id}, "run": RUN})
        self.assertIn("geometry.mesh_id: no uploaded mesh", err.exception.details)

    def test_bad_uploads_and_references_name_the_field(self):
        bogus = self.write_json({"not": "a mesh"}, "bogus.msh")
        p = self.cli("mesh", "upload", bogus)
        self.assertEqual(p.returncode, 2, p.stderr)
        self.assertIn("data: 'bogus.msh' is not a usable Gmsh mesh", p.stderr)
        self.assertIn("bogus.msh", p.stderr)
        self.assertNotIn(".staged-", p.stderr)  # the server's own file name stays private
        mesh_id = self.cli_ok("mesh", "upload", self.msh).stdout.strip()
        both = self.write_json({"geometry": {"meshId": mesh_id, "disk": {"radius": 1e-4}}})
        p = self.cli("submit", both)
        self.assertEqual(p.returncode, 2)
        self.assertIn("spec.geometry.mesh_id: cannot be combined", p.stderr)
        missing = self.write_json({"geometry": {"meshFile": "/nonexistent/square.msh"}})
        p = self.cli("submit", missing)
        self.assertEqual(p.returncode, 2)
        self.assertIn("'/nonexistent/square.msh' is not a file on this machine", p.stderr)
        p = self.cli("--json", "mesh", "list")
        self.assertEqual(len(json.loads(p.stdout)["meshes"]), 1)


# Two triangles, MSH 4.1, the second naming node `tag`: Gmsh 4.8 segfaults on 2^63 - 1 or -1.
def square_msh41(tag="4"):
    return ("$MeshFormat\n4.1 0 8\n$EndMeshFormat\n"
            "$Nodes\n1 4 1 4\n2 1 0 4\n1\n2\n3\n4\n0 0 0\n1e-4 0 0\n1e-4 1e-4 0\n0 1e-4 0\n"
            "$EndNodes\n$Elements\n1 2 1 2\n2 1 2 2\n1 1 2 3\n2 1 3 " + tag + "\n$EndElements\n")


class HostileUploadTest(DaemonTestCase):
    workers = 1

    def write_text(self, name, text):
        path = os.path.join(self.tmp, name)
        with open(path, "w") as f:
            f.write(text)
        return path

    def test_uploads_that_crash_gmsh_or_exhaust_memory_leave_the_daemon_and_its_job_alone(self):
        c = self.client()
        job = c.submit(long_spec())  # runs while the uploads arrive
        self.wait_running(c, job.id)
        crash = self.write_text("crash.msh", square_msh41("9223372036854775807"))
        negative = self.write_text("negative.msh", square_msh41("-1"))
        huge = self.write_text("huge.msh", "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n"
                               "1 150000000 1 150000000\n2 1 0 150000000\n1\n2\n3\n$EndNodes\n")
        for path, why in ((crash, "Gmsh crashed reading it"), (negative, "Gmsh crashed reading it"),
                          (huge, "$Nodes declares 150000000 nodes")):
            p = self.cli("mesh", "upload", path)
            self.assertEqual(p.returncode, 2, p.stderr)
            self.assertIn("INVALID_ARGUMENT", p.stderr)
            self.assertIn(f"'{os.path.basename(path)}' is not a usable Gmsh mesh: {why}", p.stderr)
            self.assertNotIn(self.data_dir, p.stderr)  # no server path
        self.cli_ok("health")
        # Nothing staged is left, and a good upload still works.
        self.assertEqual(glob.glob(os.path.join(self.data_dir, "meshes", "uploads", ".*")), [])
        self.assertEqual(len(self.cli_ok("mesh", "upload", self.write_text(
            "ok.msh", square_msh41())).stdout.strip()), 64)
        done = c.wait(job.id, timeout=600)
        self.assertEqual(state_name(done), "SUCCEEDED")
        self.assertEqual(done.attempt, 1)  # never interrupted by a daemon crash

    def test_names_with_folders_or_control_characters_are_refused(self):
        import grpc
        from softshock.v1 import service_pb2
        c = self.client()
        for name in ("../../etc/passwd", "a\x00b.msh", "x" * 256):
            request = service_pb2.UploadMeshRequest(file_name=name, data=square_msh41().encode())
            with self.assertRaises(SoftshockError) as err:
                c._call(lambda r, **kw: c._meshes.UploadMesh(iter([r]), **kw), request)
            self.assertEqual(err.exception.code, grpc.StatusCode.INVALID_ARGUMENT)
            self.assertIn("file_name: ", err.exception.details)
            self.assertLess(len(err.exception.details), 200)  # never echoes the name
        self.assertEqual(c.list_meshes(), [])
