"""Results leaving the server and runs compared (issue 36, items 1 and 2), against a real daemon:
`softshock fetch` and Client.download (resumable, SHA-256 checked, bounded per call), `softshock
diff`, the accounting columns of `softshock list` and labels edited after submission."""

import csv
import hashlib
import io
import json
import os
import unittest

import grpc

from softshock.v1 import service_pb2, service_pb2_grpc
from softshock_harness import DaemonTestCase, long_spec, small_spec


def sha256_of(path: str) -> str:
    with open(path, "rb") as f:
        return hashlib.sha256(f.read()).hexdigest()


class WorkflowTest(DaemonTestCase):
    def submit_done(self, spec: dict, *args: str) -> str:
        path = self.write_json(spec, f"spec-{len(os.listdir(self.tmp))}.json")
        job_id = self.cli_ok("submit", path, *args).stdout.split()[-1]
        self.cli_ok("watch", job_id)
        return job_id

    def daemon_file(self, job_id: str, name: str) -> str:
        return os.path.join(self.data_dir, "jobs", job_id, name)

    def test_fetch_resumes_and_checks_the_digest(self):
        job_id = self.submit_done(small_spec())
        out = os.path.join(self.tmp, "fetched")
        files = {f["file"]: f for f in self.cli_json("fetch", job_id, out)}
        self.assertEqual(set(files), {"result.h5", "result.xdmf", "spec.json", "summary.json"})
        for name, f in files.items():
            self.assertEqual(f["outcome"], "downloaded", name)
            self.assertEqual(sha256_of(f["path"]), f["sha256"], name)
            self.assertEqual(os.path.getsize(f["path"]), f["size"], name)
        # The result file is the daemon's, byte for byte.
        h5 = os.path.join(out, "result.h5")
        self.assertEqual(sha256_of(h5), sha256_of(self.daemon_file(job_id, "result.h5")))
        with open(os.path.join(out, "result.xdmf"), encoding="utf-8") as f:
            xdmf = f.read()
        self.assertIn("result.h5:/", xdmf)
        self.assertNotIn(self.data_dir, xdmf)  # references relative to the XDMF, for ParaView
        # The spec file is a spec softshock-solve reads; the summary has the solver's names.
        with open(os.path.join(out, "spec.json"), encoding="utf-8") as f:
            self.assertAlmostEqual(json.load(f)["run"]["endTime"], 2e-8)
        with open(os.path.join(out, "summary.json"), encoding="utf-8") as f:
            self.assertGreater(json.load(f)["energy_injected_J_per_m"], 0)

        # Fetched again: nothing moves.
        again = {f["file"]: f for f in self.cli_json("fetch", job_id, out)}
        self.assertTrue(all(f["outcome"] == "up to date" for f in again.values()), again)

        # Interrupted: the first 100,000 bytes as result.h5.part; the fetch continues from there.
        with open(h5, "rb") as f:
            whole = f.read()
        os.remove(h5)
        with open(h5 + ".part", "wb") as f:
            f.write(whole[:100_000])
        resumed = {f["file"]: f for f in self.cli_json("fetch", job_id, out, "--file", "h5")}
        self.assertEqual(list(resumed), ["result.h5"])
        self.assertEqual(resumed["result.h5"]["resumed_from"], 100_000)
        self.assertEqual(resumed["result.h5"]["outcome"], "downloaded")
        self.assertFalse(os.path.exists(h5 + ".part"))
        self.assertEqual(sha256_of(h5), files["result.h5"]["sha256"])

        # A part that is not this file's: the digest catches it and the file comes whole.
        os.remove(h5)
        with open(h5 + ".part", "wb") as f:
            f.write(b"\0" * 5000)
        text = self.cli_ok("fetch", job_id, out, "--file", "h5").stdout
        self.assertIn("the partial file did not match", text)
        self.assertEqual(sha256_of(h5), files["result.h5"]["sha256"])
        self.assertIn("ParaView: open", self.cli_ok("fetch", job_id, out).stdout)

        # The Python client: the same files, the same digests, resumed too.
        c = self.client()
        py_dir = os.path.join(self.tmp, "py")
        paths = c.download(job_id, py_dir)
        self.assertEqual(sha256_of(paths["result.h5"]), files["result.h5"]["sha256"])
        with open(paths["result.h5"], "rb") as f:
            data = f.read()
        os.remove(paths["result.h5"])
        with open(paths["result.h5"] + ".part", "wb") as f:
            f.write(data[:4096])
        c.download(job_id, py_dir, files=["h5"])
        self.assertEqual(c.last_download["result.h5"].resumed_from, 4096)
        self.assertEqual(sha256_of(paths["result.h5"]), files["result.h5"]["sha256"])

    def test_download_is_bounded_per_call_and_refused_while_running(self):
        job_id = self.submit_done(small_spec())
        stub = service_pb2_grpc.SimulationServiceStub(grpc.insecure_channel(self.daemon.address))

        def call(**kw):
            request = service_pb2.DownloadResultRequest(name=f"jobs/{job_id}",
                                                        file=service_pb2.RESULT_H5, **kw)
            return list(stub.DownloadResult(request, timeout=30))

        size = os.path.getsize(self.daemon_file(job_id, "result.h5"))
        chunks = call(offset=1000, max_bytes=7000)
        self.assertEqual(chunks[0].info.size, size)
        self.assertEqual(chunks[0].info.file_name, "result.h5")
        self.assertTrue(chunks[0].info.complete)
        self.assertEqual(sum(len(c.data) for c in chunks), 7000)
        self.assertEqual(chunks[1].offset, 1000)
        with open(self.daemon_file(job_id, "result.h5"), "rb") as f:
            self.assertEqual(b"".join(c.data for c in chunks), f.read()[1000:8000])
        whole = call()
        self.assertEqual(sum(len(c.data) for c in whole), size)
        self.assertTrue(all(len(c.data) <= 512 * 1024 for c in whole))
        self.assertEqual(call(offset=size)[0].info.size, size)  # nothing left: the header alone
        with self.assertRaises(grpc.RpcError) as beyond:
            call(offset=size + 1)
        self.assertEqual(beyond.exception.code(), grpc.StatusCode.INVALID_ARGUMENT)

        running = self.cli_ok("submit", self.write_json(long_spec(), "long.json")).stdout.split()[-1]
        self.wait_running(self.client(), running)
        p = self.cli("fetch", running, os.path.join(self.tmp, "early"))
        self.assertEqual(p.returncode, 1, p.stderr)
        self.assertIn("once it finished", p.stderr)
        with self.assertRaises(grpc.RpcError) as early:
            list(stub.DownloadResult(service_pb2.DownloadResultRequest(
                id=running, file=service_pb2.SUMMARY), timeout=30))
        self.assertEqual(early.exception.code(), grpc.StatusCode.FAILED_PRECONDITION)
        self.cli_ok("cancel", running)

    def test_diff_list_and_labels(self):
        viscous = small_spec()
        viscous["material"] = {"shearViscosity": 0.5}
        a = self.submit_done(small_spec(), "--label", "study=visc")
        b = self.submit_done(viscous, "--label", "study=visc")

        d = self.cli_json("diff", a, b)
        self.assertEqual((d["a"], d["b"]), (a, b))
        self.assertEqual([r["name"] for r in d["spec"]], ["material.shear_viscosity"])
        self.assertEqual(d["spec"][0]["b"], 0.5)
        self.assertNotEqual(d["spec"][0]["a"], 0.5)
        figures = {r["name"]: r for r in d["summary"]}
        self.assertNotIn("id", figures)
        energy = figures["energy_injected_J_per_m"]
        self.assertGreater(energy["a"], 0)
        self.assertAlmostEqual(energy["relative"], (energy["b"] - energy["a"]) / energy["a"])
        self.assertEqual(figures["elements"]["relative"], 0)
        text = self.cli_ok("diff", a, b).stdout
        self.assertIn("1 fields differ", text)
        self.assertRegex(text, r"material\.shear_viscosity\s+\S+\s+0\.5\s+\+")
        png = os.path.join(self.tmp, "diff.png")
        self.cli_ok("diff", a, b, "--png", png)
        with open(png, "rb") as f:
            self.assertEqual(f.read(8), b"\x89PNG\r\n\x1a\n")

        # Labels after submission: set, change, remove; the filter sees them.
        self.assertEqual(self.cli_ok("label", a, "note=baseline", "-study").stdout.strip(),
                         f"{a}: note=baseline")
        job = self.cli_json("label", b, "study=visc2", "note=viscous")
        self.assertEqual(job["labels"], {"study": "visc2", "note": "viscous"})
        self.assertEqual([j["id"] for j in self.cli_json("list", "--label", "note=baseline")
                          ["jobs"]], [a])
        bad = self.cli("label", a, "=x")
        self.assertEqual(bad.returncode, 2, bad.stderr)
        missing = self.cli("label", "0123456789abcdef", "k=v")
        self.assertNotEqual(missing.returncode, 0)
        self.assertIn("NOT_FOUND", missing.stderr)

        # sacct-like columns, chosen spec fields, time windows, CSV.
        lines = self.cli_ok("list", "--fields", "material.shear_viscosity").stdout.splitlines()
        self.assertRegex(lines[0], r"ID\s+STATE\s+REASON\s+PROGRESS\s+ELAPSED\s+OWNER\s+CREATED\s+"
                                   r"material\.shear_viscosity\s+LABELS")
        self.assertEqual(len(lines), 3)
        rows = list(csv.DictReader(io.StringIO(self.cli_ok(
            "list", "--format", "csv", "--since", "1h", "--fields",
            "material.shear_viscosity").stdout)))
        self.assertEqual({r["id"] for r in rows}, {a, b})
        by_id = {r["id"]: r for r in rows}
        self.assertEqual(by_id[b]["material.shear_viscosity"], "0.5")
        self.assertEqual(by_id[a]["state"], "SUCCEEDED")
        self.assertGreater(float(by_id[a]["elapsed_s"]), 0)
        self.assertLess(float(by_id[a]["elapsed_s"]), 60)
        self.assertEqual(self.cli_ok("list", "--until", "2000-01-01").stdout,
                         "no jobs match these filters\n")
        self.assertEqual(self.cli_json("list", "--since", "2000-01-01T00:00:00Z")["jobs"][0]["id"],
                         b)
        bad_time = self.cli("list", "--since", "yesterday")
        self.assertEqual(bad_time.returncode, 2)
        self.assertIn("is not a time", bad_time.stderr)
        bad_field = self.cli("list", "--fields", "material.shear_viscocity")
        self.assertEqual(bad_field.returncode, 2)
        self.assertIn("shear_viscosity", bad_field.stderr)  # did you mean

        # Python: labels and the accounting window.
        c = self.client()
        self.assertEqual(dict(c.set_labels(a, {"k": "v"}, remove=["note"]).labels), {"k": "v"})
        self.assertEqual(len(c.list(created_after=0)), 2)
        self.assertEqual(c.list(created_before=946684800), [])


if __name__ == "__main__":
    unittest.main()
