"""A finished job continued to a later end time (ExtendJob, `softshock extend`, Client.extend;
issue 35, item 5), against a real daemon: the extension starts from the state where its parent
stopped (no step recomputed), links to it by parent_id, and its result is bitwise, dataset by
dataset, the one a job run straight to the later end time writes; refusals name the rule."""

import os
import re
import subprocess
import sys
import unittest

from softshock_harness import DaemonTestCase, SoftshockError, small_spec, state_name


def compare(a: str, b: str) -> subprocess.CompletedProcess:
    script = os.path.join(os.environ["SOFTSHOCK_SOURCE_DIR"], "scripts", "compare_results.py")
    return subprocess.run([sys.executable, script, a, b], capture_output=True, text=True)


class ExtendTest(DaemonTestCase):
    def result(self, job) -> str:
        return os.path.join(self.data_dir, job.result_path)

    def test_an_extension_equals_the_longer_run_and_starts_where_the_parent_stopped(self):
        c = self.client(timeout=30)
        # 40 ns, on the output (5 ns) and history (1 ns) schedule; then to 80 ns.
        parent = c.submit(small_spec(600, 4e-8), wait=True)
        self.assertEqual(state_name(parent), "SUCCEEDED")
        self.assertTrue(os.path.exists(os.path.join(self.data_dir, "jobs", parent.id,
                                                     "final_state.ckpt")))
        parent_steps = int(c.summary(parent.id)["steps"])

        out = self.cli_ok("extend", parent.id, "--end-time", "8e-8", "--label", "stage=2",
                          "--wait").stdout
        child_id = out.split()[0]
        child = c.get(child_id)
        self.assertEqual(state_name(child), "SUCCEEDED")
        self.assertEqual(child.parent_id, parent.id)
        self.assertEqual(child.labels.get("stage"), "2")
        log = self.daemon.log_tail(400)
        self.assertRegex(log, rf"job {child_id} continues job {parent.id} from its final state "
                              rf"at t = 4e-08 s, step {parent_steps}")

        straight = c.submit(small_spec(600, 8e-8), wait=True)
        self.assertEqual(state_name(straight), "SUCCEEDED")
        self.assertEqual(int(c.summary(child_id)["steps"]), int(c.summary(straight.id)["steps"]))
        same = compare(self.result(straight), self.result(child))
        self.assertEqual(same.returncode, 0, same.stdout + same.stderr)
        # The extension's checkpoint folder (and its link to the parent's frames) is gone; the
        # parent's result is intact.
        self.assertFalse(os.path.exists(os.path.join(self.data_dir, "jobs", child_id,
                                                     "checkpoint")))
        self.assertEqual(compare(self.result(parent), self.result(parent)).returncode, 0)

        # The Python client, and an extension of an extension.
        grandchild = c.extend(child_id, 1e-7, wait=True)
        self.assertEqual(state_name(grandchild), "SUCCEEDED")
        self.assertEqual(grandchild.parent_id, child_id)
        self.assertIn(f"job {grandchild.id} continues job {child_id}", self.daemon.log_tail(400))

    def test_refusals(self):
        c = self.client(timeout=30)
        parent = c.submit(small_spec(300, 2e-8), wait=True)
        with self.assertRaises(SoftshockError) as e:
            c.extend(parent.id, 1e-8)
        self.assertEqual(e.exception.code.name, "INVALID_ARGUMENT")
        self.assertIn("end_time", str(e.exception))
        with self.assertRaises(SoftshockError) as e:
            c.extend("0123456789abcdef", 1e-7)
        self.assertEqual(e.exception.code.name, "NOT_FOUND")
        cli = self.cli("extend", parent.id)
        self.assertNotEqual(cli.returncode, 0)
        self.assertIn("--end-time", cli.stderr)
        # A parent that kept no state (here: removed) is extended from t = 0, and says why.
        os.remove(os.path.join(self.data_dir, "jobs", parent.id, "final_state.ckpt"))
        child = c.extend(parent.id, 3e-8, wait=True)
        self.assertEqual(state_name(child), "SUCCEEDED")
        self.assertTrue(re.search(rf"job {child.id}: runs from t = 0, job {parent.id}'s final "
                                  r"state not used: the parent kept no final state",
                                  self.daemon.log_tail(400)))


if __name__ == "__main__":
    unittest.main()
