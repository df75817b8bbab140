"""A finished job's files brought to this machine (DownloadResult; `softshock fetch` does the
same): result.h5, result.xdmf, spec.json and summary.json.

Each file arrives as NAME.part and becomes NAME (os.replace) only once its SHA-256 equals the one
the daemon sends. A NAME.part left by an interrupted download is continued from its size; a NAME
that already has the daemon's digest is left alone. The daemon sends at most 64 MiB per call, so
the loop asks again from the size it holds: a call cut short keeps what it brought.
"""
from __future__ import annotations

import hashlib
import os
import re
import time
from dataclasses import dataclass
from typing import Callable, Dict, Iterable, Optional

import grpc

from softshock.v1 import service_pb2

FILES = {"h5": service_pb2.RESULT_H5, "xdmf": service_pb2.RESULT_XDMF,
         "spec": service_pb2.SPEC, "summary": service_pb2.SUMMARY}
_TRANSIENT = (grpc.StatusCode.UNAVAILABLE, grpc.StatusCode.DEADLINE_EXCEEDED,
              grpc.StatusCode.RESOURCE_EXHAUSTED)


class DownloadError(Exception):
    """A download that cannot finish: `code` is the grpc.StatusCode (None for a checksum that
    does not match), `details` the reason."""

    def __init__(self, code, details: str):
        super().__init__(details if code is None else f"{details} ({code.name})")
        self.code = code
        self.details = details


@dataclass
class Downloaded:
    """One file: where it lies, its size and SHA-256, the bytes a previous download had left
    (`resumed_from`) and what happened ("downloaded", "up to date", "skipped: why")."""

    name: str
    path: str
    size: int
    sha256: str
    resumed_from: int
    outcome: str


def sha256_of(path: str) -> str:
    """Hex SHA-256 of a file, read in 1 MiB blocks."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _size(path: str) -> int:
    try:
        return os.path.getsize(path)
    except OSError:
        return 0


def make_xdmf_relative(path: str) -> bool:
    """Rewrites HDF5 references that name a folder ("/data/jobs/x/result.h5:/mesh") to the file
    beside the XDMF ("result.h5:/mesh"), as ParaView resolves them; True if anything changed."""
    with open(path, encoding="utf-8") as f:
        before = f.read()
    after = re.sub(r'(Format="HDF">\s*)[^<:]*/([^/<:]+\.h5):', r"\1\2:", before)
    if after == before:
        return False
    with open(path + ".tmp", "w", encoding="utf-8") as f:
        f.write(after)
    os.replace(path + ".tmp", path)
    return True


class Downloader:
    """Runs DownloadResult calls for one job. `call(request)` returns the stream (the Client's
    stub with its metadata); `timeout` bounds each call."""

    def __init__(self, call: Callable, job_id: str, directory: str,
                 timeout: Optional[float] = None):
        self._call = call
        self._job = job_id
        self._dir = directory
        self._timeout = timeout

    def _stream(self, kind, offset: int, max_bytes: int, out=None):
        """(info or None, bytes received, the RpcError that ended the call or None)."""
        request = service_pb2.DownloadResultRequest(name=f"jobs/{self._job}", file=kind,
                                                    offset=offset, max_bytes=max_bytes)
        stream = self._call(request, timeout=self._timeout)
        info, received = None, 0
        try:
            for chunk in stream:
                if chunk.HasField("info"):
                    info = chunk.info
                if not chunk.data:
                    continue
                if info is None or out is None or chunk.offset != offset + received:
                    stream.cancel()
                    break
                out.write(chunk.data)
                received += len(chunk.data)
        except grpc.RpcError as exc:
            if exc.code() != grpc.StatusCode.CANCELLED or info is None:
                return info, received, exc
        return info, received, None

    def fetch(self, kind) -> Downloaded:
        """One file (a ResultFileKind), as the module's doc says."""
        info, _, error = self._stream(kind, 0, 1)
        if info is None:
            if error is not None and error.code() == grpc.StatusCode.FAILED_PRECONDITION:
                return Downloaded(service_pb2.ResultFileKind.Name(kind), "", 0, "", 0,
                                  "skipped: " + (error.details() or ""))
            raise DownloadError(error.code() if error else grpc.StatusCode.INTERNAL,
                                error.details() if error else "no file header")
        expected = info
        name = expected.file_name
        if not name or "/" in name or name.startswith("."):
            raise DownloadError(grpc.StatusCode.INTERNAL, f"the daemon named a file {name!r}")
        final = os.path.join(self._dir, name)
        part = final + ".part"
        if _size(final) == expected.size and os.path.exists(final) and \
                sha256_of(final) == expected.sha256:
            if os.path.exists(part):
                os.remove(part)
            return Downloaded(name, final, expected.size, expected.sha256, 0, "up to date")
        have = _size(part)
        if have > expected.size:  # a partial file of something else
            os.remove(part)
            have = 0
        resumed_from, started_over, stalls = have, False, 0
        while True:
            while have < expected.size:
                with open(part, "ab") as out:
                    info, received, error = self._stream(kind, have, 0, out)
                if info is not None and info.sha256 != expected.sha256:
                    if started_over:
                        raise DownloadError(None, f"{name} keeps changing on the daemon")
                    started_over, expected, have = True, info, 0
                    open(part, "wb").close()
                    continue
                have += received
                if error is None:
                    continue
                if error.code() not in _TRANSIENT:
                    raise DownloadError(error.code(), error.details() or "")
                stalls = 0 if received else stalls + 1
                if stalls >= 4:
                    raise DownloadError(error.code(), error.details() or "")
                time.sleep(0.25 * stalls)
            if sha256_of(part) == expected.sha256:
                break
            if resumed_from and not started_over:
                started_over, have = True, 0  # the old part was not this file's: once more
                open(part, "wb").close()
                continue
            raise DownloadError(None, f"{name}: the downloaded bytes' SHA-256 differs from the "
                                      f"daemon's {expected.sha256} ({part} kept)")
        with open(part, "rb+") as f:
            os.fsync(f.fileno())
        os.replace(part, final)
        outcome = "downloaded"
        if started_over and resumed_from:
            outcome += " (the partial file did not match)"
        if kind == service_pb2.RESULT_XDMF and make_xdmf_relative(final):
            outcome += "; HDF5 references made relative"
        return Downloaded(name, final, expected.size, expected.sha256, resumed_from, outcome)


def download(call: Callable, job_id: str, directory: str, files: Iterable[str],
             timeout: Optional[float] = None) -> Dict[str, Downloaded]:
    """The named files ("h5", "xdmf", "spec", "summary") of a job into `directory` (created);
    returns {file name: Downloaded} for those it fetched (skipped ones under their kind's
    name). See Client.download."""
    kinds = []
    for f in files:
        if f not in FILES:
            raise ValueError(f"unknown file {f!r}: one of {', '.join(FILES)}")
        kinds.append(FILES[f])
    os.makedirs(directory, exist_ok=True)
    loader = Downloader(call, job_id, directory, timeout)
    out = {}
    for kind in kinds:
        d = loader.fetch(kind)
        out[d.name] = d
    return out
