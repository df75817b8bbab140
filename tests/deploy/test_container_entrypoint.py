"""softshockd started exactly as the image starts it: the runtime stage's ENTRYPOINT, CMD and ENV
read from deploy/Dockerfile, with only what a container run replaces swapped for local paths
(the volume, the secret) and 127.0.0.1 with an OS-chosen port instead of 0.0.0.0:50051. Then the
Dockerfile's HEALTHCHECK command, run as written, must pass."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import tempfile
import time
import unittest
from typing import Dict, List

from deploy_files import SOFTSHOCK, SOFTSHOCKD, port_of, runtime_stage

IMAGE_BINARIES = {"/usr/local/bin/softshockd": SOFTSHOCKD, "/usr/local/bin/softshock": SOFTSHOCK}


def local(argv: List[str]) -> List[str]:
    """An image command line with the image's binary paths replaced by the ones CI built."""
    return [IMAGE_BINARIES.get(a, a) for a in argv]


class ContainerEntrypointTest(unittest.TestCase):
    def setUp(self):
        self.stage = runtime_stage()
        self.image_env = self.stage.env()
        self.tmp = tempfile.mkdtemp(prefix="softshock-entrypoint-")
        self.token = "entrypoint-test-" + os.urandom(8).hex()
        self.token_file = os.path.join(self.tmp, "softshock_token")  # the mounted secret
        with open(self.token_file, "w", encoding="utf-8") as f:
            f.write(self.token + "\n")
        os.chmod(self.token_file, 0o600)  # softshockd refuses one other users may read
        self.data_dir = os.path.join(self.tmp, "volume")  # the named volume
        self.proc = None

    def tearDown(self):
        if self.proc is not None and self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait(timeout=30)
        if os.environ.get("SOFTSHOCK_KEEP_TMP") != "1":
            shutil.rmtree(self.tmp, ignore_errors=True)

    def environment(self, **overrides: str) -> Dict[str, str]:
        """The process environment as in the container: no SOFTSHOCK_* of the caller's, the
        image's ENV, then what this run replaces."""
        env = {k: v for k, v in os.environ.items() if not k.startswith("SOFTSHOCK")}
        env.update(self.image_env)
        env.update(overrides)
        return env

    def entrypoint(self) -> List[str]:
        return local(self.stage.exec_form("ENTRYPOINT") + self.stage.exec_form("CMD"))

    def run_refused(self, env: Dict[str, str]) -> subprocess.CompletedProcess:
        return subprocess.run(self.entrypoint(), env=env, capture_output=True, text=True,
                              timeout=60)

    def test_starts_as_the_image_does_and_passes_the_healthcheck(self):
        port_file = os.path.join(self.tmp, "port")
        env = self.environment(SOFTSHOCK_DATA_DIR=self.data_dir,
                               SOFTSHOCK_TOKEN_FILE=self.token_file,
                               SOFTSHOCK_LISTEN="127.0.0.1:0",
                               SOFTSHOCK_PORT_FILE=port_file)
        log_path = os.path.join(self.tmp, "softshockd.log")
        with open(log_path, "wb") as log:
            self.proc = subprocess.Popen(self.entrypoint(), env=env, stdout=log,
                                         stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)
        deadline = time.monotonic() + 60
        while not os.path.exists(port_file):
            self.assertIsNone(self.proc.poll(), open(log_path, encoding="utf-8").read())
            self.assertLess(time.monotonic(), deadline, "no port file")
            time.sleep(0.05)
        with open(port_file, encoding="utf-8") as f:
            port = int(f.read())

        # The HEALTHCHECK exactly as written, but aimed at the port chosen here; retried within
        # its own start period, as the container engine would.
        options, command = self.stage.healthcheck()
        command = local(command)
        server = command.index("--server") + 1
        self.assertEqual(port_of(command[server]), port_of(self.image_env["SOFTSHOCK_LISTEN"]))
        command[server] = f"127.0.0.1:{port}"
        deadline = time.monotonic() + float(options["start-period"].rstrip("s"))
        while True:
            check = subprocess.run(command, env=self.environment(), capture_output=True,
                                   text=True, timeout=float(options["timeout"].rstrip("s")))
            if check.returncode == 0 or time.monotonic() > deadline:
                break
            time.sleep(0.2)
        self.assertEqual(check.returncode, 0, check.stdout + check.stderr)
        self.assertIn("SERVING", check.stdout)

        # The token from the secret is in force; health needed none.
        client = [SOFTSHOCK, "--server", f"127.0.0.1:{port}", "--timeout", "10"]
        denied = subprocess.run(client + ["list"], env=self.environment(), capture_output=True,
                                text=True, timeout=30)
        self.assertNotEqual(denied.returncode, 0)
        self.assertIn("UNAUTHENTICATED", denied.stdout + denied.stderr)
        allowed = subprocess.run(client + ["--token-file", self.token_file, "list"],
                                 env=self.environment(), capture_output=True, text=True,
                                 timeout=30)
        self.assertEqual(allowed.returncode, 0, allowed.stdout + allowed.stderr)

        # `podman stop` / `docker stop` send SIGTERM: a clean exit.
        self.proc.send_signal(signal.SIGTERM)
        self.assertEqual(self.proc.wait(timeout=30), 0)
        with open(log_path, encoding="utf-8") as f:
            log = f.read()
        # The effective configuration is logged with its sources, the token never.
        self.assertIn(f"token-file={self.token_file} [env SOFTSHOCK_TOKEN_FILE]", log)
        self.assertIn(f"data-dir={self.data_dir} [env SOFTSHOCK_DATA_DIR]", log)
        self.assertNotIn(self.token, log)
        self.assertTrue(os.path.exists(os.path.join(self.data_dir, "catalogue.sqlite")))

    def test_refuses_the_image_address_without_a_token(self):
        # The image's own 0.0.0.0:50051 with the secret's variable cleared: refused before
        # anything is bound.
        r = self.run_refused(self.environment(SOFTSHOCK_DATA_DIR=self.data_dir,
                                              SOFTSHOCK_TOKEN_FILE=""))
        self.assertEqual(r.returncode, 2, r.stderr)
        self.assertIn("refusing to listen on 0.0.0.0:50051", r.stderr)
        self.assertIn("[listen from env SOFTSHOCK_LISTEN]", r.stderr)
        self.assertFalse(os.path.exists(self.data_dir))

    def test_missing_secret_stops_the_start(self):
        # No secret mounted at the image's token path: exit 1, nothing served.
        missing = os.path.join(self.tmp, "not-mounted", "softshock_token")
        r = self.run_refused(self.environment(SOFTSHOCK_DATA_DIR=self.data_dir,
                                              SOFTSHOCK_LISTEN="127.0.0.1:0",
                                              SOFTSHOCK_TOKEN_FILE=missing))
        self.assertEqual(r.returncode, 1, r.stderr)
        self.assertIn(missing, r.stderr)

    def test_invalid_settings_exit_2_naming_key_and_source(self):
        env = self.environment(SOFTSHOCK_DATA_DIR=self.data_dir, SOFTSHOCK_WORKERS="many")
        r = self.run_refused(env)
        self.assertEqual(r.returncode, 2)
        self.assertIn("workers = 'many' (env SOFTSHOCK_WORKERS)", r.stderr)
        config = os.path.join(self.tmp, "softshockd.conf")
        with open(config, "w", encoding="utf-8") as f:
            f.write("# settings\nmax-wall-time = -5\n")
        r = self.run_refused(self.environment(SOFTSHOCK_DATA_DIR=self.data_dir,
                                              SOFTSHOCK_CONFIG=config))
        self.assertEqual(r.returncode, 2)
        self.assertIn(f"max-wall-time = '-5' (file {config}:2)", r.stderr)


if __name__ == "__main__":
    unittest.main()
