"""Build step of the softshock-client distribution (metadata: pyproject.toml).

build_py also generates the gRPC stubs into the build: `softshock.v1` from the repository's
proto/ (or $SOFTSHOCK_PROTO_DIR) and `softshock_health` from grpc-proto's health.proto, with
the system protoc and gRPC's Python plugin (Debian's grpc_tools bundles a protoc too old for
proto3 `optional`). Nothing generated is committed.
"""
import os
import shutil
import subprocess
import tempfile

from setuptools import setup
from setuptools.command.build_py import build_py

HERE = os.path.dirname(os.path.abspath(__file__))
PROTO_DIR = os.environ.get("SOFTSHOCK_PROTO_DIR", os.path.join(HERE, "..", "..", "proto"))
GRPC_PROTO_DIR = os.environ.get("SOFTSHOCK_GRPC_PROTO_DIR", "/usr/share/grpc-proto")
PLUGIN = shutil.which("grpc_python_plugin") or "/usr/bin/grpc_python_plugin"
API = ["softshock/v1/spec.proto", "softshock/v1/service.proto"]


def protoc(include, out, files):
    cmd = ["protoc", "-I", include, f"--python_out={out}", f"--pyi_out={out}",
           f"--grpc_python_out={out}", f"--plugin=protoc-gen-grpc_python={PLUGIN}"] + files
    subprocess.run(cmd, check=True)


class BuildPyWithStubs(build_py):
    def run(self):
        super().run()
        for f in API:
            if not os.path.isfile(os.path.join(PROTO_DIR, f)):
                raise SystemExit(f"softshock-client: {f} not found under {PROTO_DIR}; build from "
                                 "the softshock repository or set SOFTSHOCK_PROTO_DIR")
        protoc(PROTO_DIR, self.build_lib, API)
        # health.proto under a package of our own: generated as grpc/health/v1 it would sit in
        # grpcio's `grpc` package. The descriptor keeps grpc.health.v1, so wire names are equal.
        with tempfile.TemporaryDirectory() as tmp:
            os.makedirs(os.path.join(tmp, "softshock_health"))
            shutil.copy(os.path.join(GRPC_PROTO_DIR, "grpc/health/v1/health.proto"),
                        os.path.join(tmp, "softshock_health", "health.proto"))
            protoc(tmp, self.build_lib, ["softshock_health/health.proto"])
        for package in ("softshock", "softshock/v1", "softshock_health"):
            open(os.path.join(self.build_lib, package, "__init__.py"), "a").close()


setup(cmdclass={"build_py": BuildPyWithStubs})
