"""Bearer-token authentication (--token-file) and TLS (--tls-cert/--tls-key) end to end."""

import os
import shutil
import subprocess
import unittest

import grpc

from softshock_harness import DaemonTestCase, SoftshockError, small_spec, state_name

TOKEN = "s3cret-token-for-tests-0123456789abcdef"  # softshockd wants >= 32 bytes


class TokenTest(DaemonTestCase):
    start_daemon = False

    def setUp(self):
        super().setUp()
        self.token_file = self.write_json(TOKEN + "\n", "token")  # trailing newline, as editors save
        self.daemon.extra_args += ["--token-file", self.token_file]
        self.start(health_token=TOKEN)

    def test_token_required(self):
        spec = self.write_json(small_spec(300, 1e-8))
        p = self.cli("submit", spec)
        self.assertEqual(p.returncode, 1, p.stderr)
        self.assertIn("UNAUTHENTICATED", p.stderr)
        self.assertEqual(len(p.stderr.strip().splitlines()), 1)

        wrong = self.write_json("not-the-token", "wrong")
        p = self.cli("--token-file", wrong, "list")
        self.assertEqual(p.returncode, 1)
        self.assertIn("UNAUTHENTICATED", p.stderr)

        job_id = self.cli_ok("--token-file", self.token_file, "submit", spec,
                             "--wait").stdout.split()[0]
        self.assertEqual(self.cli_json("--token-file", self.token_file, "status", job_id)["state"],
                         "SUCCEEDED")
        p = self.cli("status", job_id)  # no token: the job exists but is not shown
        self.assertEqual(p.returncode, 1)
        self.assertIn("UNAUTHENTICATED", p.stderr)

        with self.assertRaises(SoftshockError) as e:
            self.client().list()
        self.assertEqual(e.exception.code, grpc.StatusCode.UNAUTHENTICATED)
        with self.assertRaises(SoftshockError) as e:
            self.client(token="wrong").get(job_id)
        self.assertEqual(e.exception.code, grpc.StatusCode.UNAUTHENTICATED)
        good = self.client(token=TOKEN)
        self.assertEqual(state_name(good.get(job_id)), "SUCCEEDED")
        self.assertEqual(len(good.list()), 1)

        # Health stays open without a token, as load balancers and kubelet probes send none.
        self.assertEqual(self.cli("health").returncode, 0)
        # On loopback a token without TLS is fine: nothing to warn about.
        self.assertEqual(self.client().health_warnings(), [])
        self.assertNotIn("warning", self.cli_ok("health").stdout)

    def test_mesh_service_needs_the_token(self):
        msh = self.write_json("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n3\n1 0 0 0\n"
                              "2 1e-4 0 0\n3 0 1e-4 0\n$EndNodes\n$Elements\n1\n"
                              "1 2 2 0 1 1 2 3\n$EndElements\n", "tri.msh")
        for args in (["mesh", "upload", msh], ["mesh", "list"], ["mesh", "delete", "x" * 64]):
            p = self.cli(*args)
            self.assertEqual(p.returncode, 1, args)
            self.assertIn("UNAUTHENTICATED", p.stderr)
        with self.assertRaises(SoftshockError) as e:
            self.client().upload_mesh(msh)
        self.assertEqual(e.exception.code, grpc.StatusCode.UNAUTHENTICATED)
        mesh_id = self.cli_ok("--token-file", self.token_file, "mesh", "upload", msh).stdout
        self.assertEqual([m.id for m in self.client(token=TOKEN).list_meshes()], [mesh_id.strip()])

    def test_empty_token_file_is_a_usage_error(self):
        empty = self.write_json("", "empty")
        p = self.cli("--token-file", empty, "list")
        self.assertEqual(p.returncode, 2)


class TokenOffLoopbackTest(DaemonTestCase):
    """A token served without TLS on every interface: the start-up warning is also in every
    health answer, for whoever checks the daemon later."""
    start_daemon = False

    def setUp(self):
        super().setUp()
        token_file = self.write_json(TOKEN, "token")
        self.daemon.extra_args += ["--token-file", token_file, "--listen", "0.0.0.0:0"]
        self.start(health_token=TOKEN)

    def test_health_carries_the_tls_warning(self):
        warnings = self.client().health_warnings()
        self.assertEqual(len(warnings), 1, warnings)
        self.assertIn("serving 0.0.0.0:0 with a bearer token but without TLS", warnings[0])
        out = self.cli_ok("health").stdout
        self.assertIn("status:", out)
        self.assertIn("warning:", out)
        self.assertIn("without TLS", out)
        self.assertEqual(self.cli_json("health"), {"status": "SERVING", "warnings": warnings})
        self.assertIn("without TLS", self.daemon.log_tail())  # still logged at start-up too


def make_certificates(directory):
    """A throw-away CA and a server certificate for 127.0.0.1 (and localhost)."""
    def run(*args):
        subprocess.run(["openssl", *args], cwd=directory, check=True, capture_output=True)
    run("req", "-x509", "-newkey", "rsa:2048", "-nodes", "-days", "2", "-subj",
        "/CN=softshock test CA", "-keyout", "ca.key", "-out", "ca.pem")
    run("req", "-newkey", "rsa:2048", "-nodes", "-subj", "/CN=127.0.0.1", "-keyout",
        "server.key", "-out", "server.csr")
    with open(os.path.join(directory, "ext.cnf"), "w") as f:
        f.write("subjectAltName=IP:127.0.0.1,DNS:localhost\n")
    run("x509", "-req", "-in", "server.csr", "-CA", "ca.pem", "-CAkey", "ca.key",
        "-CAcreateserial", "-days", "2", "-extfile", "ext.cnf", "-out", "server.pem")
    return tuple(os.path.join(directory, n) for n in ("ca.pem", "server.pem", "server.key"))


@unittest.skipIf(shutil.which("openssl") is None, "openssl is needed to make certificates")
class TlsTest(DaemonTestCase):
    start_daemon = False

    def setUp(self):
        super().setUp()
        self.ca, cert, key = make_certificates(self.tmp)
        self.token_file = self.write_json(TOKEN, "token")
        self.daemon.extra_args += ["--tls-cert", cert, "--tls-key", key,
                                   "--token-file", self.token_file]
        self.start(health_token=TOKEN, tls_ca=self.ca)

    def test_tls_with_token(self):
        spec = self.write_json(small_spec(300, 1e-8))
        job_id = self.cli_ok("--tls-ca", self.ca, "--token-file", self.token_file, "submit",
                             spec, "--wait").stdout.split()[0]
        self.assertEqual(self.cli_json("--tls-ca", self.ca, "--token-file", self.token_file,
                                       "summary", job_id)["id"], job_id)
        with self.client(tls_ca=self.ca, token=TOKEN) as c:
            self.assertEqual(state_name(c.get(job_id)), "SUCCEEDED")
            self.assertEqual(c.field(job_id, "J", raster=(8, 8)).values.shape, (8, 8))

        # Plaintext against a TLS port fails (exit 1), and so does an unknown CA.
        p = self.cli("--timeout", "3", "--token-file", self.token_file, "status", job_id)
        self.assertEqual(p.returncode, 1)
        self.assertIn("UNAVAILABLE", p.stderr)
        other = os.path.join(self.tmp, "other")
        os.makedirs(other)
        other_ca, _, _ = make_certificates(other)
        p = self.cli("--timeout", "3", "--tls-ca", other_ca, "--token-file", self.token_file,
                     "status", job_id)
        self.assertEqual(p.returncode, 1)
        self.assertIn("UNAVAILABLE", p.stderr)


if __name__ == "__main__":
    unittest.main()
