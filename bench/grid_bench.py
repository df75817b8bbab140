#!/usr/bin/python3
"""Wall time of a whole parameter grid on this machine (a benchmark, not a test).

Starts softshockd (--workers 2 by default) on a fresh data folder, submits a grid file
(default examples/pbar_tpulse_grid.json: the 121-run P-bar x t-bar_pulse study to t-bar = 4),
waits for every point, writes the reduction (max A-bar over 0 <= t-bar <= 4) as CSV and as a
heat map, and prints the wall time with the load average before and after (the machine may be
shared: the load says how much of it the grid had).

    cmake --build build --target softshockd softshock_python
    PYTHONPATH=build/python:client/python /usr/bin/python3 bench/grid_bench.py --out out/grid-bench

Figures are recorded in docs/performance.md.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import resource
import shutil
import signal
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)


def start_daemon(softshockd: str, data_dir: str, workers: int, log_path: str):
    port_file = os.path.join(data_dir, "port")
    os.makedirs(data_dir, exist_ok=True)
    log = open(log_path, "wb")
    proc = subprocess.Popen([softshockd, "--data-dir", data_dir, "--listen", "127.0.0.1:0",
                             "--port-file", port_file, "--workers", str(workers)],
                            stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)
    deadline = time.monotonic() + 30
    while not (os.path.exists(port_file) and open(port_file).read().strip()):
        if proc.poll() is not None or time.monotonic() > deadline:
            raise RuntimeError(f"softshockd did not start; see {log_path}")
        time.sleep(0.05)
    return proc, f"127.0.0.1:{int(open(port_file).read().strip())}"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--grid", default=os.path.join(ROOT, "examples", "pbar_tpulse_grid.json"))
    parser.add_argument("--softshockd", default=os.path.join(ROOT, "build", "server", "softshockd"))
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--out", default=os.path.join(ROOT, "out", "grid-bench"))
    parser.add_argument("--keep-data", action="store_true", help="keep the daemon's data folder")
    args = parser.parse_args()

    import numpy as np
    from softshock_client import Client, plots, state_name  # needs build/python on PYTHONPATH

    os.makedirs(args.out, exist_ok=True)
    data_dir = tempfile.mkdtemp(prefix="softshock-grid-bench-")
    proc, address = start_daemon(args.softshockd, os.path.join(data_dir, "data"), args.workers,
                                 os.path.join(args.out, "softshockd.log"))
    try:
        with Client(address, timeout=60) as c:
            while True:
                try:
                    if c.health() == "SERVING":
                        break
                except Exception:  # noqa: BLE001 - not up yet
                    time.sleep(0.05)
            load_before = os.getloadavg()
            start = time.monotonic()
            grid = c.submit_grid(grid_file=args.grid)
            last = ""
            while True:
                grid = c.grid(grid.id)
                line = (f"{state_name(grid)} {grid.progress:6.1%}  "
                        f"{grid.counts.succeeded + grid.counts.failed}/{grid.point_count} done")
                if line != last:
                    print(f"[{time.monotonic() - start:7.1f} s] {line}", flush=True)
                    last = line
                if state_name(grid) in ("SUCCEEDED", "FAILED", "CANCELLED"):
                    break
                time.sleep(0.2)
            wall = time.monotonic() - start
            load_after = os.getloadavg()
            # The same grid again: every point reuses its identical earlier run.
            start = time.monotonic()
            again = c.submit_grid(grid_file=args.grid)
            while state_name(c.grid(again.id)) not in ("SUCCEEDED", "FAILED", "CANCELLED"):
                time.sleep(0.01)
            resubmit_wall = time.monotonic() - start
            red = c.grid_reduction(grid.id, "max_abar_first_cycle")
            csv_path = os.path.join(args.out, "reduction.csv")
            with open(csv_path, "w", newline="", encoding="utf-8") as f:
                w = csv.writer(f)
                w.writerow(red.axis_names + [red.quantity, "job_id", "state"])
                for index in range(red.values.size):
                    at = [int(i) for i in np.unravel_index(index, red.values.shape)]
                    w.writerow([red.axis_values[k][at[k]] for k in range(len(at))] +
                               [repr(float(red.values.flat[index])), red.job_ids.flat[index],
                                red.states.flat[index]])
            png = plots.plot_grid_heatmap(red, os.path.join(args.out, "max_abar_first_cycle.png"))
            job_walls = [q["summary"]["wall_time"] for q in c.query(grid_id=grid.id)
                         if q["summary"]]
            summaries = [q["summary"] for q in c.query(grid_id=grid.id) if q["summary"]]
            elements = {q["elements"] for q in summaries}
            # Where the time went (daemons that report it): element loop alone vs whole run,
            # and how many points meshed.
            kernel = [q["kernel_grind_time"] for q in summaries if q.get("kernel_grind_time")]
            grind = [q["grind_time"] for q in summaries if q.get("grind_time")]
            cache = {}
            for q in summaries:
                cache[q.get("mesh_cache", "")] = cache.get(q.get("mesh_cache", ""), 0) + 1
        report = {
            "grid": os.path.relpath(args.grid, ROOT), "grid_id": grid.id,
            "state": state_name(grid), "points": grid.point_count,
            "succeeded": grid.counts.succeeded, "failed": grid.counts.failed,
            "workers": args.workers, "cpus": os.cpu_count(), "wall_time_s": round(wall, 1),
            "sum_job_wall_time_s": round(sum(job_walls), 1),
            "mean_job_wall_time_s": round(sum(job_walls) / max(1, len(job_walls)), 2),
            "elements": sorted(elements),
            "resubmit_wall_time_s": round(resubmit_wall, 2),
            "mean_grind_ns": round(sum(grind) / len(grind), 1) if grind else None,
            "mean_kernel_grind_ns": round(sum(kernel) / len(kernel), 1) if kernel else None,
            "mesh_cache": cache,
            "loadavg_before": [round(x, 2) for x in load_before],
            "loadavg_after": [round(x, 2) for x in load_after],
            "reduction_csv": csv_path, "heatmap_png": png,
        }
        with open(os.path.join(args.out, "report.json"), "w", encoding="utf-8") as f:
            json.dump(report, f, indent=2)
        print(json.dumps(report, indent=2))
        print(f"wall time of the {grid.point_count}-run grid: {wall:.1f} s "
              f"({wall / 60:.2f} min) with {args.workers} workers; load average "
              f"{load_before[0]:.2f} before, {load_after[0]:.2f} after (1-min); resubmitted in "
              f"{resubmit_wall:.2f} s")
    finally:
        proc.send_signal(signal.SIGTERM)
        proc.wait(timeout=30)
        if not args.keep_data:
            shutil.rmtree(data_dir, ignore_errors=True)
    # The daemon's CPU time (all its threads, start to stop): unlike the wall time, other
    # processes on a shared machine cannot inflate it.
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    print(f"softshockd CPU time: {usage.ru_utime + usage.ru_stime:.1f} s "
          f"(user {usage.ru_utime:.1f} s, system {usage.ru_stime:.1f} s)")
    return 0 if report["state"] == "SUCCEEDED" else 1


if __name__ == "__main__":
    sys.exit(main())
