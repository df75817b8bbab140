"""End to end: softshockd with the slurm executor against a real one-node Slurm started by
scripts/slurm-dev (docs/cluster.md). A grid through Slurm matches the local executor's; cancel
reaches Slurm; a solver failure on the cluster is FAILED with Slurm's and the solver's reason;
an uploaded mesh runs on the cluster; kill -9 of the daemon mid-grid loses and duplicates nothing.

Without a usable Slurm (packages missing, not root, daemons refuse to start) the whole file
prints "SKIPPED: <reason>" and exits 77, which CTest reports as skipped (SKIP_RETURN_CODE)."""

import glob
import os
import subprocess
import sys
import time
import unittest

import numpy as np

from softshock_harness import Daemon, DaemonTestCase, long_spec, small_spec, state_name

REPO = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
SOLVE = os.environ.get("SOFTSHOCK_SOLVE", "softshock-solve")
SKIP = 77
SLURM_DEV = os.path.join(REPO, "scripts", "slurm-dev")


def slurm_up() -> str:
    """Starts scripts/slurm-dev; returns '' when ready, else why not."""
    try:
        p = subprocess.run([SLURM_DEV, "up"], capture_output=True, text=True, timeout=90)
    except (OSError, subprocess.TimeoutExpired) as e:
        return f"scripts/slurm-dev up: {e}"
    if p.returncode != 0:
        return "scripts/slurm-dev up failed: " + (p.stderr.strip().splitlines() or ["?"])[-1]
    for line in p.stdout.splitlines():
        if line.startswith("export SLURM_CONF="):
            os.environ["SLURM_CONF"] = line.split("=", 1)[1]
    return ""


def grid_request(end_time: float = 2e-8, elements: int = 300) -> dict:
    """3 x 3 points of a tiny disk: P-bar x t-bar_pulse."""
    return {"base_spec": small_spec(elements=elements, end_time=end_time),
            "axes": [{"name": "pbar", "values": [0.5, 1.0, 1.5]},
                     {"name": "tbar_pulse", "linspace": {"start": 0.1, "stop": 0.2, "num": 3}}]}


def squeue_names() -> list:
    p = subprocess.run(["squeue", "-h", "--states=all", "-o", "%F|%j"], capture_output=True,
                       text=True, check=True)
    return [line.split("|", 1) for line in p.stdout.split()]


class SlurmTest(DaemonTestCase):
    workers = 2  # the array throttle (%2): the dev node has 2 CPUs

    def extra_daemon_args(self):
        return ["--executor", "slurm", "--slurm-solver", SOLVE, "--slurm-poll-interval", "0.3",
                "--slurm-sbatch-arg=--nice=0", "--checkpoint-interval", "30"]

    def submit_grid(self, c, **kw):
        g = grid_request(**kw)
        return c.submit_grid(g["base_spec"], g["axes"], recompute=True)

    def batches(self) -> list:
        return sorted(glob.glob(os.path.join(self.data_dir, "slurm", "batches", "*.ids")))

    def test_grid_matches_local_executor(self):
        c = self.client()
        t0 = time.monotonic()
        grid = self.submit_grid(c)
        done = c.wait_grid(grid.id, timeout=120)
        slurm_s = time.monotonic() - t0
        self.assertEqual(state_name(done), "SUCCEEDED", done)
        self.assertEqual(len(self.batches()), 1, "one array job for the whole grid")
        # The nodes checkpoint (softshock-solve --checkpoint-dir; a requeued job continues), and
        # a finished run leaves no checkpoint folder.
        with open(self.batches()[0][:-len(".ids")] + ".sh") as f:
            self.assertIn('--checkpoint-dir "$dir/checkpoint" --checkpoint-interval 30', f.read())
        self.assertEqual(glob.glob(os.path.join(self.data_dir, "slurm", "jobs", "*",
                                                "checkpoint")), [])
        self.assertIn("(array)", self.daemon.log_tail(200))

        # The same grid through the local executor in a separate data dir.
        local = Daemon(os.path.join(self.tmp, "local"), os.path.join(self.tmp, "local.log"),
                       workers=2)
        local.start()
        self.addCleanup(local.stop)
        from softshock_client import Client
        with Client(local.address) as lc:
            lgrid = self.submit_grid(lc)
            self.assertEqual(state_name(lc.wait_grid(lgrid.id, timeout=120)), "SUCCEEDED")
            for quantity in ("max_abar_first_cycle", "max_abar", "energy_injected"):
                a = c.grid_reduction(grid.id, quantity)
                b = lc.grid_reduction(lgrid.id, quantity)
                np.testing.assert_allclose(a.values, b.values, rtol=1e-8, err_msg=quantity)
            rows = {r["grid_index"]: r for r in c.query(grid_id=grid.id)}
            lrows = {r["grid_index"]: r for r in lc.query(grid_id=lgrid.id)}
            self.assertEqual(sorted(rows), list(range(9)))
            for k, row in rows.items():
                s, ls = row["summary"], lrows[k]["summary"]
                for key in ("steps", "elements", "dominant_mode_end"):
                    self.assertEqual(s.get(key), ls.get(key), key)
                # Fourier modes: read from result.h5 on the cluster side, exact doubles.
                t, m, amp = c.modes(row["id"])
                lt, lm, lamp = lc.modes(lrows[k]["id"])
                np.testing.assert_array_equal(t, lt)
                np.testing.assert_array_equal(m, lm)
                np.testing.assert_allclose(amp, lamp, rtol=1e-12, atol=0)
        print(f"\n[3x3 grid through Slurm: {slurm_s:.1f} s]", file=sys.stderr)

    def test_cancel_running_job(self):
        c = self.client()
        job = c.submit(long_spec())
        self.wait_running(c, job.id, timeout=60)
        slurm_id = None
        for base, name in squeue_names():
            if name == f"softshock-{job.id}":
                slurm_id = base
        self.assertIsNotNone(slurm_id)
        c.cancel(job.id)
        final = c.wait(job.id, timeout=30)
        self.assertEqual(state_name(final), "CANCELLED", final)
        self.assertEqual(final.reason, "CANCELLED_BY_USER")
        state = subprocess.run(["squeue", "-h", "--states=all", "-j", slurm_id, "-o", "%T"],
                               capture_output=True, text=True).stdout.strip()
        self.assertIn(state, ("CANCELLED", "COMPLETING", ""), f"Slurm still has it {state}")

    def test_solver_failure_is_failed_with_reason(self):
        c = self.client()
        # Crushes the rim at once (as tests/integration/test_softshock_solve.py): exit 1.
        spec = {"geometry": {"disk": {"radius": 9e-5}, "targetElements": 500},
                "viscosity": {"c1": 0, "c2": 0}, "load": {"pressure": 2e11, "duration": 1e-7},
                "run": {"endTime": 1e-7, "cfl": 0.95, "outputInterval": 1e-8}}
        job = c.submit(spec)
        final = c.wait(job.id, timeout=60)
        self.assertEqual(state_name(final), "FAILED", final)
        # The solver's cause, as a local run reports it; Slurm's word and the solver's message in
        # the error.
        self.assertEqual(final.reason, "ELEMENT_INVERSION")
        self.assertIn("FAILED", final.error)
        self.assertIn("element inversion", final.error)
        self.assertIn("Slurm job", final.error)

    def test_uploaded_mesh_runs_on_the_cluster(self):
        from test_meshes import mesh_rounded_square  # the client's own Gmsh
        msh = os.path.join(self.tmp, "square.msh")
        mesh_rounded_square(msh)
        c = self.client()
        job = c.submit({"geometry": {"meshFile": msh},
                        "run": {"endTime": 1e-8, "outputInterval": 5e-9}})  # uploaded first
        final = c.wait(job.id, timeout=120)
        self.assertEqual(state_name(final), "SUCCEEDED", final.error)
        [mesh] = c.list_meshes()
        self.assertEqual(final.spec.geometry.mesh_file, f"uploads/{mesh.id}.msh")
        self.assertEqual(c.summary(job.id)["elements"], mesh.elements)

    def test_cylinder_runs_on_the_cluster_as_locally(self):
        # A 3-D job through sbatch: the same solver, so the same answer as the local executor.
        spec = {"geometry": {"cylinder": {"radius": 9e-5, "thickness": 6e-6},
                             "targetElements": 2000},
                "run": {"endTime": 1e-8, "outputInterval": 5e-9}}
        c = self.client()
        final = c.wait(c.submit(spec).id, timeout=120)
        self.assertEqual(state_name(final), "SUCCEEDED", final.error)
        cluster = c.summary(final.id)
        self.assertGreater(cluster["elements"], 1500)
        local = Daemon(os.path.join(self.tmp, "local3d"), os.path.join(self.tmp, "local3d.log"),
                       workers=1)
        local.start()
        self.addCleanup(local.stop)
        from softshock_client import Client
        with Client(local.address) as lc:
            lfinal = lc.wait(lc.submit(spec).id, timeout=120)
            self.assertEqual(state_name(lfinal), "SUCCEEDED", lfinal.error)
            here = lc.summary(lfinal.id)
        for name in ("elements", "steps", "dominant_mode_end"):
            self.assertEqual(cluster[name], here[name], name)
        for name in ("energy_injected", "energy_after_pulse", "max_abar"):
            np.testing.assert_allclose(cluster[name], here[name], rtol=1e-8, err_msg=name)

    def test_kill9_mid_grid_restart_no_duplicates(self):
        c = self.client()
        grid = self.submit_grid(c, end_time=5e-8, elements=800)
        # Wait until Slurm runs some points but not all, then kill the daemon hard.
        self.wait_for(lambda: c.grid(grid.id).counts.running + c.grid(grid.id).counts.succeeded
                      > 0, 60, what="a point running")
        self.daemon.kill9()
        time.sleep(1.0)  # Slurm goes on without us
        self.daemon.start()
        c = self.client()  # a new port
        done = c.wait_grid(grid.id, timeout=120)
        self.assertEqual(state_name(done), "SUCCEEDED", done)
        self.assertEqual(done.counts.succeeded, 9)
        self.assertEqual(len(self.batches()), 1, "submitted exactly once")
        ids = {r["id"] for r in c.query(grid_id=grid.id)}
        ours = [(b, n) for b, n in squeue_names() if n.startswith("softshock-")]
        grid_bases = {b for b, n in ours if n[len("softshock-"):] in ids}
        self.assertEqual(len(grid_bases), 1, f"one Slurm array for the grid: {ours}")
        self.assertIn("re-attached", self.daemon.log_tail(400))


def slurm_running() -> bool:
    """A dev cluster already up (a developer's): the test uses it and leaves it up."""
    return subprocess.run([SLURM_DEV, "status"], capture_output=True, timeout=30).returncode == 0


if __name__ == "__main__":
    started_here = not slurm_running()
    why = slurm_up()
    if why:
        print(f"SKIPPED: {why}")
        sys.exit(SKIP)
    try:
        result = unittest.main(exit=False).result
    finally:
        if started_here:  # leave the machine as found: no Slurm daemons outlive the test
            subprocess.run([SLURM_DEV, "down"], capture_output=True, timeout=60)
    sys.exit(0 if result.wasSuccessful() else 1)
