"""Reads softshock result files (result.h5, docs/results-format.md) without a daemon.

Accepts format_version 1 (node vectors N x 2) and 2 (N x 3 with z = 0): vectors always come back
N x 2, so code written against either version keeps working. Needs h5py (python3-h5py).
"""
from __future__ import annotations

import json
from typing import Dict, List, Tuple

import numpy as np

KNOWN_FORMAT_VERSIONS = (1, 2)
NODE_VECTORS = ("displacement", "velocity")


class ResultFile:
    """An open result.h5. Use as a context manager, or call close()."""

    def __init__(self, path: str):
        import h5py  # here, so importing softshock_client never needs h5py

        self.path = path
        self._h5 = h5py.File(path, "r")
        self.format_version = int(self._h5.attrs["format_version"])
        if self.format_version not in KNOWN_FORMAT_VERSIONS:
            self._h5.close()
            raise ValueError(f"{path}: format_version {self.format_version}; this reader knows "
                             f"{', '.join(map(str, KNOWN_FORMAT_VERSIONS))}")
        self._frames = sorted(self._h5["fields"])

    def close(self) -> None:
        """Closes the HDF5 file."""
        self._h5.close()

    def __enter__(self) -> "ResultFile":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    @property
    def complete(self) -> bool:
        """False for the partial file of a run that stopped early (failed, cancelled)."""
        return bool(self._h5.attrs["complete"])

    @property
    def summary(self) -> dict:
        """The run's summary, as softshock-solve prints it (units in the names)."""
        return json.loads(self._h5.attrs["summary"])

    @property
    def frame_times(self) -> np.ndarray:
        """The frames' times (s), in frame order."""
        return np.array([self._h5["fields"][k].attrs["time"] for k in self._frames])

    def mesh(self) -> Tuple[np.ndarray, np.ndarray]:
        """Reference nodes (N x 2, m) and triangles (E x 3, 0-based)."""
        return self._h5["mesh/nodes"][:], self._h5["mesh/triangles"][:]

    def series(self) -> Dict[str, np.ndarray]:
        """Every scalar history by name ("time" in s, "abar", the energies, ...)."""
        return {name: ds[:] for name, ds in self._h5["timeseries"].items()}

    def field(self, name: str, frame: int = -1) -> np.ndarray:
        """A field of a frame (negative counts from the end): vectors N x 2, scalars E."""
        if not self._frames:
            raise IndexError(f"{self.path} has no field frames")
        group = self._h5["fields"][self._frames[frame]]
        if name not in group:
            raise KeyError(f"field {name!r}: not in {self.path} (have {sorted(group)})")
        values = group[name][:]
        return values[:, :2] if name in NODE_VECTORS else values

    def frame_names(self) -> List[str]:
        """The frames' group names under /fields, in frame order."""
        return list(self._frames)
