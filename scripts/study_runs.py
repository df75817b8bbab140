"""Shared by the study scripts (plane_strain_study.py, damage_study.py): one softshock-solve run
per output folder, reused when the folder already holds a finished run of the same spec."""
import json
import os
import subprocess
import time


def run(solver, spec, out, threads):
    """Runs the spec in `out` (reusing a finished run of the same spec there); a run that fails
    (e.g. MESH_DISTORTION) keeps its partial result and its summary says why."""
    os.makedirs(out, exist_ok=True)
    path = os.path.join(out, "spec.json")
    done = os.path.join(out, "summary.json")
    if os.path.exists(done) and os.path.exists(path):
        with open(path) as f, open(done) as g:
            if json.load(f) == spec:
                return json.load(g)
    with open(path, "w") as f:
        json.dump(spec, f)
    started = time.monotonic()
    p = subprocess.run([solver, "--spec", path, "--out", out, "--quiet", "--threads", str(threads)],
                       capture_output=True, text=True)
    if p.returncode not in (0, 1) or not p.stdout.strip():
        raise SystemExit(f"{out}: softshock-solve failed ({p.returncode}): {p.stderr[-2000:]}")
    summary = json.loads(p.stdout.strip().splitlines()[-1])
    summary["seconds"] = time.monotonic() - started
    with open(done, "w") as f:
        json.dump(summary, f)
    return summary
