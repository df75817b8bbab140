"""The CLI's error contract: exit 2 for usage and invalid input (including the server's
INVALID_ARGUMENT), exit 1 for server-side failures, unknown ids and an unreachable server;
always one line on stderr, "softshock: COMMAND: message (CODE)"."""

import socket
import time
import unittest

from softshock_harness import DaemonTestCase, small_spec


def one_line(test, stderr):
    lines = stderr.strip().splitlines()
    test.assertEqual(len(lines), 1, stderr)
    return lines[0]


class CliErrorTest(DaemonTestCase):
    def assert_fails(self, code, *args, contains=(), **kw):
        p = self.cli(*args, **kw)
        self.assertEqual(p.returncode, code,
                         f"softshock {' '.join(args)}: stdout {p.stdout!r} stderr {p.stderr!r}")
        line = one_line(self, p.stderr)
        self.assertTrue(line.startswith("softshock: "), line)
        for text in contains:
            self.assertIn(text, line)
        return line

    def test_bad_specs(self):
        negative = self.write_json({"geometry": {"disk": {"radius": -9e-5}}}, "neg.json")
        line = self.assert_fails(2, "submit", negative,
                                 contains=("geometry.disk.radius", "INVALID_ARGUMENT"))
        self.assertTrue(line.startswith("softshock: submit: "), line)

        unknown = self.write_json({"geometry": {"disk": {"radius": 9e-5}}, "rnu": {}}, "unk.json")
        self.assert_fails(2, "submit", unknown, contains=("unk.json", "rnu"))
        wrong_type = self.write_json('{"run": {"endTime": "soon"}}', "type.json")
        self.assert_fails(2, "submit", wrong_type, contains=("end_time",))
        self.assert_fails(2, "submit", self.write_json("{not json", "broken.json"))
        self.assert_fails(2, "submit", self.tmp + "/missing.json", contains=("missing.json",))

        # Limits the daemon enforces are INVALID_ARGUMENT too (--max-end-time defaults to 1e-5).
        too_long = self.write_json(small_spec(end_time=1.0), "long.json")
        self.assert_fails(2, "submit", too_long, contains=("INVALID_ARGUMENT",))
        cfl = self.write_json({"run": {"cfl": 1.5}}, "cfl.json")
        self.assert_fails(2, "submit", cfl, contains=("cfl", "INVALID_ARGUMENT"))
        # Nothing was created by any of these.
        self.assertEqual(self.cli_json("list")["jobs"], [])

    def test_unknown_ids(self):
        for args in (["status", "nosuchjob"], ["summary", "nosuchjob"], ["cancel", "nosuchjob"],
                     ["delete", "nosuchjob"], ["watch", "nosuchjob"], ["series", "nosuchjob"],
                     ["modes", "nosuchjob"], ["field", "nosuchjob", "--name", "J"],
                     ["status", "jobs/nosuchjob"]):
            self.assert_fails(1, *args, contains=("NOT_FOUND",))

    def test_result_requests_on_bad_state_or_arguments(self):
        job_id = self.cli_ok("submit", self.write_json(small_spec(300, 1e-8)),
                             "--wait").stdout.split()[0]
        self.assert_fails(2, "field", job_id, "--name", "pressure", contains=("INVALID_ARGUMENT",))
        self.assert_fails(2, "series", job_id, "--name", "no_such_series",
                          contains=("INVALID_ARGUMENT",))
        # Cancelling a finished job is an illegal transition (AIP-216).
        self.assert_fails(1, "cancel", job_id, contains=("FAILED_PRECONDITION",))

    def test_usage_errors(self):
        self.assert_fails(2, "frobnicate")
        self.assert_fails(2, "status")
        self.assert_fails(2, "status", "a", "b")
        self.assert_fails(2, "submit", "x.json", "--priority", "high", contains=("--priority",))
        self.assert_fails(2, "submit", "x.json", "--label", "novalue", contains=("--label",))
        self.assert_fails(2, "list", "--limit", "-1")
        self.assert_fails(2, "list", "--state", "SLEEPING", contains=("SLEEPING",))
        self.assert_fails(2, "field", "id")  # --name missing
        self.assert_fails(2, "field", "id", "--name", "J", "--raster", "10", contains=("NXxNY",))
        self.assert_fails(2, "field", "id", "--name", "J", "--time", "1", "--frame", "2")
        self.assert_fails(2, "field", "id", "--name", "J", "--raster", "4x4", "--every", "2")
        self.assert_fails(2, "modes", "id", "--mode-min", "5", "--mode-max", "2")
        self.assert_fails(2, "--timeout", "soon", "health")
        self.assert_fails(2, "status", "id", "--bogus")
        p = self.cli("--help")
        self.assertEqual(p.returncode, 0)
        self.assertIn("submit", p.stdout)

    def test_unreachable_server(self):
        # A port nothing listens on: bind, note, close.
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            port = s.getsockname()[1]
        start = time.monotonic()
        p = self.cli("status", "x", server=f"127.0.0.1:{port}")
        self.assertEqual(p.returncode, 1)
        line = one_line(self, p.stderr)
        self.assertIn("UNAVAILABLE", line)
        self.assertIn(f"127.0.0.1:{port}", line)
        self.assertLess(time.monotonic() - start, 10)  # a few quick retries, then give up
        p = self.cli("--timeout", "2", "health", server=f"127.0.0.1:{port}")
        self.assertEqual(p.returncode, 1)


if __name__ == "__main__":
    unittest.main()
