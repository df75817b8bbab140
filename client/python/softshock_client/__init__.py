"""softshock_client: Python client of softshockd (see client/README.md).

`Client` needs the generated stubs (build/python on PYTHONPATH); `softshock_client.plots`
needs only numpy and matplotlib, so importing the package itself stays cheap and the CLI's
PNG helper works without the stubs.
"""

__all__ = ["Client", "FieldData", "GridReduction", "SeriesDict", "SoftshockError", "SpecError",
           "parse_where", "state_name"]


def __getattr__(name):
    # Lazy: `python3 -m softshock_client.plots` must not require the gRPC stubs.
    if name in __all__:
        from . import client
        return getattr(client, name)
    raise AttributeError(name)
