"""softshock_client: Python client of softshockd (see client/README.md).

`Client` needs the generated stubs (build/python on PYTHONPATH, or an installed package);
`softshock_client.plots` needs only numpy and matplotlib, and `JobState`/`Summary` nothing at
all, so importing the package itself stays cheap and the CLI's PNG helper works without the
stubs.
"""

__all__ = ["Client", "DownloadError", "FieldData", "Grid", "GridReduction", "Job", "JobState",
           "SeriesDict", "SoftshockError", "SpecError", "Summary", "parse_where", "state_name"]

# Defined here, needing nothing but the standard library.
_FROM_JOBS = ("Grid", "Job", "JobState", "Summary")


def __getattr__(name):
    # Lazy: `python3 -m softshock_client.plots` must not require the gRPC stubs.
    if name in _FROM_JOBS:
        from . import jobs
        return getattr(jobs, name)
    if name == "DownloadError":
        from . import downloads
        return downloads.DownloadError
    if name in __all__:
        from . import client
        return getattr(client, name)
    raise AttributeError(f"module 'softshock_client' has no attribute {name!r}")


def __dir__():
    # The lazy names too: dir(softshock_client) shows Client and the rest of the API.
    return sorted(set(globals()) | set(__all__))
