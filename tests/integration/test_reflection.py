"""softshockd driven through server reflection alone, as grpcurl or `buf curl` would: a client
process with no softshock stubs (reflection_client.py) lists the services, describes them, checks
health, and submits, watches and reads a job by its resource name (AIP-131 `name`)."""

import json
import os
import subprocess
import sys

from softshock_harness import DaemonTestCase, small_spec

HERE = os.path.dirname(os.path.abspath(__file__))


class ReflectionTest(DaemonTestCase):
    def generic(self, *args):
        # A clean environment: nothing of softshock on the path, only Debian's grpcio/protobuf.
        env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
        return subprocess.run([sys.executable, os.path.join(HERE, "reflection_client.py"),
                               self.daemon.address] + list(args),
                              capture_output=True, text=True, timeout=120, env=env)

    def generic_ok(self, *args):
        r = self.generic(*args)
        self.assertEqual(r.returncode, 0, f"{args}: {r.stderr}")
        return [json.loads(line) if line.startswith("{") else line
                for line in r.stdout.splitlines()]

    def test_health_is_described_and_callable(self):
        services = self.generic_ok("list")
        for s in ("softshock.v1.SimulationService", "grpc.health.v1.Health",
                  "grpc.reflection.v1alpha.ServerReflection"):
            self.assertIn(s, services)
        methods = self.generic_ok("describe", "grpc.health.v1.Health")
        self.assertTrue(any(m.startswith("Check(grpc.health.v1.HealthCheckRequest)")
                            for m in methods), methods)
        self.assertEqual(self.generic_ok("call", "grpc.health.v1.Health/Check", "{}"),
                         [{"status": "SERVING"}])

    def test_job_by_resource_name(self):
        job = self.generic_ok("call", "softshock.v1.SimulationService/SubmitJob",
                              json.dumps({"spec": small_spec()}))[0]
        name = job["name"]
        self.assertTrue(name.startswith("jobs/"), name)
        states = [m["state"] for m in self.generic_ok(
            "call", "softshock.v1.SimulationService/WatchJob", json.dumps({"name": name}))]
        self.assertEqual(states[-1], "SUCCEEDED")
        got = self.generic_ok("call", "softshock.v1.SimulationService/GetJob",
                              json.dumps({"name": name}))[0]
        self.assertEqual((got["name"], got["state"]), (name, "SUCCEEDED"))
        # `id` stays an alias, bare or full.
        by_id = self.generic_ok("call", "softshock.v1.SimulationService/GetJob",
                                json.dumps({"id": job["id"]}))[0]
        self.assertEqual(by_id["name"], name)
        summary = self.generic_ok("call", "softshock.v1.SimulationService/GetJobSummary",
                                  json.dumps({"name": name}))[0]
        self.assertGreater(int(summary["steps"]), 0)
        field = self.generic_ok("call", "softshock.v1.SimulationService/GetField",
                                json.dumps({"job": name, "name": "J", "every": 50}))
        self.assertEqual(field[0]["header"]["name"], "J")

        r = self.generic("call", "softshock.v1.SimulationService/GetJob",
                         json.dumps({"name": "grids/" + job["id"]}))
        self.assertEqual(r.returncode, 1)
        self.assertIn("INVALID_ARGUMENT: name: 'grids/", r.stderr)
        r = self.generic("call", "softshock.v1.SimulationService/GetJob",
                         json.dumps({"name": name, "id": "other"}))
        self.assertIn("INVALID_ARGUMENT: name:", r.stderr)
        self.assertIn("name different jobs", r.stderr)
