"""Shared fixtures of the end-to-end tests: a real softshockd on loopback, the real `softshock`
CLI, the Python client, and small run specs.

Environment (set by tests/CMakeLists.txt): SOFTSHOCKD and SOFTSHOCK (binary paths), PYTHONPATH
(build/python, client/python, tests/integration). SOFTSHOCK_KEEP_TMP=1 keeps each test's data
directory and daemon log for inspection.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import unittest
from typing import Optional, Sequence

from softshock_client import Client, SoftshockError, state_name  # noqa: F401  (re-exported)

SOFTSHOCKD = os.environ.get("SOFTSHOCKD", "softshockd")
SOFTSHOCK = os.environ.get("SOFTSHOCK", "softshock")

TERMINAL = {"SUCCEEDED", "FAILED", "CANCELLED"}


def small_spec(elements: int = 400, end_time: float = 2e-8, **run) -> dict:
    """A run that finishes in a fraction of a second: a 90 µm disk, a few hundred elements."""
    spec = {
        "geometry": {"disk": {"radius": 9e-5}, "targetElements": elements},
        "run": {"endTime": end_time, "outputInterval": 5e-9, "historyInterval": 1e-9},
    }
    spec["run"].update(run)
    return spec


def long_spec(elements: int = 16500, end_time: float = 6e-7) -> dict:
    """A run that stays RUNNING for seconds, for the cancel and crash tests: the baseline mesh
    over 600 ns (measured here: ~10,900 steps, ~5 s on one core). Smaller meshes finish too
    soon to be caught reliably (8000 elements / 600 ns: 1.8 s; 4000 / 300 ns: under 1 s)."""
    return {
        "geometry": {"disk": {"radius": 9e-5}, "targetElements": elements},
        "run": {"endTime": end_time, "outputInterval": 5e-8, "historyInterval": 2e-9},
    }


class Daemon:
    """softshockd as a child process: --listen 127.0.0.1:0 with a port file, like a user would
    run it under a supervisor. Several may share one data dir in turn (restart tests)."""

    def __init__(self, data_dir: str, log_path: str, extra_args: Sequence[str] = (),
                 workers: int = 2):
        self.data_dir = data_dir
        self.log_path = log_path
        self.extra_args = list(extra_args)
        self.workers = workers
        self.proc: Optional[subprocess.Popen] = None
        self.port: Optional[int] = None
        self.starts = 0

    @property
    def address(self) -> str:
        return f"127.0.0.1:{self.port}"

    def start(self, timeout: float = 30.0, health_token: Optional[str] = None,
              tls_ca: Optional[str] = None) -> None:
        port_file = os.path.join(self.data_dir, "port")
        if os.path.exists(port_file):
            os.unlink(port_file)  # a stale file from the previous run would point nowhere
        os.makedirs(self.data_dir, exist_ok=True)
        self.starts += 1
        log = open(self.log_path, "ab")
        log.write(f"\n===== start #{self.starts} =====\n".encode())
        log.flush()
        cmd = [SOFTSHOCKD, "--data-dir", self.data_dir, "--listen", "127.0.0.1:0",
               "--port-file", port_file, "--workers", str(self.workers)] + self.extra_args
        self.proc = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT,
                                     stdin=subprocess.DEVNULL)
        log.close()
        deadline = time.monotonic() + timeout
        while True:
            if self.proc.poll() is not None:
                raise RuntimeError(f"softshockd exited with {self.proc.returncode} at start-up:\n"
                                   + self.log_tail())
            text = ""
            try:
                with open(port_file, encoding="utf-8") as f:
                    text = f.read().strip()
            except FileNotFoundError:
                pass
            if text:
                # Accept "PORT" or "HOST:PORT".
                try:
                    self.port = int(text.rsplit(":", 1)[-1])
                    break
                except ValueError:
                    pass  # half-written; read again
            if time.monotonic() > deadline:
                raise RuntimeError("softshockd wrote no port file:\n" + self.log_tail())
            time.sleep(0.02)
        # Listening is not the same as ready: wait until the health service says SERVING.
        with Client(self.address, token=health_token, tls_ca=tls_ca, timeout=2) as c:
            while True:
                try:
                    if c.health() == "SERVING":
                        return
                except SoftshockError:
                    pass
                if self.proc.poll() is not None or time.monotonic() > deadline:
                    raise RuntimeError("softshockd never reported SERVING:\n" + self.log_tail())
                time.sleep(0.05)

    def kill9(self) -> None:
        assert self.proc is not None
        self.proc.send_signal(signal.SIGKILL)
        self.proc.wait(timeout=30)

    def stop(self, timeout: float = 30.0) -> Optional[int]:
        """SIGTERM, then SIGKILL after `timeout` s; returns the exit status (None if killed)."""
        if self.proc is None or self.proc.poll() is not None:
            return None if self.proc is None else self.proc.returncode
        self.proc.send_signal(signal.SIGTERM)
        try:
            return self.proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait(timeout=30)
            return None

    def log_tail(self, lines: int = 60) -> str:
        try:
            with open(self.log_path, encoding="utf-8", errors="replace") as f:
                return "".join(f.readlines()[-lines:])
        except OSError:
            return "(no log)"


class DaemonTestCase(unittest.TestCase):
    """Each test gets a fresh data dir and daemon; the daemon must stop cleanly on SIGTERM."""

    daemon_args: Sequence[str] = ()
    workers = 2
    start_daemon = True

    def setUp(self) -> None:
        self.tmp = tempfile.mkdtemp(prefix="softshock-it-")
        self.data_dir = os.path.join(self.tmp, "data")
        self.daemon = Daemon(self.data_dir, os.path.join(self.tmp, "softshockd.log"),
                             self.extra_daemon_args(), workers=self.workers)
        self.addCleanup(self._cleanup)
        if self.start_daemon:
            self.start()

    def extra_daemon_args(self) -> Sequence[str]:
        return list(self.daemon_args)

    def start(self, **kw) -> None:
        self.daemon.start(**kw)

    def _cleanup(self) -> None:
        rc = self.daemon.stop()
        self._log = self.daemon.log_tail(80)
        if os.environ.get("SOFTSHOCK_KEEP_TMP") == "1":
            print(f"\n[kept {self.tmp}]", file=sys.stderr)
        else:
            shutil.rmtree(self.tmp, ignore_errors=True)
        if rc not in (0, None) and self.daemon.proc is not None and self.daemon.starts:
            # SIGKILLed daemons (restart tests) report -9 before the final stop; only the
            # SIGTERM we just sent is judged here.
            if rc != -signal.SIGKILL:
                self.fail(f"softshockd exited with {rc} after SIGTERM:\n{self._log}")

    def run(self, result=None):
        # On failure, show the daemon's log: most end-to-end failures are explained there.
        result = result if result is not None else self.defaultTestResult()
        before = len(result.failures) + len(result.errors)
        super().run(result)
        if len(result.failures) + len(result.errors) > before:
            print(f"\n----- softshockd log ({self.id()}) -----\n{getattr(self, '_log', '')}",
                  file=sys.stderr)
        return result

    # -- helpers -------------------------------------------------------------------------------
    def write_json(self, obj, name: str = "spec.json") -> str:
        path = os.path.join(self.tmp, name)
        # 0600: softshockd refuses a token file other users may read.
        with open(os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600), "w",
                  encoding="utf-8") as f:
            if isinstance(obj, str):
                f.write(obj)
            else:
                json.dump(obj, f)
        return path

    def cli(self, *args: str, server: Optional[str] = None, timeout: float = 120,
            input: Optional[str] = None) -> subprocess.CompletedProcess:
        cmd = [SOFTSHOCK, "--server", server or self.daemon.address] + list(args)
        return subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, input=input)

    def cli_ok(self, *args: str, **kw) -> subprocess.CompletedProcess:
        p = self.cli(*args, **kw)
        self.assertEqual(p.returncode, 0, f"softshock {' '.join(args)} failed:\n"
                         f"stdout: {p.stdout[-2000:]}\nstderr: {p.stderr[-2000:]}")
        return p

    def cli_json(self, *args: str, **kw):
        return json.loads(self.cli_ok("--json", *args, **kw).stdout)

    def client(self, **kw) -> Client:
        c = Client(self.daemon.address, **kw)
        self.addCleanup(c.close)
        return c

    def wait_for(self, predicate, timeout: float, interval: float = 0.05, what: str = "condition"):
        deadline = time.monotonic() + timeout
        while True:
            value = predicate()
            if value:
                return value
            if time.monotonic() > deadline:
                self.fail(f"timed out after {timeout} s waiting for {what}")
            time.sleep(interval)

    def wait_running(self, c: Client, job_id: str, timeout: float = 60.0,
                     min_fraction: float = 0.0):
        def running():
            job = c.get(job_id)
            if state_name(job) in TERMINAL:
                self.fail(f"job {job_id} ended ({state_name(job)}) before it could be caught "
                          f"RUNNING; the long spec is too short for this machine")
            return job if (state_name(job) == "RUNNING" and
                           job.progress.fraction > min_fraction) else None
        return self.wait_for(running, timeout, what=f"{job_id} RUNNING")
