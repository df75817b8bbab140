"""Uploaded meshes: the request stream of UploadMesh, and which spec mesh files are local.

A spec's geometry.mesh_file that names a file on the client's machine (absolute, or relative to
the spec file's folder; for a dict or RunSpec, to the working directory) is uploaded and replaced
by geometry.mesh_id. A path that is not a local file is left alone: it names a file in the
daemon's DATA/meshes/.
"""
from __future__ import annotations

import os
from typing import Iterator, Optional

from softshock.v1 import service_pb2

CHUNK_BYTES = 1 << 20  # well under gRPC's 4 MiB message limit


def upload_requests(path: str) -> Iterator[service_pb2.UploadMeshRequest]:
    """The file in parts of CHUNK_BYTES, read as they are sent (never whole in memory); the
    first part names it."""
    name = os.path.basename(path)
    with open(path, "rb") as f:
        first = True
        while True:
            data = f.read(CHUNK_BYTES)
            if not data and not first:
                return
            yield service_pb2.UploadMeshRequest(file_name=name if first else "", data=data)
            first = False


def local_mesh_file(spec, base_dir: Optional[str]) -> Optional[str]:
    """The local file a RunSpec's geometry.mesh_file names, or None."""
    if spec.geometry.WhichOneof("shape") != "mesh_file":
        return None
    named = spec.geometry.mesh_file
    path = named if os.path.isabs(named) else os.path.join(base_dir or os.getcwd(), named)
    if os.path.isfile(path):
        return path
    if os.path.isabs(named):
        raise FileNotFoundError(f"geometry.mesh_file: '{named}' is not a file on this machine")
    return None


def spec_dir(spec) -> Optional[str]:
    """The folder relative mesh paths are taken from: the spec file's, when spec is a path."""
    if isinstance(spec, (str, os.PathLike)) and not str(spec).lstrip().startswith("{"):
        return os.path.dirname(os.path.abspath(str(spec)))
    return None
