"""Crash test: SIGKILL softshockd at random moments while jobs and small grids run, restart it
each time, then check what an operator relies on (docs/reliability.md):

- every acknowledged job (its SubmitJob/SubmitGrid answer arrived) reaches a terminal state,
  none is lost or stuck;
- each SUCCEEDED result opens, is marked complete and matches its catalogued summary;
- no job ran more times than its attempt counter says (attempt history rows <= attempt);
- the catalogue passes PRAGMA integrity_check;
- kills during mesh uploads (an upload runs in a thread in about half the rounds, the kill
  landing before, during or after it): every mesh whose UploadMesh answer arrived is listed
  after the last restart, its file holds exactly the uploaded bytes (id = SHA-256), and no
  staged or checker file is left in DATA/meshes/uploads;
- kills during checkpoints (the daemon checkpoints every 20 ms of a run, so kills land before,
  while and after a state file is written): every SUCCEEDED job that continued from a checkpoint
  has a result bitwise equal, dataset by dataset, to softshock-solve's uninterrupted run of its
  spec, and no checkpoint folder outlives its job.

SOFTSHOCK_CHAOS_KILLS (default 20) sets the number of kills, SOFTSHOCK_CHAOS_SEED the random
seed; the figures (kills, acknowledged, lost, corrupt, restart-to-healthy) are printed.
"""

import glob
import hashlib
import json
import os
import random
import re
import sqlite3
import statistics
import subprocess
import sys
import threading
import time
import unittest

import h5py

from softshock_harness import (DaemonTestCase, SoftshockError, TERMINAL, small_spec,
                               state_name)
from test_meshes import mesh_rounded_square

KILLS = int(os.environ.get("SOFTSHOCK_CHAOS_KILLS", "20"))
SEED = int(os.environ.get("SOFTSHOCK_CHAOS_SEED", "12"))


class ChaosTest(DaemonTestCase):
    workers = 2
    # Enough attempts that most jobs finish despite the kills; the rest must end FAILED
    # MAX_ATTEMPTS, which is terminal too.
    # Checkpoints every 20 ms of a run: the runs here take 0.1-0.5 s, so kills land before,
    # during and after state files are written, and restarts continue from them.
    daemon_args = ("--max-attempts", "6", "--checkpoint-interval", "0.02")

    def test_sigkill_at_random_moments(self):
        rng = random.Random(SEED)
        acknowledged = set()
        restarts = []
        uploads = self._upload_files(rng)
        meshes_acknowledged, uploads_started, answers = {}, 0, []
        for _ in range(KILLS):
            c = self.client(timeout=5)
            uploader = None
            if rng.random() < 0.5:
                uploads_started += 1
                uploader = threading.Thread(
                    target=self._upload, args=(rng.choice(uploads), meshes_acknowledged, answers))
                uploader.start()
            try:
                for _ in range(rng.randint(1, 3)):
                    spec = small_spec(rng.choice([300, 600, 1200]), rng.choice([2e-8, 4e-8, 8e-8]))
                    acknowledged.add(c.submit(spec).id)
                if rng.random() < 0.3:
                    grid = c.submit_grid(
                        base_spec=small_spec(300, 2e-8),
                        axes=[{"name": "pbar", "values": [0.5, rng.choice([0.7, 0.9])]}])
                    for job in c.list(label=None):
                        if job.grid_id == grid.id:
                            acknowledged.add(job.id)
            except SoftshockError as e:  # e.g. a full queue: not acknowledged, not counted
                print(f"submission refused: {e}")
            # The random moment: anywhere from just after the submissions to well into a run.
            time.sleep(rng.uniform(0.0, 0.8))
            # It must still be alive: an abort of its own (a sanitizer report) is a finding.
            self.assertIsNone(self.daemon.proc.poll(), "softshockd died by itself:\n" +
                              self.daemon.log_tail())
            self.daemon.kill9()
            if uploader is not None:
                uploader.join(timeout=30)
                self.assertFalse(uploader.is_alive(), "an upload hung past the daemon's death")
            started = time.monotonic()
            self.daemon.start()
            restarts.append(time.monotonic() - started)

        # One kill sure to land after a checkpoint: a longer job, killed as soon as its state file
        # exists (the folder goes when the job ends), so at least one job continues from one.
        c = self.client(timeout=5)
        sure = c.submit(small_spec(4000, 4e-7)).id
        acknowledged.add(sure)
        state_file = os.path.join(self.data_dir, "jobs", sure, "checkpoint", "state.ckpt")
        deadline = time.monotonic() + 120
        while not os.path.exists(state_file) and time.monotonic() < deadline:
            time.sleep(0.002)
        self.assertTrue(os.path.exists(state_file), "no checkpoint of a running job in 120 s")
        self.daemon.kill9()
        self.daemon.start()

        c = self.client(timeout=10)
        deadline = time.monotonic() + 300
        pending = set(acknowledged)
        while pending and time.monotonic() < deadline:
            pending = {j for j in pending if state_name(c.get(j)) not in TERMINAL}
            time.sleep(0.2)
        lost = [j for j in acknowledged if not self._exists(c, j)]
        self.assertEqual(lost, [], "acknowledged jobs missing from the catalogue")
        self.assertEqual(sorted(pending), [], "jobs stuck in a non-terminal state")

        corrupt, states = [], {}
        for job_id in sorted(acknowledged):
            job = c.get(job_id)
            key = state_name(job) + (f"/{job.reason}" if job.reason else "")
            states[key] = states.get(key, 0) + 1
            if state_name(job) != "SUCCEEDED":
                continue
            summary = c.summary(job_id)
            try:
                with h5py.File(os.path.join(self.data_dir, job.result_path), "r") as h5:
                    stored = json.loads(h5.attrs["summary"])
                    ok = (int(h5.attrs["complete"]) == 1 and
                          stored["elements"] == int(summary["elements"]) and
                          stored["steps"] == int(summary["steps"]))
            except (OSError, KeyError, ValueError) as e:
                print(f"{job_id}: {e}")
                ok = False
            if not ok:
                corrupt.append(job_id)
        self.assertEqual(corrupt, [], "SUCCEEDED jobs whose result does not match the summary")

        listed = {m.id: m for m in c.list_meshes()}
        missing = sorted(set(meshes_acknowledged) - set(listed))
        self.assertEqual(missing, [], "acknowledged uploads missing after the kills")
        uploads_dir = os.path.join(self.data_dir, "meshes", "uploads")
        for mesh_id, sha in meshes_acknowledged.items():
            self.assertEqual(mesh_id, sha)
            with open(os.path.join(uploads_dir, mesh_id + ".msh"), "rb") as f:
                self.assertEqual(hashlib.sha256(f.read()).hexdigest(), sha, mesh_id)
            self.assertGreater(listed[mesh_id].elements, 0, mesh_id)

        # Continued from checkpoints: the same answer as a run that never stopped.
        with open(self.daemon.log_path, encoding="utf-8", errors="replace") as f:
            continued = set(re.findall(r"job ([0-9a-f]+) continues from its checkpoint", f.read()))
        self.assertIn(sure, continued, "the job killed after its checkpoint did not continue")
        checked, differing = 0, []
        for job_id in sorted(continued & acknowledged):
            job = c.get(job_id)
            if state_name(job) != "SUCCEEDED":
                continue
            result = os.path.join(self.data_dir, job.result_path)
            if not self._equals_an_uninterrupted_run(result, job_id):
                differing.append(job_id)
            checked += 1
        self.assertEqual(differing, [], "continued jobs whose result differs from a run that "
                         "never stopped")

        self.assertEqual(self.daemon.stop(), 0)
        leftovers = [os.path.basename(p) for p in glob.glob(os.path.join(uploads_dir, ".*"))]
        self.assertEqual(leftovers, [], "staged or checker files left after the kills")
        db = sqlite3.connect(os.path.join(self.data_dir, "catalogue.sqlite"))
        try:
            self.assertEqual(db.execute("PRAGMA integrity_check").fetchone()[0], "ok")
            over = db.execute(
                "SELECT j.id, j.attempt, COUNT(a.attempt) FROM jobs j "
                "LEFT JOIN job_attempts a ON a.job_id = j.id GROUP BY j.id "
                "HAVING COUNT(a.attempt) > j.attempt").fetchall()
        finally:
            db.close()
        self.assertEqual(over, [], "jobs with more runs than their attempt counter says")

        leftover_checkpoints = glob.glob(os.path.join(self.data_dir, "jobs", "*", "checkpoint"))
        self.assertEqual(leftover_checkpoints, [], "checkpoint folders left after their jobs")

        print(f"\nchaos: kills={KILLS} seed={SEED} acknowledged={len(acknowledged)} lost=0 "
              f"stuck=0 corrupt=0 states={states} restart-to-healthy median="
              f"{statistics.median(restarts):.3f}s max={max(restarts):.3f}s "
              f"uploads started={uploads_started} answered={len(answers)} (killed before the "
              f"answer {uploads_started - len(answers)}) distinct meshes stored="
              f"{len(meshes_acknowledged)} lost=0 leftovers=0 continued from a checkpoint="
              f"{len(continued)} (succeeded and compared bitwise: {checked}, differing 0)")

    def _equals_an_uninterrupted_run(self, result, job_id):
        """softshock-solve runs the job's stored spec without a stop (one thread, as the
        daemon's default --solver-threads); every dataset must equal the job's bit for bit."""
        with h5py.File(result, "r") as h5:
            spec = h5.attrs["spec"]
        folder = os.path.join(self.tmp, "uninterrupted", job_id)
        os.makedirs(folder)
        spec_path = os.path.join(folder, "spec.json")
        with open(spec_path, "w") as f:
            f.write(spec if isinstance(spec, str) else spec.decode())
        subprocess.run([os.environ["SOFTSHOCK_SOLVE"], "--spec", spec_path, "--out", folder,
                        "--threads", "1", "--quiet"], check=True, stdout=subprocess.DEVNULL)
        compare = os.path.join(os.environ["SOFTSHOCK_SOURCE_DIR"], "scripts", "compare_results.py")
        return subprocess.run([sys.executable, compare, result,
                               os.path.join(folder, "result.h5"), "--quiet"]).returncode == 0

    def _upload_files(self, rng):
        """A few distinct meshes of 0.1-1 MB, so that a kill often lands inside an upload."""
        folder = os.path.join(self.tmp, "uploads")
        os.makedirs(folder)
        paths = []
        for k in range(4):
            path = os.path.join(folder, f"square{k}.msh")
            mesh_rounded_square(path, side=1.2e-4 + k * 1e-6, size=rng.choice([2e-6, 3e-6, 5e-6]))
            paths.append(path)
        return paths

    def _upload(self, path, acknowledged, answers):
        with open(path, "rb") as f:
            sha = hashlib.sha256(f.read()).hexdigest()
        try:
            mesh = self.client(timeout=5).upload_mesh(path)
        except SoftshockError:  # the daemon died under it: not acknowledged
            return
        answers.append(mesh.id)
        acknowledged[mesh.id] = sha  # the id is checked against the bytes' SHA-256 at the end

    def _exists(self, c, job_id):
        try:
            c.get(job_id)
            return True
        except SoftshockError:
            return False


if __name__ == "__main__":
    unittest.main()
