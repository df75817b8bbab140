"""Executes examples/notebooks/thesis_figures.ipynb as a user would (jupyter nbconvert --execute;
any failing cell fails it) with TMPDIR set to a fresh folder, then checks that the daemon the
notebook started for itself left no temporary data folder behind (softshock-notebook-*).

Usage: run_notebook.py JUPYTER NOTEBOOK OUTPUT_DIR"""

import glob
import os
import shutil
import subprocess
import sys

jupyter, notebook, out = sys.argv[1:4]
tmp = os.path.join(out, "tmp")
shutil.rmtree(tmp, ignore_errors=True)
os.makedirs(tmp)
env = dict(os.environ, TMPDIR=tmp)
env.pop("SOFTSHOCK_SERVER", None)  # the notebook starts its own daemon
env.pop("SOFTSHOCK_KEEP_TMP", None)
subprocess.run([jupyter, "nbconvert", "--to", "notebook", "--execute", "--output-dir", out,
                os.path.basename(notebook)], cwd=os.path.dirname(os.path.abspath(notebook)),
               env=env, check=True)
executed = open(os.path.join(out, os.path.basename(notebook)), encoding="utf-8").read()
if "(started here)" not in executed:
    sys.exit("run_notebook: the notebook did not start its own softshockd")
left = glob.glob(os.path.join(tmp, "softshock-notebook-*"))
if left:
    sys.exit(f"run_notebook: the notebook left its temporary folder behind: {left}")
print("run_notebook: OK; no softshock-notebook-* folder left in", tmp)
