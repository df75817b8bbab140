"""The client's results as xarray objects, coordinates and variables carrying `units` attributes.

Needs xarray (Debian: python3-xarray); imported only when one of these is called, so the rest of
softshock_client works without it. Used by SeriesDict.to_xarray(), GridReduction.to_xarray() and
Client.modes_xarray().
"""
from __future__ import annotations

import numpy as np

# Grid axes are spec field paths or nondimensional groups; their units by the field's last name.
_GROUPS = {"pbar", "tbar_pulse", "mubar", "gamma", "c1", "c2"}
_SPEC_UNITS = {
    "pressure": "Pa", "bulk_modulus": "Pa", "shear_modulus": "Pa", "density": "kg/m^3",
    "duration": "s", "end_time": "s", "output_interval": "s", "history_interval": "s",
    "radius": "m", "side": "m", "corner_radius": "m", "tait_gamma": "1", "c1": "1", "c2": "1",
    "cfl": "1", "target_elements": "1",
}


def _xr():
    try:
        import xarray
    except ImportError as exc:
        raise ImportError("xarray is not installed (Debian: apt install python3-xarray)") from exc
    return xarray


def axis_units(name: str) -> str:
    """Units of a grid axis: "1" for groups, the spec field's unit, "" when unknown."""
    if name in _GROUPS:
        return "1"
    leaf = name.replace("-", "_").split(".")[-1]
    leaf = "".join("_" + c.lower() if c.isupper() else c for c in leaf)  # JSON spelling
    return _SPEC_UNITS.get(leaf, "")


def series_dataset(series, job_id: str = ""):
    """A SeriesDict as a Dataset over `time` (s), one variable per series with its units."""
    xr = _xr()
    time = xr.Variable("time", series["time"], {"units": series.units.get("time", "s"),
                                                "long_name": "time"})
    data = {name: xr.Variable("time", values, {"units": series.units.get(name, "")})
            for name, values in series.items() if name != "time"}
    return xr.Dataset(data, coords={"time": time}, attrs={"job_id": job_id} if job_id else {})


def modes_dataarray(time, modes, amplitude, job_id: str = ""):
    """Rim Fourier amplitudes / R0 over (time [s], mode [1])."""
    xr = _xr()
    return xr.DataArray(
        np.asarray(amplitude), dims=("time", "mode"),
        coords={"time": ("time", np.asarray(time), {"units": "s"}),
                "mode": ("mode", np.asarray(modes), {"units": "1"})},
        name="amplitude",
        attrs={"units": "1", "long_name": "rim radial displacement mode amplitude / R0",
               **({"job_id": job_id} if job_id else {})})


def reduction_dataarray(red):
    """A GridReduction over its axes (coordinates with units), job ids and states alongside."""
    xr = _xr()
    dims = tuple(red.axis_names)
    coords = {name: (name, values, {"units": axis_units(name)})
              for name, values in zip(red.axis_names, red.axis_values)}
    coords["job_id"] = (dims, red.job_ids)
    coords["state"] = (dims, red.states)
    attrs = {"units": red.units, "grid_id": red.grid_id}
    if red.quantity == "abar_at":
        attrs["tbar"] = red.tbar
    return xr.DataArray(red.values, dims=dims, coords=coords, name=red.quantity, attrs=attrs)
