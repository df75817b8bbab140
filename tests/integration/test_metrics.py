"""softshockd's Prometheus metrics (docs/api.md, "Metrics"), scraped as Prometheus would: the
metrics listener (--metrics-listen, no token) and /metrics on the dashboard's port (behind the
token), parsed strictly (prometheus_text.py), and the figures checked against what the test did:
a job submitted and run to SUCCEEDED moves the jobs-by-state gauge, the queue-wait and run-time
histograms, the element-steps counter (= the summary's elements x steps) and the RPC counts by
method and code; a rejected mesh upload counts with its bytes; disk gauges and the reserve."""

import os
import unittest
import urllib.error
import urllib.request

from prometheus_text import Metrics
from softshock_harness import DaemonTestCase, small_spec, state_name

TOKEN = "metrics-token-0123456789abcdef0123456789"
SIM = "softshock.v1.SimulationService"


def read_port(path: str) -> int:
    with open(path, encoding="utf-8") as f:
        return int(f.read().strip().rsplit(":", 1)[-1])


class MetricsTest(DaemonTestCase):
    start_daemon = False
    workers = 1

    def setUp(self):
        super().setUp()
        token_file = self.write_json(TOKEN + "\n", "token")
        self.http_port_file = os.path.join(self.tmp, "http.port")
        self.metrics_port_file = os.path.join(self.tmp, "metrics.port")
        self.daemon.extra_args += [
            "--token-file", token_file, "--min-free-bytes", "1M",
            "--http-listen", "127.0.0.1:0", "--http-port-file", self.http_port_file,
            "--metrics-listen", "127.0.0.1:0", "--metrics-port-file", self.metrics_port_file]
        self.start(health_token=TOKEN)
        self.metrics_url = f"http://127.0.0.1:{read_port(self.metrics_port_file)}/metrics"
        self.dashboard_url = f"http://127.0.0.1:{read_port(self.http_port_file)}/metrics"

    def scrape(self, url=None, token=None) -> Metrics:
        req = urllib.request.Request(url or self.metrics_url)
        if token:
            req.add_header("Authorization", "Bearer " + token)
        with urllib.request.urlopen(req, timeout=10) as r:
            self.assertEqual(r.status, 200)
            self.assertEqual(r.headers["Content-Type"],
                             "text/plain; version=0.0.4; charset=utf-8")
            return Metrics(r.read().decode("utf-8"))

    def rpcs(self, m: Metrics, method: str, code: str = "OK") -> float:
        return m.get("grpc_server_handled_total", 0.0, grpc_service=SIM, grpc_method=method,
                     grpc_type="unary", grpc_code=code)

    def test_a_finished_job_moves_the_counts(self):
        before = self.scrape()
        for state in ("QUEUED", "RUNNING", "SUCCEEDED", "FAILED", "CANCELLED"):
            self.assertEqual(before.get("softshock_jobs", state=state), 0, state)
        self.assertEqual(before.types["softshock_job_queue_wait_seconds"], "histogram")
        self.assertEqual(before.get("softshock_job_queue_wait_seconds_count"), 0)
        self.assertEqual(before.get("softshock_element_steps_total"), 0)
        self.assertEqual(self.rpcs(before, "SubmitJob"), 0)
        self.assertEqual(before.get("softshock_data_disk_reserve_bytes"), 1024 * 1024)
        total = before.get("softshock_data_disk_total_bytes")
        free = before.get("softshock_data_disk_free_bytes")
        self.assertGreater(total, 0)
        self.assertTrue(0 < free <= total, (free, total))
        self.assertEqual(before.get("softshock_workers"), 1)

        c = self.client(token=TOKEN)
        job = c.submit(small_spec(elements=400), labels={"study": "metrics"})
        done = c.wait(job.id, timeout=120)
        self.assertEqual(state_name(done), "SUCCEEDED")
        summary = c.summary(job.id)
        with self.assertRaises(Exception):
            c.get("no-such-job")

        after = self.scrape()
        self.assertEqual(after.get("softshock_jobs", state="SUCCEEDED"), 1)
        self.assertEqual(after.get("softshock_jobs", state="QUEUED"), 0)
        self.assertEqual(after.get("softshock_job_queue_wait_seconds_count"), 1)
        self.assertGreaterEqual(after.get("softshock_job_queue_wait_seconds_sum"), 0)
        self.assertEqual(after.get("softshock_job_run_seconds_count", state="SUCCEEDED"), 1)
        self.assertGreater(after.get("softshock_job_run_seconds_sum", state="SUCCEEDED"), 0)
        self.assertEqual(after.get("softshock_job_runs_finished_total", outcome="SUCCEEDED",
                                   reason="none"), 1)
        steps = int(summary["steps"]) * int(summary["elements"])
        self.assertGreater(steps, 0)
        self.assertEqual(after.get("softshock_element_steps_total"), steps)
        self.assertEqual(self.rpcs(after, "SubmitJob"), 1)
        self.assertEqual(self.rpcs(after, "GetJobSummary"), 1)
        self.assertEqual(self.rpcs(after, "GetJob", "NOT_FOUND"), 1)
        self.assertEqual(after.get("grpc_server_handling_seconds_count", grpc_service=SIM,
                                   grpc_method="SubmitJob", grpc_type="unary", grpc_code="OK"), 1)
        # This scrape's own request was counted by the one before it.
        self.assertGreaterEqual(after.get("softshock_http_requests_total", listener="metrics",
                                          route="/metrics", code="200"), 1)

    def test_a_rejected_upload_counts_with_its_bytes(self):
        garbage = b"$MeshFormat\nthis is not a mesh\n" * 20
        path = os.path.join(self.tmp, "bad.msh")
        with open(path, "wb") as f:
            f.write(garbage)
        with self.assertRaises(Exception):
            self.client(token=TOKEN).upload_mesh(path)
        m = self.scrape()
        self.assertEqual(m.get("softshock_mesh_uploads_total", outcome="rejected"), 1)
        self.assertEqual(m.get("softshock_mesh_upload_bytes_total", outcome="rejected"),
                         len(garbage))
        self.assertIsNone(m.get("softshock_mesh_uploads_total", outcome="stored"))
        self.assertEqual(m.total("grpc_server_handled_total", grpc_method="UploadMesh"), 1)

    def test_the_dashboard_port_serves_metrics_only_with_the_token(self):
        with self.assertRaises(urllib.error.HTTPError) as e:
            urllib.request.urlopen(self.dashboard_url, timeout=10)
        self.assertEqual(e.exception.code, 401)
        with self.assertRaises(urllib.error.HTTPError) as e:
            self.scrape(self.dashboard_url, token="wrong-token-0123456789abcdef012345")
        self.assertEqual(e.exception.code, 401)
        m = self.scrape(self.dashboard_url, token=TOKEN)
        self.assertIn("softshock_jobs", m.types)
        # The refused scrapes are counted by route and status on the dashboard's listener.
        self.assertEqual(m.get("softshock_http_requests_total", listener="dashboard",
                               route="/metrics", code="401"), 2)


if __name__ == "__main__":
    unittest.main()
