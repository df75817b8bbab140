"""Cancelling jobs: a running one stops within about a second; a queued one never runs."""

import subprocess
import time
import unittest

from softshock_harness import SOFTSHOCK, DaemonTestCase, long_spec, small_spec, state_name


class CancelTest(DaemonTestCase):
    workers = 1  # one runner: the second job is guaranteed to wait in the queue

    def test_cancel_running_and_queued(self):
        c = self.client()
        running = c.submit(long_spec(), labels={"t": "cancel"})
        queued = c.submit(long_spec(), labels={"t": "cancel"})
        self.wait_running(c, running.id, min_fraction=0.02)
        self.assertEqual(state_name(c.get(queued.id)), "QUEUED")

        # The queued job is cancelled at once and never starts (cancelled first: once the
        # runner is free it would start).
        q = c.cancel(queued.id)
        self.assertEqual(state_name(q), "CANCELLED")
        self.assertEqual(q.reason, "CANCELLED_BY_USER")
        self.assertFalse(q.HasField("start_time"))

        # Cancel through the CLI; it returns the job as it is after the request.
        start = time.monotonic()
        out = self.cli_ok("cancel", running.id).stdout
        self.assertIn("state:", out)

        def cancelled():
            job = c.get(running.id)
            return job if state_name(job) == "CANCELLED" else None
        job = self.wait_for(cancelled, timeout=5.0, interval=0.02, what="CANCELLED")
        elapsed = time.monotonic() - start
        self.assertLess(elapsed, 1.5, f"cancel took {elapsed:.2f} s")
        self.assertEqual(job.reason, "CANCELLED_BY_USER")
        self.assertLess(job.progress.fraction, 1.0)
        self.assertTrue(job.HasField("finish_time"))

        # Terminal states never change; cancelling again is an illegal transition.
        again = self.cli("cancel", running.id)
        self.assertEqual(again.returncode, 1)
        self.assertIn("FAILED_PRECONDITION", again.stderr)

        # `watch` of a cancelled job ends at once with exit 1 and says how it ended.
        w = self.cli("watch", running.id, timeout=30)
        self.assertEqual(w.returncode, 1)
        self.assertIn("CANCELLED", w.stderr)

        # The runner is free again: a new job runs to completion.
        done = c.submit(small_spec(elements=300, end_time=1e-8), wait=True)
        self.assertEqual(state_name(done), "SUCCEEDED")
        self.assertEqual(state_name(c.get(running.id)), "CANCELLED")
        self.assertFalse(c.get(queued.id).HasField("start_time"))
        self.assertEqual(sorted(state_name(j) for j in c.list(label="t=cancel")),
                         ["CANCELLED", "CANCELLED"])

    def test_cancel_while_watching(self):
        # A watcher sees the cancellation as the final state and exits 1.
        c = self.client()
        job = c.submit(long_spec())
        self.wait_running(c, job.id)
        watcher = subprocess.Popen([SOFTSHOCK, "--server", self.daemon.address, "watch", job.id],
                                   stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        time.sleep(0.3)
        c.cancel(job.id)
        out, err = watcher.communicate(timeout=20)
        self.assertEqual(watcher.returncode, 1, err)
        self.assertIn("CANCELLED", out.strip().splitlines()[-1])


if __name__ == "__main__":
    unittest.main()
