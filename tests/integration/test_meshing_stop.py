"""Gmsh meshing honours cancel and the wall-time limit: softshockd meshes in a softshock-mesh
child process and kills it. A job whose frontal-Delaunay mesh would take many seconds is
caught while its child meshes; a cancel ends it CANCELLED within a second, the wall limit ends
it FAILED / WALL_TIME_EXCEEDED, no mesher is left behind, and the daemon keeps serving."""

import os
import time
import unittest

from softshock_harness import DaemonTestCase, small_spec, state_name

# About 1.5 million triangles with Gmsh's frontal-Delaunay mesher: tens of seconds on one core
# here (softshock-mesh alone: see docs/reliability.md), far longer than any bound below. One
# nanosecond of simulated time keeps the admission estimate small.
HUGE_GMSH_DISK = {
    "geometry": {"disk": {"radius": 9e-5}, "targetElements": 1500000,
                 "mesher": "FRONTAL_DELAUNAY"},
    "run": {"endTime": 1e-9, "outputInterval": 0, "historyInterval": 1e-10, "modes": 8},
}


def mesher_children(pid: int):
    """Pids of the daemon's softshock-mesh children (any of its threads may have spawned one)."""
    found = []
    task_dir = f"/proc/{pid}/task"
    for tid in os.listdir(task_dir):
        try:
            with open(f"{task_dir}/{tid}/children", encoding="ascii") as f:
                children = f.read().split()
        except OSError:
            continue  # the thread ended meanwhile
        for child in children:
            try:
                with open(f"/proc/{child}/comm", encoding="utf-8") as f:
                    if f.read().strip() == "softshock-mesh":
                        found.append(int(child))
            except OSError:
                pass  # exited meanwhile
    return found


class MeshingStopCase(DaemonTestCase):
    workers = 1

    def catch_meshing(self, c, job_id: str):
        """Waits until the job is RUNNING with its mesher child alive, and a little more so that
        Gmsh is well into the mesh; returns the child's pid."""
        pid = self.daemon.proc.pid

        def meshing():
            job = c.get(job_id)
            if state_name(job) in ("SUCCEEDED", "FAILED", "CANCELLED"):
                self.fail(f"job ended ({state_name(job)}: {job.error}) before meshing was seen")
            children = mesher_children(pid)
            return children[0] if state_name(job) == "RUNNING" and children else None
        child = self.wait_for(meshing, timeout=30, interval=0.02, what="softshock-mesh running")
        time.sleep(0.5)
        self.assertIn(child, mesher_children(pid), "the mesher ended too soon to be stopped")
        return child

    def assert_still_serving(self, c):
        self.assertEqual(c.health(), "SERVING")
        self.assertEqual(mesher_children(self.daemon.proc.pid), [], "a mesher was left behind")
        # A Gmsh mesh through the same child route still works, and a plain run after it.
        gmsh_spec = small_spec(elements=400, end_time=1e-8)
        gmsh_spec["geometry"]["mesher"] = "FRONTAL_DELAUNAY"
        done = c.submit(gmsh_spec, wait=True)
        self.assertEqual(state_name(done), "SUCCEEDED", done.error)
        self.assertEqual(c.summary(done.id)["mesh_cache"], "miss")


class CancelWhileMeshingTest(MeshingStopCase):
    def test_cancel_kills_the_mesher(self):
        c = self.client()
        job = c.submit(HUGE_GMSH_DISK)
        child = self.catch_meshing(c, job.id)

        start = time.monotonic()
        c.cancel(job.id)

        def cancelled():
            j = c.get(job.id)
            return j if state_name(j) == "CANCELLED" else None
        ended = self.wait_for(cancelled, timeout=30, interval=0.01, what="CANCELLED")
        elapsed = time.monotonic() - start
        print(f"\ncancel while meshing: CANCELLED after {elapsed:.3f} s")
        # Under CancelJob's own 0.8 s grace, after which it records CANCELLED for a worker that
        # does not stop (in-process meshing): the runner itself must have ended the job.
        self.assertLess(elapsed, 0.6, f"cancel during meshing took {elapsed:.2f} s")
        self.assertEqual(ended.reason, "CANCELLED_BY_USER")
        self.assertEqual(ended.error, "cancelled by user while meshing")
        self.assertFalse(os.path.exists(f"/proc/{child}"), "the mesher still runs")
        self.assert_still_serving(c)


class WallTimeWhileMeshingTest(MeshingStopCase):
    wall_s = 2.0
    daemon_args = ("--max-wall-time", str(wall_s))

    def test_wall_limit_kills_the_mesher(self):
        c = self.client()
        job = c.submit(HUGE_GMSH_DISK)
        self.catch_meshing(c, job.id)

        def ended():
            j = c.get(job.id)
            return j if state_name(j) in ("SUCCEEDED", "FAILED", "CANCELLED") else None
        failed = self.wait_for(ended, timeout=30, interval=0.01, what="the wall-time limit")
        ran = failed.finish_time.ToMicroseconds() - failed.start_time.ToMicroseconds()
        print(f"\nwall limit {self.wall_s} s while meshing: FAILED after {ran / 1e6:.3f} s")
        self.assertEqual(state_name(failed), "FAILED", failed.error)
        self.assertEqual(failed.reason, "WALL_TIME_EXCEEDED")
        self.assertIn("while meshing", failed.error)
        self.assertLess(ran / 1e6, self.wall_s + 1.0, "the limit took effect late")
        self.assert_still_serving(c)


if __name__ == "__main__":
    unittest.main()
