"""Crash safety: softshockd killed with SIGKILL mid-run and restarted on the same data dir.
The interrupted job runs again (attempt 2) and completes; a job that had finished before the
crash keeps its summary and its result file byte for byte."""

import hashlib
import os
import subprocess
import time
import unittest

from softshock_harness import (SOFTSHOCK, DaemonTestCase, long_spec, small_spec,
                               state_name)


def sha256(path):
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


class RestartTest(DaemonTestCase):
    def test_kill9_mid_run_then_restart(self):
        c = self.client()
        done = c.submit(small_spec(), labels={"phase": "before"}, wait=True)
        self.assertEqual(state_name(done), "SUCCEEDED")
        summary_before = c.summary(done.id)
        result_path = c.get(done.id).result_path
        self.assertEqual(result_path, f"jobs/{done.id}/result.h5", "relative to the data folder")
        result = os.path.join(self.daemon.data_dir, result_path)
        self.assertTrue(os.path.isfile(result), result)
        digest_before = sha256(result)
        cli_summary_before = self.cli_ok("summary", done.id).stdout

        victim = c.submit(long_spec(), labels={"phase": "victim"})
        queued_small = c.submit(small_spec(300, 1e-8), labels={"phase": "queued"}, priority=-1)
        self.wait_running(c, victim.id, min_fraction=0.05)
        c.close()

        self.daemon.kill9()

        # A watcher started now sees the daemon gone, keeps retrying, and follows the job to
        # its end once the daemon is back (watch tolerates restarts).
        watcher = subprocess.Popen([SOFTSHOCK, "--server", self.daemon.address, "--timeout", "4",
                                    "watch", victim.id], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                   text=True)
        time.sleep(0.5)
        old_address = self.daemon.address
        self.daemon.start()  # same data dir, new port
        c = self.client()

        after = c.get(victim.id)
        self.assertIn(state_name(after), ("QUEUED", "RUNNING", "SUCCEEDED"))
        final = c.wait(victim.id, timeout=120)
        self.assertEqual(state_name(final), "SUCCEEDED", f"{final.reason}: {final.error}")
        self.assertEqual(final.attempt, 2)
        self.assertAlmostEqual(final.progress.fraction, 1.0, places=6)
        self.assertTrue(os.path.isfile(os.path.join(self.daemon.data_dir, final.result_path)))
        self.assertEqual(state_name(c.wait(queued_small.id, timeout=60)), "SUCCEEDED")

        # The finished job is untouched.
        self.assertEqual(c.summary(done.id), summary_before)
        self.assertEqual(sha256(result), digest_before)
        self.assertEqual(c.get(done.id).attempt, 1)
        self.assertEqual(self.cli_ok("summary", done.id).stdout, cli_summary_before)
        # No result file is left half-written anywhere in the data dir.
        for root, _, files in os.walk(self.data_dir):
            for name in files:
                self.assertFalse(name.endswith(".tmp"), os.path.join(root, name))

        # The watcher pointed at the old port: it cannot find the new daemon, so it must give
        # up with exit 1 rather than hang (its patience is --timeout, 4 s) — unless the OS
        # reused the port. Either way it must not report success for a job it did not see finish.
        out, err = watcher.communicate(timeout=60)
        if self.daemon.address != old_address:
            self.assertEqual(watcher.returncode, 1, out + err)
            self.assertIn("UNAVAILABLE", err)

    def test_watch_survives_restart_on_same_port(self):
        # A supervisor restarts the daemon on its fixed port; `softshock watch` reconnects.
        c = self.client()
        job = c.submit(long_spec())
        self.wait_running(c, job.id, min_fraction=0.05)
        c.close()
        port = self.daemon.port
        watcher = subprocess.Popen([SOFTSHOCK, "--server", self.daemon.address, "watch", job.id],
                                   stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        time.sleep(0.5)
        self.daemon.kill9()
        time.sleep(0.5)
        listen = f"127.0.0.1:{port}"
        # Restart on the same port: --listen given twice, the last one wins in softshockd's
        # flag parser; the port file still reports it.
        self.daemon.extra_args += ["--listen", listen]
        self.daemon.start()
        self.assertEqual(self.daemon.port, port)
        out, err = watcher.communicate(timeout=120)
        self.assertEqual(watcher.returncode, 0, out + err)
        self.assertIn("SUCCEEDED", out.strip().splitlines()[-1])
        self.assertIn("reconnecting", err)


if __name__ == "__main__":
    unittest.main()
