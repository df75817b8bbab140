#!/usr/bin/python3
"""A generic gRPC client that knows a server only through server reflection (like grpcurl or
`buf curl`): no softshock stubs, only grpcio, protobuf and grpc-proto's reflection.proto.

Usage:
    reflection_client.py ADDRESS list                      # services, one per line
    reflection_client.py ADDRESS describe SERVICE          # its methods
    reflection_client.py ADDRESS call SERVICE/METHOD JSON  # JSON in, JSON out (one line per
                                                           # message of a server stream)
Option --token T sends `authorization: Bearer T`. A failed call prints `CODE: details` on stderr
and exits 1.
"""
import argparse
import importlib
import json
import os
import shutil
import subprocess
import sys
import tempfile

import grpc
from google.protobuf import descriptor_pb2, descriptor_pool, json_format, message_factory

REFLECTION_PROTO = "/usr/share/grpc-proto/grpc/reflection/v1alpha/reflection.proto"
REFLECTION_METHOD = "/grpc.reflection.v1alpha.ServerReflection/ServerReflectionInfo"


def reflection_messages():
    """reflection.proto's messages, generated now with the system protoc (under a package name
    of our own: generated as grpc/reflection/... they would clash with grpcio's `grpc`)."""
    gen = tempfile.mkdtemp(prefix="reflection-stubs-")
    try:
        os.makedirs(os.path.join(gen, "generic_reflection"))
        shutil.copy(REFLECTION_PROTO, os.path.join(gen, "generic_reflection", "reflection.proto"))
        subprocess.run(["protoc", "-I", gen, f"--python_out={gen}",
                        "generic_reflection/reflection.proto"], check=True)
        sys.path.insert(0, gen)
        return importlib.import_module("generic_reflection.reflection_pb2")
    finally:
        if gen in sys.path:
            sys.path.remove(gen)
        shutil.rmtree(gen, ignore_errors=True)  # the module is loaded; its files can go


class ReflectionClient:
    def __init__(self, address, token=None):
        self.channel = grpc.insecure_channel(address)
        self.metadata = [("authorization", f"Bearer {token}")] if token else []
        self.pb = reflection_messages()
        self.pool = descriptor_pool.DescriptorPool()
        self.added = set()
        self.info = self.channel.stream_stream(
            REFLECTION_METHOD,
            request_serializer=self.pb.ServerReflectionRequest.SerializeToString,
            response_deserializer=self.pb.ServerReflectionResponse.FromString)

    def ask(self, **request):
        responses = list(self.info(iter([self.pb.ServerReflectionRequest(**request)]),
                                   metadata=self.metadata, timeout=10))
        response = responses[0]
        if response.HasField("error_response"):
            raise LookupError(response.error_response.error_message)
        return response

    def services(self):
        return [s.name for s in self.ask(list_services="").list_services_response.service]

    def _add_files(self, serialized):
        files = {}
        for blob in serialized:
            fdp = descriptor_pb2.FileDescriptorProto.FromString(blob)
            files[fdp.name] = fdp
        while files:  # dependencies before dependants; ask for any the server left out
            ready = [f for f in files.values() if all(d in self.added for d in f.dependency)]
            if not ready:
                missing = {d for f in files.values() for d in f.dependency} - self.added
                name = sorted(missing - set(files))[0]
                more = self.ask(file_by_filename=name).file_descriptor_response
                for blob in more.file_descriptor_proto:
                    fdp = descriptor_pb2.FileDescriptorProto.FromString(blob)
                    files.setdefault(fdp.name, fdp)
                continue
            for f in ready:
                if f.name not in self.added:
                    self.pool.Add(f)
                    self.added.add(f.name)
                del files[f.name]

    def service(self, name):
        response = self.ask(file_containing_symbol=name)
        self._add_files(response.file_descriptor_response.file_descriptor_proto)
        return self.pool.FindServiceByName(name)

    def call(self, full_method, request_json, timeout=60):
        service_name, _, method_name = full_method.rpartition("/")
        method = self.service(service_name).FindMethodByName(method_name)
        if method is None:
            raise LookupError(f"{service_name} has no method {method_name}")
        factory = message_factory.MessageFactory(self.pool)
        request_cls = factory.GetPrototype(method.input_type)
        response_cls = factory.GetPrototype(method.output_type)
        request = json_format.Parse(request_json, request_cls())
        path = f"/{service_name}/{method_name}"
        kinds = {(False, False): self.channel.unary_unary,
                 (False, True): self.channel.unary_stream}
        stub = kinds[(method.client_streaming, method.server_streaming)](
            path, request_serializer=request_cls.SerializeToString,
            response_deserializer=response_cls.FromString)
        answer = stub(request, metadata=self.metadata, timeout=timeout)
        messages = answer if method.server_streaming else [answer]
        for m in messages:
            yield json_format.MessageToJson(m, indent=None)


def main(argv):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("address")
    parser.add_argument("--token")
    parser.add_argument("command", choices=["list", "describe", "call"])
    parser.add_argument("args", nargs="*")
    a = parser.parse_args(argv)
    client = ReflectionClient(a.address, a.token)
    try:
        if a.command == "list":
            print("\n".join(client.services()))
        elif a.command == "describe":
            for m in client.service(a.args[0]).methods:
                print(f"{m.name}({m.input_type.full_name}) returns "
                      f"({'stream ' if m.server_streaming else ''}{m.output_type.full_name})")
        else:
            for line in client.call(a.args[0], a.args[1] if len(a.args) > 1 else "{}"):
                print(line, flush=True)
    except grpc.RpcError as e:
        print(f"{e.code().name}: {e.details()}", file=sys.stderr)
        return 1
    except (LookupError, KeyError) as e:
        print(f"reflection: {e}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
