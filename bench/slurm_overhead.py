#!/usr/bin/python3
"""Per-job overhead of softshockd's slurm executor versus the local one (docs/cluster.md).

Submits N tiny jobs (300 elements, 20 ns: ~0.1 s of solver time), one at a time, to a daemon
with each executor and times submit -> SUCCEEDED per job; prints the medians and their
difference. The slurm side needs a running Slurm (scripts/slurm-dev up).

  SOFTSHOCKD=build/server/softshockd SOFTSHOCK_SOLVE=build/solver/softshock-solve \\
  PYTHONPATH=build/python:client/python:tests/integration bench/slurm_overhead.py [N]
"""

import os
import statistics
import subprocess
import sys
import tempfile
import time

from softshock_client import Client
from softshock_harness import Daemon, small_spec, state_name

REPO = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))


def time_jobs(extra_args, n, tmp, name):
    daemon = Daemon(os.path.join(tmp, name), os.path.join(tmp, name + ".log"), extra_args,
                    workers=1)
    daemon.start()
    times = []
    try:
        with Client(daemon.address) as c:
            for k in range(n):
                # Distinct specs: identical ones could be answered from the catalogue.
                spec = small_spec(elements=300, end_time=2e-8 + k * 1e-10)
                t0 = time.monotonic()
                job = c.submit(spec, wait=True)
                times.append(time.monotonic() - t0)
                assert state_name(job) == "SUCCEEDED", job
    finally:
        daemon.stop()
    return times


def main():
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 10
    up = subprocess.run([os.path.join(REPO, "scripts", "slurm-dev"), "up"], capture_output=True,
                        text=True)
    if up.returncode != 0:
        sys.exit("no Slurm: " + up.stderr.strip())
    os.environ["SLURM_CONF"] = up.stdout.strip().split("=", 1)[1]
    solve = os.environ.get("SOFTSHOCK_SOLVE", "softshock-solve")
    with tempfile.TemporaryDirectory(prefix="softshock-bench-") as tmp:
        local = time_jobs([], n, tmp, "local")
        slurm = time_jobs(["--executor", "slurm", "--slurm-solver", solve,
                           "--slurm-poll-interval", os.environ.get("POLL", "0.2")], n, tmp,
                          "slurm")
    ml, ms = statistics.median(local), statistics.median(slurm)
    print(f"jobs: {n} each, one at a time")
    print(f"local executor: median {ml:.3f} s per job (min {min(local):.3f}, max {max(local):.3f})")
    print(f"slurm executor: median {ms:.3f} s per job (min {min(slurm):.3f}, max {max(slurm):.3f})")
    print(f"slurm overhead: median {ms - ml:.3f} s per job")


if __name__ == "__main__":
    main()
