"""End to end through the `softshock` CLI: submit -> watch -> status -> summary -> series,
modes and field exports (CSV, PNG, JSON) -> list -> delete, against a real softshockd."""

import csv
import io
import json
import math
import os
import unittest

from softshock_harness import DaemonTestCase, small_spec


class CliWorkflowTest(DaemonTestCase):
    def submit_small(self, *extra, **spec_kw):
        spec = self.write_json(small_spec(**spec_kw))
        p = self.cli_ok("submit", spec, "--wait", *extra)
        lines = p.stdout.strip().splitlines()
        job_id = lines[0].strip()
        self.assertRegex(job_id, r"^[A-Za-z0-9_-]+$", p.stdout)
        # Plain (non-TTY) progress lines, ending with the terminal state.
        self.assertIn("SUCCEEDED", lines[-1])
        self.assertIn(job_id, lines[-1])
        return job_id

    def test_submit_watch_status_summary(self):
        job_id = self.submit_small("--label", "study=cli", "--label", "case=1", "--priority", "3")

        status = self.cli_ok("status", job_id).stdout
        fields = dict(line.split(":", 1) for line in status.splitlines())
        self.assertEqual(fields["state"].strip(), "SUCCEEDED")
        self.assertEqual(fields["labels"].strip(), "case=1,study=cli")
        self.assertEqual(fields["priority"].strip(), "3")
        self.assertIn("100 %", fields["progress"])
        # Values are aligned in one column.
        starts = {len(line) - len(line[line.index(":") + 1:].lstrip())
                  for line in status.splitlines()}
        self.assertEqual(len(starts), 1, status)

        job = self.cli_json("status", job_id)
        self.assertEqual(job["state"], "SUCCEEDED")
        self.assertEqual(job["id"], job_id)
        self.assertEqual(job["name"], f"jobs/{job_id}")
        self.assertEqual(job["labels"], {"study": "cli", "case": "1"})
        self.assertAlmostEqual(job["spec"]["geometry"]["disk"]["radius"], 9e-5)
        self.assertAlmostEqual(job["spec"]["run"]["endTime"], 2e-8)
        self.assertAlmostEqual(job["progress"]["fraction"], 1.0, places=6)
        # Bare id and resource name are interchangeable.
        self.assertEqual(self.cli_json("status", f"jobs/{job_id}")["id"], job_id)

        summary_text = self.cli_ok("summary", job_id).stdout
        for key, unit in [("wall time", " s"), ("simulated time", " ns"),
                          ("energy injected", " J/m"), ("time scale R0/c0", " ns")]:
            line = next(l for l in summary_text.splitlines() if l.startswith(key + ":"))
            self.assertTrue(line.rstrip().endswith(unit), line)
        self.assertIn("kernel grind time:", summary_text)
        self.assertRegex(summary_text, r"meshing: .* s \(.* % of meshing \+ run; mesh cache: ")
        self.assertRegex(summary_text, r"diagnostics: .* s \(.* % of the run: history samples")
        self.assertRegex(summary_text, r"output: .* s \(.* % of the run: frames handed to")
        summary = self.cli_json("summary", job_id)
        self.assertGreater(int(summary["elements"]), 200)
        self.assertGreater(int(summary["steps"]), 0)
        self.assertAlmostEqual(summary["end_time_s"], 2e-8, delta=1e-10)
        self.assertGreater(summary["energy_injected_J_per_m"], 0)
        self.assertAlmostEqual(summary["groups"]["gamma"], 6.15)

        # The daemon's table of figures names every figure the summary has, and says which the
        # query and grid reduce take.
        figures = self.cli_json("figures")["figures"]
        names = {f["name"] for f in figures}
        self.assertLessEqual(set(summary) - {"id", "groups"}, names)
        self.assertLessEqual(set(summary["groups"]), {f["name"] for f in figures
                                                      if f.get("inGroups")})
        by_name = {f["name"]: f for f in figures}
        self.assertEqual(by_name["energy_injected_J_per_m"]["unit"], "J/m")
        self.assertEqual(by_name["energy_injected_J_per_m"]["formerName"], "energy_injected")
        self.assertTrue(by_name["max_abar_first_cycle"].get("gridQuantity"))
        self.assertFalse(by_name["nodes"].get("queryable", False))
        listed = self.cli_ok("figures", "--query").stdout.splitlines()
        queryable = [line.split()[0] for line in listed[1:]]
        self.assertEqual(sorted(queryable),
                         sorted(("groups." if f.get("inGroups") else "") + f["name"]
                                for f in figures if f.get("queryable")))
        # The list is exactly what the query takes: every listed name, and no other figure.
        for name in queryable:
            self.cli_ok("query", "--where", name.removeprefix("groups.") + ">-1e300")
        for f in figures:
            if not f.get("queryable"):
                p = self.cli("query", "--where", f["name"] + ">-1e300")
                self.assertNotEqual(p.returncode, 0, f["name"])

        health = self.cli_ok("health")
        self.assertIn("SERVING", health.stdout)

    def test_series_and_modes(self):
        job_id = self.submit_small(end_time=3e-8)

        rows = list(csv.reader(io.StringIO(self.cli_ok("series", job_id, "--csv").stdout)))
        header, data = rows[0], rows[1:]
        self.assertEqual(header[0], "time")
        self.assertIn("abar", header)
        self.assertIn("kinetic_energy", header)
        times = [float(r[0]) for r in data]
        self.assertGreaterEqual(len(times), 20)  # history every 1 ns over 30 ns
        self.assertEqual(times, sorted(times))
        self.assertAlmostEqual(times[-1], 3e-8, delta=1.1e-9)
        self.assertTrue(all(len(r) == len(header) for r in data))

        every = list(csv.reader(io.StringIO(
            self.cli_ok("series", job_id, "--csv", "--every", "3", "--name", "abar").stdout)))
        self.assertEqual(every[0], ["time", "abar"])
        self.assertEqual(len(every) - 1, math.ceil(len(data) / 3))

        table = self.cli_ok("series", job_id, "--name", "abar", "--name", "kinetic_energy")
        self.assertIn("t (ns)", table.stdout.splitlines()[0])
        self.assertIn("kinetic_energy (J/m)", table.stdout.splitlines()[0])

        modes = list(csv.reader(io.StringIO(self.cli_ok(
            "modes", job_id, "--csv", "--mode-min", "2", "--mode-max", "4").stdout)))
        self.assertEqual(modes[0], ["time", "mode_2", "mode_3", "mode_4"])
        self.assertGreater(len(modes), 2)
        self.assertTrue(all(math.isfinite(float(v)) for r in modes[1:] for v in r))

        m = self.cli_json("modes", job_id, "--every", "2")
        self.assertEqual(len(m["amplitude"]), len(m["time"]) * m["modeCount"])
        # Modes 0..M with M = min(64, (N - 1) / 2) for a rim of N nodes (the rest would be aliases):
        # the 400-element disk's 49 rim nodes give 0..24 (docs/results-format.md).
        self.assertEqual(m["modeCount"], 25)

    def test_field_exports(self):
        job_id = self.submit_small()
        elements = int(self.cli_json("summary", job_id)["elements"])

        out = os.path.join(self.tmp, "ms.csv")
        text = self.cli_ok("field", job_id, "--name", "mean_stress", "--raster", "32x24",
                           "--csv", out).stdout
        self.assertIn("wrote:", text)
        with open(out) as f:
            rows = list(csv.reader(f))
        self.assertEqual(rows[0], ["x", "y", "value"])
        self.assertEqual(len(rows) - 1, 32 * 24)
        values = [float(r[2]) for r in rows[1:]]
        nan = sum(math.isnan(v) for v in values)
        # A disk in its bounding box: the corners (1 - pi/4 of the area) lie outside.
        self.assertGreater(nan, 0.1 * len(values))
        self.assertLess(nan, 0.35 * len(values))
        xs = [float(r[0]) for r in rows[1:]]
        self.assertLess(max(abs(x) for x in xs), 1.2e-4)  # metres, cell centres

        vec = self.cli_ok("field", job_id, "--name", "displacement", "--raster", "8x8", "--csv",
                          "-").stdout.splitlines()
        self.assertEqual(vec[0], "x,y,value_x,value_y")
        self.assertEqual(len(vec), 65)

        per_element = self.cli_ok("field", job_id, "--name", "J", "--every", "1", "--csv",
                                  "-").stdout.splitlines()
        self.assertEqual(per_element[0], "index,value")
        self.assertEqual(len(per_element) - 1, elements)
        self.assertTrue(all(0.2 < float(l.split(",")[1]) < 5 for l in per_element[1:]))

        first = self.cli_json("field", job_id, "--name", "J", "--frame", "0", "--every", "50")
        self.assertEqual(first["header"]["frame"], 0)
        self.assertEqual(first["header"]["location"], "element")
        self.assertEqual(len(first["values"]), math.ceil(elements / 50))
        mid = self.cli_json("field", job_id, "--name", "hoop_stress", "--time", "10ns",
                            "--raster", "4x4")
        self.assertAlmostEqual(mid["header"]["time"], 1e-8, delta=2.6e-9)
        self.assertEqual(len(mid["values"]), 16)

        png = os.path.join(self.tmp, "vm.png")
        self.cli_ok("field", job_id, "--name", "von_mises", "--raster", "64x64", "--png", png)
        with open(png, "rb") as f:
            head = f.read(8)
        self.assertEqual(head, b"\x89PNG\r\n\x1a\n")
        self.assertGreater(os.path.getsize(png), 10_000)  # a real plot, not an empty canvas

    def test_watch_outputs_and_exit_codes(self):
        job_id = self.submit_small()
        plain = self.cli_ok("watch", job_id)
        self.assertIn("SUCCEEDED", plain.stdout)
        lines = self.cli_ok("--json", "watch", job_id).stdout.strip().splitlines()
        last = json.loads(lines[-1])
        self.assertEqual(last["state"], "SUCCEEDED")
        # Global options also work after the command.
        self.assertEqual(json.loads(self.cli_ok("status", job_id, "--json").stdout)["id"],
                         job_id)

    def test_list_and_delete(self):
        a = self.submit_small("--label", "group=a")
        b = self.submit_small("--label", "group=b")
        listing = self.cli_ok("list").stdout.splitlines()
        self.assertTrue(listing[0].startswith("ID"))
        ids = [l.split()[0] for l in listing[1:]]
        self.assertEqual(ids, [b, a])  # newest first
        only_a = self.cli_json("list", "--label", "group=a")["jobs"]
        self.assertEqual([j["id"] for j in only_a], [a])
        self.assertEqual(len(self.cli_json("list", "--state", "succeeded")["jobs"]), 2)
        self.assertEqual(self.cli_json("list", "--state", "RUNNING")["jobs"], [])
        self.assertEqual(len(self.cli_json("list", "--limit", "1")["jobs"]), 1)

        self.assertEqual(self.cli_ok("delete", a).stdout, f"deleted: {a}\n")  # not silent
        gone = self.cli("status", a)
        self.assertEqual(gone.returncode, 1)
        self.assertIn("NOT_FOUND", gone.stderr)
        self.assertEqual([j["id"] for j in self.cli_json("list")["jobs"]], [b])

    def test_spec_from_stdin_and_request_id(self):
        spec = json.dumps(small_spec(elements=300, end_time=1e-8))
        first = self.cli_ok("submit", "-", "--request-id", "rq-cli-1", input=spec).stdout.strip()
        again = self.cli_ok("submit", "-", "--request-id", "rq-cli-1", input=spec).stdout.strip()
        self.assertEqual(first, again)
        other = self.cli_ok("submit", "-", input=spec).stdout.strip()
        self.assertNotEqual(first, other)
        self.cli_ok("watch", first)
        self.cli_ok("watch", other)
        self.assertEqual(len(self.cli_json("list")["jobs"]), 2)


if __name__ == "__main__":
    unittest.main()
