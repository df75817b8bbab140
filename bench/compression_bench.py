#!/usr/bin/python3
"""Compression settings for field frames, measured (a benchmark, not a test).

Reads the field frames of a result file (e.g. the baseline disk to t-bar = 4) and writes them
again with h5py (the same libhdf5 and zlib as softshock) under several filter settings, chunked
as solver/io/result_writer.cpp chunks them (rows of ~256 KiB), and prints per setting the
file size and the median write time per frame (CPU time of this process: robust to other load).

    build/solver/softshock-solve --spec SPEC --out out/t4 --quiet
    /usr/bin/python3 bench/compression_bench.py out/t4/result.h5

Figures are recorded in docs/performance.md.
"""

from __future__ import annotations

import os
import statistics
import sys
import tempfile
import time

import h5py
import numpy as np

SETTINGS = {
    "none": {},
    "deflate 1": {"compression": "gzip", "compression_opts": 1},
    "shuffle + deflate 1": {"shuffle": True, "compression": "gzip", "compression_opts": 1},
    "shuffle + deflate 4": {"shuffle": True, "compression": "gzip", "compression_opts": 4},
    "shuffle + deflate 6": {"shuffle": True, "compression": "gzip", "compression_opts": 6},
}


def main() -> int:
    if len(sys.argv) != 2:
        print(__doc__)
        return 2
    with h5py.File(sys.argv[1], "r") as f:
        frames = [{name: f["fields"][g][name][()] for name in f["fields"][g]}
                  for g in sorted(f["fields"])]
    print(f"{len(frames)} frames of {len(frames[0])} fields from {sys.argv[1]}")
    print(f"{'setting':<22} {'MB':>7} {'ratio':>6} {'ms per frame (CPU)':>19}")
    base = None
    for name, opts in SETTINGS.items():
        with tempfile.TemporaryDirectory() as tmp:
            path = os.path.join(tmp, "f.h5")
            times = []
            with h5py.File(path, "w") as out:
                for k, frame in enumerate(frames):
                    t0 = time.process_time()
                    g = out.create_group(f"frame_{k:05d}")
                    for field, data in frame.items():
                        row = data[0].nbytes if data.ndim == 2 else data.itemsize
                        rows = max(1, min(len(data), 256 * 1024 // row))
                        chunks = (rows,) + data.shape[1:] if opts else None
                        g.create_dataset(field, data=data, chunks=chunks, **opts)
                    out.flush()
                    times.append(time.process_time() - t0)
            size = os.path.getsize(path) / 1e6
        base = base or size
        print(f"{name:<22} {size:>7.2f} {base / size:>6.2f} {statistics.median(times) * 1e3:>19.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
