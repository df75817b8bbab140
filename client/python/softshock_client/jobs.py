"""Jobs and grids as the client hands them out, and the summary with its older names.

`Job` and `Grid` wrap the protobuf messages: every field reads as on the message (`job.id`,
`job.progress.fraction`, `job.HasField("start_time")`), but `state` is a `JobState`, an IntEnum:
it prints as its name (``RUNNING``) and still compares equal to the number and to
``service_pb2.RUNNING``. The message itself is `.proto`. A state newer than this client stays a
plain int (clients must tolerate states they do not know).

`Summary` is the dict `Client.summary` returns: the figures by the names `softshock-solve`
prints (units in the name: ``energy_injected_J_per_m``, ``shock_at_center_s``, ``grind_ns``),
also as attributes (``s.max_abar``); the names they had before (``energy_injected``,
``shock_at_center``, ``grind_time``, ``groups["time_scale"]``, ...) still read the same values.
"""
from __future__ import annotations

import enum
from typing import Union

# Old name -> today's: the former names of the daemon's table of figures
# (Client.summary_figures(); solver/summary_figures.cpp), kept here so a Summary reads them offline.
RENAMED_SUMMARY_NAMES = {
    "wall_time": "wall_time_s",
    "end_time": "end_time_s",
    "time_scale": "time_scale_s",
    "energy_injected": "energy_injected_J_per_m",
    "energy_after_pulse": "energy_after_pulse_J_per_m",
    "shock_at_center": "shock_at_center_s",
    "rim_reflections": "rim_reflections_s",
    "min_dt": "min_dt_s",
    "max_dt": "max_dt_s",
    "kernel_time": "kernel_time_s",
    "grind_time": "grind_ns",
    "kernel_grind_time": "kernel_grind_ns",
    "meshing_time": "meshing_time_s",
    "aspect_ratio_above_10": "aspect_ratio_above_10_s",
    "diagnostics_time": "diagnostics_time_s",
    "output_time": "output_time_s",
}


class JobState(enum.IntEnum):
    """softshock.v1.JobState as a Python enum: ``str(JobState.RUNNING) == "RUNNING"`` and
    ``JobState.RUNNING == 2``."""

    JOB_STATE_UNSPECIFIED = 0
    QUEUED = 1
    RUNNING = 2
    SUCCEEDED = 3
    FAILED = 4
    CANCELLED = 5

    def __str__(self) -> str:
        return self.name

    @property
    def terminal(self) -> bool:
        """True for SUCCEEDED, FAILED and CANCELLED, which never change."""
        return self in (JobState.SUCCEEDED, JobState.FAILED, JobState.CANCELLED)


def job_state(value: int) -> Union[JobState, int]:
    """The JobState of a number; a number this client does not know stays an int."""
    try:
        return JobState(value)
    except ValueError:
        return value


class _Wrapped:
    """A protobuf message whose `state` reads as a JobState; everything else is the message's."""

    __slots__ = ("_message",)

    def __init__(self, message):
        object.__setattr__(self, "_message", message)

    @property
    def proto(self):
        """The protobuf message itself (to pass to protobuf's own functions)."""
        return self._message

    @property
    def state(self) -> Union[JobState, int]:
        """The state as a JobState (prints as its name, equals its number)."""
        return job_state(self._message.state)

    def __getattr__(self, name):
        if name == "_message":  # not set yet (copy, pickle): no recursion
            raise AttributeError(name)
        return getattr(self._message, name)

    def __setattr__(self, name, value):
        setattr(self._message, name, value)

    def __eq__(self, other):
        other = other._message if isinstance(other, _Wrapped) else other
        return self._message == other

    def __hash__(self):
        return hash(self._message.SerializeToString(deterministic=True))

    def __repr__(self) -> str:
        return f"{type(self).__name__}(id={self._message.id!r}, state={self.state!s})"


class Job(_Wrapped):
    """A softshock.v1.Job (see the module's doc): `id`, `state` (a JobState), `spec`, `labels`,
    `progress`, `owner`, `reason`, `error`, the times, ...; `.proto` is the message."""

    __slots__ = ()


class Grid(_Wrapped):
    """A softshock.v1.Grid (see the module's doc): `id`, `state` (a JobState), `counts`, `axes`,
    `progress`, `owner`, ...; `.proto` is the message."""

    __slots__ = ()


class Summary(dict):
    """The run's figures by name (dict and attributes); older names read the renamed figures
    (energy_injected -> energy_injected_J_per_m, ...; docs/api.md, "Summary names")."""

    def __missing__(self, key):
        renamed = RENAMED_SUMMARY_NAMES.get(key)
        if renamed is not None and renamed in self:
            return self[renamed]
        raise KeyError(key)

    def get(self, key, default=None):
        """As dict.get, for today's and the older names."""
        try:
            return self[key]
        except KeyError:
            return default

    def __getattr__(self, name):
        try:
            return self[name]
        except KeyError:
            raise AttributeError(name) from None


def summary_dict(values: dict) -> Summary:
    """A Summary of message_to_dict's output; nested dicts (groups) alias their names too."""
    return Summary({k: summary_dict(v) if isinstance(v, dict) else v for k, v in values.items()})
