"""Python client of softshockd, the softshock simulation daemon (API: proto/softshock/v1).

The generated stubs are built, not committed::

    cmake --build build --target softshock_python
    export PYTHONPATH=$PWD/build/python:$PWD/client/python
    /usr/bin/python3 -c 'import softshock_client'

Example::

    from softshock_client import Client
    with Client("127.0.0.1:50051") as c:
        job = c.submit({"run": {"endTime": 2e-8}}, labels={"study": "demo"}, wait=True)
        print(c.summary(job.id)["max_abar"])
        series = c.series(job.id)            # {"time": array, "abar": array, ...}
        raster = c.field(job.id, "mean_stress", raster=(256, 256))
"""

from __future__ import annotations

import json
import os
import time
import uuid
from dataclasses import dataclass, field as dc_field
from typing import Dict, Iterator, List, Mapping, Optional, Sequence, Tuple, Union

import grpc
import numpy as np
from google.protobuf import json_format

try:
    from softshock.v1 import service_pb2, service_pb2_grpc, spec_pb2
    from softshock_health import health_pb2, health_pb2_grpc
except ImportError as exc:  # pragma: no cover - depends on the environment
    raise ImportError(
        "softshock_client needs the stubs generated from proto/: install the package "
        "(pip install --no-build-isolation client/python generates them) or run "
        "`cmake --build build --target softshock_python` and put build/python on PYTHONPATH "
        "(PYTHONPATH=build/python:client/python)") from exc

from .downloads import Downloaded, DownloadError, download as _download  # noqa: E402
from .jobs import Grid, Job, JobState, Summary, job_state, summary_dict  # noqa: E402
from .meshes import local_mesh_file, spec_dir, upload_requests  # noqa: E402 (needs the stubs)

DEFAULT_SERVER = "127.0.0.1:50051"
TERMINAL_STATES = frozenset(
    {service_pb2.SUCCEEDED, service_pb2.FAILED, service_pb2.CANCELLED})


class SoftshockError(Exception):
    """A failed call: `code` is the grpc.StatusCode, `details` the server's message."""

    def __init__(self, code: grpc.StatusCode, details: str):
        super().__init__(f"{details} ({code.name})")
        self.code = code
        self.details = details


class SpecError(ValueError):
    """The run spec could not be read or parsed (found before anything is sent)."""


def state_name(state_or_job) -> str:
    """Name of a JobState value (or of a Job's state); tolerates values newer than this client."""
    value = int(getattr(state_or_job, "state", state_or_job))
    try:
        return service_pb2.JobState.Name(value)
    except ValueError:
        return f"JobState({value})"


class SeriesDict(dict):
    """name -> numpy array (with "time" in s); `units` maps each name to its unit string."""

    def __init__(self, *args, units: Optional[Dict[str, str]] = None, **kwargs):
        super().__init__(*args, **kwargs)
        self.units = dict(units or {})

    def to_xarray(self, job_id: str = ""):
        """An xarray Dataset over time, units as attributes (needs python3-xarray)."""
        from .xarray_views import series_dataset
        return series_dataset(self, job_id)


@dataclass
class GridReduction:
    """One scalar per grid point as an N-D array. `values[i, j]` belongs to the point with
    coordinates (axis_values[0][i], axis_values[1][j]); NaN where the point has no result.
    `job_ids` and `states` have the same shape."""

    grid_id: str
    quantity: str
    units: str
    tbar: float
    axis_names: List[str]
    axis_values: List[np.ndarray]
    values: np.ndarray
    job_ids: np.ndarray
    states: np.ndarray

    def __array__(self, dtype=None):
        return self.values if dtype is None else self.values.astype(dtype)

    def to_xarray(self):
        """An xarray DataArray over the grid's axes (needs python3-xarray)."""
        from .xarray_views import reduction_dataarray
        return reduction_dataarray(self)


# QueryJobs filters from text: "pbar>=0.5", "gamma>6", "pbar=0.5..1.5".
_WHERE_OPS = (">=", "<=", "==", ">", "<", "=")


def parse_where(text: str):
    """A RangeFilter from "NAME OP VALUE" (OP one of < <= > >= =) or "NAME=A..B"."""
    for op in _WHERE_OPS:
        at = text.find(op)
        if at > 0:
            name, value = text[:at].strip(), text[at + len(op):].strip()
            f = service_pb2.RangeFilter(name=name)
            if op in ("=", "=="):
                if ".." in value:
                    lo, hi = value.split("..", 1)
                    f.ge, f.le = float(lo), float(hi)
                else:
                    v = float(value)
                    f.ge, f.le = v - 1e-9 * abs(v), v + 1e-9 * abs(v)
            else:
                setattr(f, {">": "gt", ">=": "ge", "<": "lt", "<=": "le"}[op], float(value))
            return f
    raise ValueError(f"not a filter: {text!r} (expected NAME OP VALUE, e.g. 'gamma>6')")


def _grid_axis(axis) -> "service_pb2.GridAxis":
    """A GridAxis from a message or a dict {"name", "values" | "linspace" | "geomspace"};
    a span may be a (start, stop, num) tuple or a dict."""
    if isinstance(axis, service_pb2.GridAxis):
        return axis
    out = service_pb2.GridAxis(name=axis["name"])
    if "values" in axis:
        out.values.extend(float(v) for v in axis["values"])
    for kind in ("linspace", "geomspace"):
        if kind in axis:
            span = axis[kind]
            if not isinstance(span, Mapping):
                span = dict(zip(("start", "stop", "num"), span))
            getattr(out, kind).CopyFrom(service_pb2.Span(
                start=float(span["start"]), stop=float(span["stop"]), num=int(span["num"])))
    return out


@dataclass
class FieldData:
    """A field frame. `values` is (ny, nx) for scalar rasters, (ny, nx, d) for vector rasters
    (d = 2 in 2-D, 3 in 3-D), (n,) or (n, d) for node/element samples. Raster cells outside the
    body are NaN. `extent` is (x_min, x_max, y_min, y_max) in m for rasters, else None; for a 3-D
    result's slice these are along the plane's axes `slice_u` and `slice_v` from `slice_origin`
    (cell (i, j)'s centre: origin + u_i * slice_u + v_j * slice_v). A 3-D "surface" carries the
    decimated deformed boundary: `vertices` (n, 3) in m, `triangles` (t, 3) vertex indices, and
    `values` per vertex (node fields) or per triangle (element fields).

    Unpacks as ``values, extent = client.field(...)`` and converts with ``np.asarray``.
    """

    values: np.ndarray
    extent: Optional[Tuple[float, float, float, float]]
    name: str
    units: str
    time: float
    frame: int
    location: str
    every: int = 1
    header: object = dc_field(default=None, repr=False)
    dimension: int = 2
    slice_origin: Optional[Tuple[float, float, float]] = None
    slice_u: Optional[Tuple[float, float, float]] = None
    slice_v: Optional[Tuple[float, float, float]] = None
    vertices: Optional[np.ndarray] = None
    triangles: Optional[np.ndarray] = None

    def to_xarray(self):
        """A raster as an xarray.DataArray with coordinates x and y (the slice's u and v in 3-D)
        in m and the time as an attribute."""
        import xarray as xr
        if self.location != "raster":
            raise ValueError("to_xarray needs a raster (raster=(nx, ny))")
        ny, nx = self.values.shape[:2]
        x_min, x_max, y_min, y_max = self.extent
        coords = {"y": y_min + (np.arange(ny) + 0.5) * (y_max - y_min) / ny,
                  "x": x_min + (np.arange(nx) + 0.5) * (x_max - x_min) / nx}
        dims = ("y", "x") + (("component",) if self.values.ndim == 3 else ())
        attrs = {"units": self.units, "time_s": self.time, "frame": self.frame}
        if self.slice_origin is not None:
            attrs.update(slice_origin=self.slice_origin, slice_u=self.slice_u,
                         slice_v=self.slice_v)
        return xr.DataArray(self.values, coords=coords, dims=dims, name=self.name, attrs=attrs)

    def __iter__(self):
        return iter((self.values, self.extent))

    def __array__(self, dtype=None):
        return self.values if dtype is None else self.values.astype(dtype)


def message_to_dict(message) -> dict:
    """Fields (defaults included) by proto name with Python values. Unlike json_format, int64
    stays int rather than becoming a string (the JSON mapping's rule for 64-bit integers)."""
    out = {}
    for f in message.DESCRIPTOR.fields:
        value = getattr(message, f.name)
        if f.message_type is not None and f.label != f.LABEL_REPEATED:
            value = message_to_dict(value)
        elif f.label == f.LABEL_REPEATED:
            value = [message_to_dict(v) if f.message_type is not None else v for v in value]
        out[f.name] = value
    return out


def load_spec(spec) -> spec_pb2.RunSpec:
    """A RunSpec from a dict (protobuf JSON mapping), a path to a JSON file, a JSON string or a
    RunSpec message. Unknown fields are errors: a misspelt key must not become a default."""
    if isinstance(spec, spec_pb2.RunSpec):
        return spec
    source = "spec"
    if isinstance(spec, (str, os.PathLike)):
        text = str(spec)
        if not text.lstrip().startswith("{"):
            source = text
            try:
                with open(text, encoding="utf-8") as f:
                    text = f.read()
            except OSError as exc:
                raise SpecError(f"{source}: {exc.strerror}") from exc
        try:
            spec = json.loads(text)
        except json.JSONDecodeError as exc:
            raise SpecError(f"{source}: not JSON: {exc}") from exc
    if not isinstance(spec, dict):
        raise SpecError(f"{source}: expected a JSON object, got {type(spec).__name__}")
    try:
        return json_format.ParseDict(spec, spec_pb2.RunSpec(), ignore_unknown_fields=False)
    except json_format.ParseError as exc:
        raise SpecError(f"{source}: not a valid run spec: {exc}") from exc


class Client:
    """Connection to softshockd. Every unary call has a deadline of `timeout` seconds (watch has
    none); UNAVAILABLE is retried briefly (submits carry a request_id, so retries are safe)."""

    def __init__(self, server: Optional[str] = None, token: Optional[str] = None,
                 tls_ca: Optional[Union[str, bytes, os.PathLike]] = None,
                 timeout: Optional[float] = 30):
        self.server = server or os.environ.get("SOFTSHOCK_SERVER") or DEFAULT_SERVER
        self.timeout = timeout
        self._metadata = (("authorization", f"Bearer {token.strip()}"),) if token else ()
        # Field chunks stay well under 1 MiB, but a full ListJobs page (specs included) may not.
        options = [("grpc.max_receive_message_length", 64 * 1024 * 1024)]
        if tls_ca is not None:
            pem = tls_ca
            if not isinstance(pem, bytes):
                with open(pem, "rb") as f:
                    pem = f.read()
            creds = grpc.ssl_channel_credentials(root_certificates=pem)
            self._channel = grpc.secure_channel(self.server, creds, options=options)
        else:
            self._channel = grpc.insecure_channel(self.server, options=options)
        self._stub = service_pb2_grpc.SimulationServiceStub(self._channel)
        self._meshes = service_pb2_grpc.MeshServiceStub(self._channel)
        self._health = health_pb2_grpc.HealthStub(self._channel)

    # -- plumbing ------------------------------------------------------------------------------
    def close(self) -> None:
        """Closes the channel; the client cannot be used afterwards."""
        self._channel.close()

    def __enter__(self) -> "Client":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _call(self, method, request, attempts: int = 4):
        delay = 0.2
        deadline = None if self.timeout is None else time.monotonic() + self.timeout
        for attempt in range(1, attempts + 1):
            try:
                return method(request, timeout=self.timeout, metadata=self._metadata)
            except grpc.RpcError as exc:
                code = exc.code()
                retry = (code == grpc.StatusCode.UNAVAILABLE and attempt < attempts and
                         (deadline is None or time.monotonic() + delay < deadline))
                if not retry:
                    raise SoftshockError(code, exc.details() or "") from None
            time.sleep(delay)
            delay = min(delay * 2, 2.0)
        raise AssertionError("unreachable")

    # -- jobs ----------------------------------------------------------------------------------
    def submit(self, spec, labels: Optional[Dict[str, str]] = None, wait: bool = False,
               priority: int = 0, request_id: Optional[str] = None, reuse_result: bool = False):
        """Submits a run; returns the Job (the final one when wait=True). With reuse_result, an
        identical SUCCEEDED run's result is reused (Job.reused_from) instead of running."""
        request = service_pb2.SubmitJobRequest(
            spec=self._with_uploaded_mesh(load_spec(spec), spec_dir(spec)),
            labels=dict(labels or {}), priority=priority,
            request_id=request_id or str(uuid.uuid4()), reuse_result=reuse_result)
        job = self._call(self._stub.SubmitJob, request)
        if wait:
            return self.wait(job.id)
        return Job(job)

    def extend(self, job_id: str, end_time: float, labels: Optional[Dict[str, str]] = None,
               wait: bool = False, priority: int = 0, request_id: Optional[str] = None):
        """Continues a SUCCEEDED job to a later `end_time` (s) as a new job (its `parent_id` is
        `job_id`), starting from where the parent stopped when its final state was kept
        (docs/api.md, ExtendJob). Returns the new Job (the final one when wait=True)."""
        job = self._call(self._stub.ExtendJob, service_pb2.ExtendJobRequest(
            id=job_id, end_time=end_time, labels=dict(labels or {}), priority=priority,
            request_id=request_id or str(uuid.uuid4())))
        if wait:
            return self.wait(job.id)
        return Job(job)

    def get(self, job_id: str) -> Job:
        """The job (`id` or `jobs/{id}`) with its live progress; `state` is a JobState."""
        return Job(self._call(self._stub.GetJob, service_pb2.GetJobRequest(id=job_id)))

    def list(self, state: Optional[Union[str, int]] = None, label: Optional[str] = None,
             limit: Optional[int] = None, page_size: int = 0,
             owner: Optional[str] = None, created_after=None,
             created_before=None) -> List[Job]:
        """Jobs, newest first, following page tokens until `limit` (None = all). `owner`: only
        that user's jobs (your own: owner=client.whoami()[0]); `created_after` and
        `created_before`: datetimes (naive = UTC) or seconds since the epoch."""
        request = service_pb2.ListJobsRequest(label=label or "", owner=owner or "")
        if state is not None:
            request.state = service_pb2.JobState.Value(state) if isinstance(state, str) else state
        for field, when in (("created_after", created_after), ("created_before", created_before)):
            if when is None:
                continue
            if isinstance(when, (int, float)):
                getattr(request, field).FromNanoseconds(int(when * 1e9))
            else:
                getattr(request, field).FromDatetime(when)
        jobs = []
        while True:
            if limit is not None:
                request.page_size = min(1000, limit - len(jobs))
                if request.page_size <= 0:
                    break
            elif page_size:
                request.page_size = page_size
            page = self._call(self._stub.ListJobs, request)
            jobs.extend(Job(j) for j in page.jobs)
            if not page.next_page_token:
                break
            request.page_token = page.next_page_token
        return jobs if limit is None else jobs[:limit]

    def watch(self, job_id: str, patience: float = 30.0) -> Iterator:
        """Yields the job now and on every change; ends after a terminal state. Reconnects when
        the daemon goes away (jobs survive restarts) for up to `patience` seconds."""
        request = service_pb2.WatchJobRequest(id=job_id)
        lost_since = None
        while True:
            stream = self._stub.WatchJob(request, metadata=self._metadata)
            job = None
            try:
                for job in stream:
                    lost_since = None
                    yield Job(job)
                    if job.state in TERMINAL_STATES:
                        stream.cancel()
                        return
            except grpc.RpcError as exc:
                if exc.code() != grpc.StatusCode.UNAVAILABLE:
                    raise SoftshockError(exc.code(), exc.details() or "") from None
            finally:
                stream.cancel()
            # The stream ended without a terminal state: the server went away. Try again.
            now = time.monotonic()
            lost_since = lost_since or now
            if now - lost_since > patience:
                raise SoftshockError(grpc.StatusCode.UNAVAILABLE,
                                     f"lost softshockd at {self.server} while watching {job_id}")
            time.sleep(0.5)

    def wait(self, job_id: str, timeout: Optional[float] = None):
        """Blocks until the job is terminal; returns the final Job."""
        start = time.monotonic()
        last = None
        for last in self.watch(job_id):
            if timeout is not None and time.monotonic() - start > timeout:
                raise TimeoutError(f"job {job_id} still {state_name(last)} after {timeout} s")
        return last

    def whoami(self) -> Tuple[str, str]:
        """(user, role) the client's token names on the daemon; role is "user" or "admin"."""
        caller = self._call(self._stub.GetCaller, service_pb2.GetCallerRequest())
        return caller.user, caller.role

    def summary_figures(self) -> List[dict]:
        """The summary figures the daemon reports, in its summary's order: dicts with name,
        former_name ("" if none), unit, meaning, in_groups, queryable (a query() name),
        grid_quantity (a grid_reduction() quantity; so is "abar_at" with a t-bar), only_3d,
        only_damage and derived."""
        figures = self._call(self._stub.ListSummaryFigures,
                             service_pb2.ListSummaryFiguresRequest())
        keys = ("name", "former_name", "unit", "meaning", "in_groups", "queryable",
                "grid_quantity", "only_3d", "only_damage", "derived")
        return [{k: getattr(f, k) for k in keys} for f in figures.figures]

    def cancel(self, job_id: str) -> Job:
        """Cancels a queued or running job (your own; an admin: any); returns the job, normally
        CANCELLED (a running job gets up to ~5 s to stop; watch it if it is still RUNNING)."""
        return Job(self._call(self._stub.CancelJob, service_pb2.CancelJobRequest(id=job_id)))

    def delete(self, job_id: str) -> None:
        """Deletes a job and its result files (your own; an admin: any), cancelling it first if
        it has not finished."""
        self._call(self._stub.DeleteJob, service_pb2.DeleteJobRequest(id=job_id))

    def set_labels(self, job_id: str, labels: Optional[Dict[str, str]] = None,
                   remove: Sequence[str] = ()) -> Job:
        """Sets `labels` and removes the keys in `remove` on a job (your own; an admin: any);
        returns the job with its labels as they now are. Keys follow submit's rules (at most 64
        labels); removing a key the job lacks is no error."""
        request = service_pb2.UpdateJobLabelsRequest(name=job_id, set=dict(labels or {}),
                                                     remove=list(remove))
        return Job(self._call(self._stub.UpdateJobLabels, request))

    def download(self, job_id: str, directory: Optional[str] = None,
                 files: Sequence[str] = ("h5", "xdmf", "spec", "summary")) -> Dict[str, str]:
        """Brings a finished job's files to this machine, as `softshock fetch` does:
        result.h5, result.xdmf (ParaView opens it there), spec.json and summary.json into
        `directory` (default ./JOB_ID, created). Resumes a NAME.part an interrupted download left,
        checks every file's SHA-256 against the daemon's, and leaves a file that is already
        there and equal alone. Returns {file name: local path}; `last_download` keeps the
        details (sizes, digests, what happened). Raises SoftshockError for an unfinished job
        or a failed call, DownloadError for a checksum that does not match."""
        job = self.get(job_id)
        if job.state in (JobState.QUEUED, JobState.RUNNING):
            raise SoftshockError(grpc.StatusCode.FAILED_PRECONDITION,
                                 f"job {job.id} is {job.state}: its files can be downloaded "
                                 "once it finished")
        directory = directory or job.id
        call = lambda request, timeout: self._stub.DownloadResult(  # noqa: E731
            request, timeout=timeout, metadata=self._metadata)
        try:
            self.last_download = _download(call, job.id, directory, files, timeout=self.timeout)
        except DownloadError as exc:
            if exc.code is None:
                raise
            raise SoftshockError(exc.code, exc.details) from None
        return {name: d.path for name, d in self.last_download.items() if d.path}

    def health(self, service: str = "") -> str:
        """grpc.health.v1 status name, e.g. "SERVING"."""
        response = self._call(self._health.Check, health_pb2.HealthCheckRequest(service=service))
        return health_pb2.HealthCheckResponse.ServingStatus.Name(response.status)

    def health_warnings(self) -> List[str]:
        """What the daemon warns about its set-up (e.g. a bearer token served without TLS off
        loopback): the `softshock-warning` entries of a health answer's metadata."""
        _, call = self._call(self._health.Check.with_call, health_pb2.HealthCheckRequest())
        return [value for key, value in call.initial_metadata() if key == "softshock-warning"]

    # -- results -------------------------------------------------------------------------------
    def summary(self, job_id: str) -> Summary:
        """The run's figures as a dict (also attributes) by the names softshock-solve prints,
        units in the name (energy_injected_J_per_m, shock_at_center_s, grind_ns, ...); the older
        names (energy_injected, shock_at_center, grind_time, ...) read the same values."""
        s = self._call(self._stub.GetJobSummary, service_pb2.GetJobSummaryRequest(id=job_id))
        return summary_dict(message_to_dict(s))

    def series(self, job_id: str, names: Optional[List[str]] = None,
               every: Optional[int] = None) -> SeriesDict:
        """The scalar histories of a finished job: {"time": s, "abar": ..., "kinetic_energy":
        ..., ...} as numpy arrays (`names`: only these; `every`: every k-th sample), units in
        `.units`."""
        ts = self._call(self._stub.GetTimeSeries, service_pb2.GetTimeSeriesRequest(
            id=job_id, names=list(names or []), every=every or 0))
        out = SeriesDict(units={"time": "s"})
        out["time"] = np.asarray(ts.time, dtype=float)
        for s in ts.series:
            out[s.name] = np.asarray(s.values, dtype=float)
            out.units[s.name] = s.units
        return out

    def modes(self, job_id: str, every: Optional[int] = None, mode_min: Optional[int] = None,
              mode_max: Optional[int] = None) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(time in s, mode numbers, amplitude / R0 as a len(time) x len(modes) array)."""
        m = self._call(self._stub.GetModes, service_pb2.GetModesRequest(
            id=job_id, every=every or 0, mode_min=mode_min or 0, mode_max=mode_max or 0))
        t = np.asarray(m.time, dtype=float)
        amp = np.asarray(m.amplitude, dtype=float)
        if amp.size != t.size * m.mode_count:
            raise SoftshockError(grpc.StatusCode.INTERNAL,
                                 f"{amp.size} amplitudes for {t.size} x {m.mode_count}")
        return t, np.arange(m.mode_min, m.mode_min + m.mode_count), amp.reshape(t.size,
                                                                                 m.mode_count)

    def modes_xarray(self, job_id: str, **kw):
        """modes() as an xarray DataArray over (time, mode) (needs python3-xarray)."""
        from .xarray_views import modes_dataarray
        return modes_dataarray(*self.modes(job_id, **kw), job_id=job_id)

    def field(self, job_id: str, name: str, time: Optional[float] = None,
              frame: Optional[int] = None, raster: Optional[Tuple[int, int]] = None,
              every: Optional[int] = None, slice=None,
              surface: Optional[int] = None) -> FieldData:
        """A field frame (nearest to `time` in s, or index `frame`; default the last one), either
        interpolated on an nx x ny raster over the deformed body or every k-th node/element.
        3-D results: the raster samples the plane `slice` = (point, normal) in m (default z = 0);
        `surface=N` gives the deformed boundary decimated to at most N triangles (0 = the
        server's default)."""
        if time is not None and frame is not None:
            raise ValueError("give time or frame, not both")
        if sum(x is not None for x in (raster, every, surface)) > 1:
            raise ValueError("give one of raster, every and surface")
        request = service_pb2.GetFieldRequest(id=job_id, name=name)
        if slice is not None:
            (px, py, pz), (nx, ny, nz) = slice
            request.slice.CopyFrom(service_pb2.Slice(px=px, py=py, pz=pz, nx=nx, ny=ny, nz=nz))
            if raster is None:
                raster = (256, 256)
        if surface is not None:
            request.surface.max_triangles = int(surface)
        if time is not None:
            request.time = time
        if frame is not None:
            request.frame = frame
        if raster is not None:
            request.raster.nx, request.raster.ny = int(raster[0]), int(raster[1])
        if every is not None:
            request.every = every
        try:
            chunks = self._stub.GetField(request, timeout=self.timeout, metadata=self._metadata)
            header, values, seen = None, None, 0
            for chunk in chunks:
                if chunk.HasField("header"):
                    header = chunk.header
                    values = np.full(header.value_count, np.nan)
                if header is None:
                    raise SoftshockError(grpc.StatusCode.INTERNAL, "field values before header")
                n = len(chunk.values)
                if chunk.offset < 0 or chunk.offset + n > values.size:
                    raise SoftshockError(grpc.StatusCode.INTERNAL,
                                         f"field chunk at {chunk.offset} overruns {values.size}")
                values[chunk.offset:chunk.offset + n] = chunk.values
                seen += n
        except grpc.RpcError as exc:
            raise SoftshockError(exc.code(), exc.details() or "") from None
        if header is None:
            raise SoftshockError(grpc.StatusCode.INTERNAL, "field stream without header")
        if seen != values.size:
            raise SoftshockError(grpc.StatusCode.INTERNAL,
                                 f"field stream carried {seen} of {values.size} values")
        comps = max(1, header.components)
        extent = None
        extra = {"dimension": header.dimension or 2}
        if header.location == "raster":
            shape = (header.ny, header.nx) + ((comps,) if comps > 1 else ())
            values = values.reshape(shape)
            extent = (header.x_min, header.x_max, header.y_min, header.y_max)
            if len(header.slice_origin) == 3:
                extra.update(slice_origin=tuple(header.slice_origin),
                             slice_u=tuple(header.slice_u), slice_v=tuple(header.slice_v))
        elif header.location == "surface":
            nv, nt = header.surface_vertices, header.surface_triangles
            extra["vertices"] = values[:3 * nv].reshape(nv, 3)
            extra["triangles"] = values[3 * nv:3 * (nv + nt)].astype(np.int64).reshape(nt, 3)
            values = values[3 * (nv + nt):]
            if comps > 1:
                values = values.reshape(-1, comps)
        elif comps > 1:
            values = values.reshape(-1, comps)
        return FieldData(values=values, extent=extent, name=header.name, units=header.units,
                         time=header.time, frame=header.frame, location=header.location,
                         every=max(1, header.every), header=header, **extra)

    # -- grids -----------------------------------------------------------------------------------
    def submit_grid(self, base_spec=None, axes: Sequence = (),
                    labels: Optional[Dict[str, str]] = None, priority: int = 0,
                    request_id: Optional[str] = None, recompute: bool = False,
                    wait: bool = False, grid_file=None):
        """Submits a grid: a base spec (as for submit) and 1-3 axes (dicts or GridAxis), or a
        grid file (JSON of SubmitGridRequest, as `softshock grid submit` reads). Returns the
        Grid (the final one when wait=True)."""
        if grid_file is not None:
            with open(grid_file, encoding="utf-8") as f:
                request = json_format.Parse(f.read(), service_pb2.SubmitGridRequest())
            base_dir = spec_dir(grid_file)
        else:
            request = service_pb2.SubmitGridRequest(base_spec=load_spec(base_spec or {}))
            request.axes.extend(_grid_axis(a) for a in axes)
            base_dir = spec_dir(base_spec)
        self._with_uploaded_mesh(request.base_spec, base_dir)
        request.labels.update(labels or {})
        request.priority = priority or request.priority
        request.recompute = recompute or request.recompute
        request.request_id = request_id or request.request_id or str(uuid.uuid4())
        grid = self._call(self._stub.SubmitGrid, request)
        return self.wait_grid(grid.id) if wait else Grid(grid)

    # -- meshes --------------------------------------------------------------------------------
    def upload_mesh(self, path: str):
        """Uploads a Gmsh .msh file; returns the Mesh (id = SHA-256 of the bytes; uploading
        the same bytes again returns the same mesh). Use it as {"geometry": {"meshId": id}}."""
        return self._call(lambda _, **kw: self._meshes.UploadMesh(upload_requests(path), **kw),
                          None)

    def list_meshes(self, owner: Optional[str] = None) -> List:
        """Uploaded meshes by id; `owner`: only that user's."""
        out, token, owner = [], "", owner or ""
        while True:
            page = self._call(self._meshes.ListMeshes,
                              service_pb2.ListMeshesRequest(page_size=1000, page_token=token,
                                                            owner=owner))
            out.extend(page.meshes)
            token = page.next_page_token
            if not token:
                return out

    def delete_mesh(self, mesh_id: str) -> None:
        """Refused (FAILED_PRECONDITION) while a queued or running job uses the mesh, and
        (PERMISSION_DENIED) for another user's mesh unless the caller is an admin."""
        self._call(self._meshes.DeleteMesh, service_pb2.DeleteMeshRequest(name=mesh_id))

    def _with_uploaded_mesh(self, spec, base_dir):
        """Uploads a local geometry.mesh_file (see softshock_client.meshes) and names it by id."""
        try:
            path = local_mesh_file(spec, base_dir)
        except FileNotFoundError as exc:
            raise SpecError(str(exc)) from None
        if path is not None:
            mesh_id = self.upload_mesh(path).id
            spec.geometry.ClearField("shape")
            spec.geometry.mesh_id = mesh_id
        return spec

    def grid(self, grid_id: str) -> Grid:
        """The grid with its live counts and progress; `state` is a JobState."""
        return Grid(self._call(self._stub.GetGrid, service_pb2.GetGridRequest(id=grid_id)))

    def list_grids(self, owner: Optional[str] = None) -> List[Grid]:
        """Every grid, newest first (`owner`: only that user's)."""
        request = service_pb2.ListGridsRequest(page_size=1000, owner=owner or "")
        grids = []
        while True:
            page = self._call(self._stub.ListGrids, request)
            grids.extend(Grid(g) for g in page.grids)
            if not page.next_page_token:
                return grids
            request.page_token = page.next_page_token

    def cancel_grid(self, grid_id: str) -> Grid:
        """Cancels every unfinished point (finished ones keep their results); returns the grid."""
        return Grid(self._call(self._stub.CancelGrid, service_pb2.CancelGridRequest(id=grid_id)))

    def wait_grid(self, grid_id: str, timeout: Optional[float] = None, poll: float = 0.5):
        """Polls until every point of the grid finished; returns the final Grid."""
        start = time.monotonic()
        while True:
            grid = self.grid(grid_id)
            if grid.state in TERMINAL_STATES:
                return grid
            if timeout is not None and time.monotonic() - start > timeout:
                raise TimeoutError(f"grid {grid_id} still {state_name(grid)} after {timeout} s")
            time.sleep(poll)

    def grid_reduction(self, grid_id: str, quantity: str = "max_abar_first_cycle",
                       tbar: Optional[float] = None) -> GridReduction:
        """One scalar per point as an N-D numpy array with its axes (see GridReduction)."""
        request = service_pb2.GetGridReductionRequest(id=grid_id, quantity=quantity)
        if tbar is not None:
            request.tbar = tbar
        r = self._call(self._stub.GetGridReduction, request)
        shape = tuple(r.shape)
        return GridReduction(
            grid_id=r.grid_id, quantity=r.quantity, units=r.units, tbar=r.tbar,
            axis_names=[a.name for a in r.axes],
            axis_values=[np.asarray(a.values, dtype=float) for a in r.axes],
            values=np.asarray(r.values, dtype=float).reshape(shape),
            job_ids=np.asarray(list(r.job_ids), dtype=object).reshape(shape),
            states=np.asarray([state_name(s) for s in r.states], dtype=object).reshape(shape))

    # -- result database -------------------------------------------------------------------------
    def query(self, where: Sequence = (), state: Optional[Union[str, int]] = None,
              grid_id: Optional[str] = None, order_by: Optional[str] = None,
              limit: Optional[int] = None, owner: Optional[str] = None) -> List[dict]:
        """Catalogued jobs whose groups and summary figures pass every filter ("pbar>=0.5",
        "gamma>6", "max_abar_first_cycle>0.01", "pbar=0.5..1.5" or RangeFilter messages),
        sorted by `order_by` ("max_abar desc"); answered from the catalogue alone. Each row is
        a dict: id, state, owner, grid_id, grid_index, reused_from, the groups by name (NaN if
        not known) and "summary" (a dict, or None for unfinished jobs). `owner`: only that
        user's jobs."""
        request = service_pb2.QueryJobsRequest(grid_id=grid_id or "", order_by=order_by or "",
                                               owner=owner or "")
        request.filters.extend(w if isinstance(w, service_pb2.RangeFilter) else parse_where(w)
                               for w in where)
        if state is not None:
            request.state = service_pb2.JobState.Value(state) if isinstance(state, str) else state
        rows = []
        while True:
            request.page_size = 1000 if limit is None else max(1, min(1000, limit - len(rows)))
            page = self._call(self._stub.QueryJobs, request)
            for q in page.jobs:
                row = {"id": q.job.id, "state": state_name(q.job), "owner": q.job.owner,
                       "grid_id": q.job.grid_id,
                       "grid_index": q.job.grid_index, "reused_from": q.job.reused_from}
                row.update({k: v for k, v in message_to_dict(q.groups).items()})
                row["summary"] = (summary_dict(message_to_dict(q.summary))
                                  if q.HasField("summary") else None)
                rows.append(Summary(row))
            if not page.next_page_token or (limit is not None and len(rows) >= limit):
                return rows if limit is None else rows[:limit]
            request.page_token = page.next_page_token

    def abar_series(self, job_ids: Sequence[str]) -> Tuple[List[SeriesDict], Optional[float]]:
        """Ā(t) of several jobs and their common time scale R0/c0 (None when they differ), for
        plots.plot_abar."""
        series = [self.series(j, names=["abar"]) for j in job_ids]
        scales = {self.summary(j)["groups"]["time_scale_s"] for j in job_ids}
        return series, (scales.pop() if len(scales) == 1 else None)
