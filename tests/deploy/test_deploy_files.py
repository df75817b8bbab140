"""deploy/ is well-formed and consistent with itself and with softshockd: the Dockerfile's stages,
user, volume, HEALTHCHECK and runtime packages; compose.yaml; the Kubernetes manifests; the
settings they use exist (`softshockd --help`); docs/deploy.md documents every setting."""

from __future__ import annotations

import os
import re
import subprocess
import unittest

import yaml

from deploy_files import (DEPLOY_DIR, SOFTSHOCK, SOFTSHOCK_SOLVE, SOFTSHOCKD, SOURCE_DIR,
                          daemon_settings, port_of, read_dockerfile, runtime_stage)

RUNTIME_BINARIES = {"softshockd": SOFTSHOCKD, "softshock": SOFTSHOCK,
                    "softshock-solve": SOFTSHOCK_SOLVE}


def load_yaml_documents(name: str) -> list:
    with open(os.path.join(DEPLOY_DIR, name), encoding="utf-8") as f:
        return [d for d in yaml.safe_load_all(f) if d is not None]


def direct_library_packages(binaries) -> set:
    """Debian packages of the libraries the binaries link directly (their NEEDED entries), in
    one dpkg query (each costs a second). Merged /usr: a library may be registered under /lib."""
    paths = set()
    for binary in binaries:
        needed = re.findall(r"NEEDED\s+(\S+)", subprocess.run(
            ["objdump", "-p", binary], check=True, capture_output=True, text=True).stdout)
        resolved = dict(re.findall(r"^\s*(\S+) => (/\S+)", subprocess.run(
            ["ldd", binary], check=True, capture_output=True, text=True).stdout, re.MULTILINE))
        paths |= {os.path.realpath(resolved[lib]) for lib in needed}
    candidates = {p: (p, re.sub(r"^/usr/lib/", "/lib/", p)) for p in paths}
    query = sorted({c for pair in candidates.values() for c in pair})
    owners = {}
    for line in subprocess.run(["dpkg", "-S"] + query, capture_output=True,
                               text=True).stdout.splitlines():
        package, _, path = line.partition(": ")
        owners[path] = package.split(":")[0]
    packages = set()
    for path, pair in candidates.items():
        owner = next((owners[c] for c in pair if c in owners), None)
        if owner is None:
            raise AssertionError(f"no package ships {path}")
        packages.add(owner)
    return packages


class DockerfileTest(unittest.TestCase):
    def setUp(self):
        self.args, self.stages = read_dockerfile()
        self.runtime = self.stages[-1]
        self.build = self.stages[0]

    def test_base_image_is_an_argument(self):
        self.assertEqual(self.args.get("BASE_IMAGE"), "debian:bookworm")
        for stage in self.stages:
            self.assertEqual(stage.base, "${BASE_IMAGE}", stage.name)
        self.assertEqual([s.name for s in self.stages], ["build", "runtime"])

    def test_build_stage_uses_install_deps_and_ci_flags(self):
        runs = " ".join(i.args for i in self.build.all("RUN"))
        self.assertIn("/src/scripts/install-deps", runs)
        self.assertIn("-DSOFTSHOCK_WERROR=ON", runs)
        self.assertIn("-DCMAKE_BUILD_TYPE=Release", runs)
        for target in RUNTIME_BINARIES:
            self.assertRegex(runs, rf"--target [^&]*\b{re.escape(target)}\b")

    def test_build_stage_copies_every_cmake_subdirectory(self):
        copied = {i.args.split()[0] for i in self.build.all("COPY")}
        with open(os.path.join(SOURCE_DIR, "CMakeLists.txt"), encoding="utf-8") as f:
            top = f.read()
        self.assertIn("CMakeLists.txt", copied)
        subdirs = re.findall(r"add_subdirectory\((\w+)\)", top)
        subdirs += re.findall(r"include\((\w+)/", top)  # e.g. packaging/cpack.cmake
        self.assertIn("server", subdirs)
        runs = " ".join(i.args for i in self.build.all("RUN"))
        for d in subdirs:
            if d == "bench":  # configured off in the image
                self.assertIn("-DSOFTSHOCK_BUILD_BENCH=OFF", runs)
                continue
            self.assertIn(d, copied, f"deploy/Dockerfile does not COPY {d}/")

    def test_runtime_stage_carries_only_runtime_packages_and_binaries(self):
        install = " ".join(i.args for i in self.runtime.all("RUN"))
        m = re.search(r"apt-get install ((?:-\S+ )*)(.*?)(?: &&|$)", install)
        self.assertIsNotNone(m)
        self.assertIn("--no-install-recommends", m.group(1))
        packages = set(m.group(2).split())
        self.assertTrue(packages)
        for p in packages:
            self.assertFalse(p.endswith("-dev"), p)
            self.assertNotIn(p, {"build-essential", "cmake", "g++", "gcc", "clang-format"})
        self.assertNotIn("install-deps", install)
        # Every library the binaries CI built link directly comes from a listed package.
        missing = direct_library_packages(RUNTIME_BINARIES.values()) - packages
        self.assertFalse(missing, f"the binaries need {missing}: add them to the runtime stage")
        copies = self.runtime.all("COPY")
        self.assertEqual([c.args for c in copies], ["--from=build /out/ /usr/local/bin/"])
        build_runs = " ".join(i.args for i in self.build.all("RUN"))
        for binary in ("server/softshockd", "client/softshock", "solver/softshock-solve",
                       "solver/softshock-mesh"):
            self.assertIn(f"/build/{binary}", build_runs)

    def test_non_root_user_volume_and_port(self):
        user = self.runtime.user()
        uid = user.split(":")[0]
        self.assertTrue(uid.isdigit(), "USER should be numeric (Kubernetes runAsNonRoot)")
        self.assertNotEqual(int(uid), 0)
        runs = " ".join(i.args for i in self.runtime.all("RUN"))
        self.assertIn(f"--uid {uid}", runs)
        env = self.runtime.env()
        volume = self.runtime.last("VOLUME").args
        self.assertEqual(volume, '["/var/lib/softshock"]')
        self.assertEqual(env["SOFTSHOCK_DATA_DIR"], "/var/lib/softshock")
        self.assertIn(f"-o {uid}", runs)  # the volume's mount point belongs to the user
        self.assertEqual(env["SOFTSHOCK_LISTEN"], "0.0.0.0:50051")
        self.assertEqual(self.runtime.last("EXPOSE").args, "50051")

    def test_exposed_listen_comes_with_a_token(self):
        env = self.runtime.env()
        self.assertTrue(env.get("SOFTSHOCK_TOKEN_FILE", "").startswith("/run/secrets/"))
        self.assertNotIn("SOFTSHOCK_INSECURE_NO_AUTH", env)
        settings = daemon_settings()
        for key in env:
            if key.startswith("SOFTSHOCK_"):
                self.assertIn(key, settings.values(), f"{key} is no softshockd setting")

    def test_entrypoint_is_the_daemon_in_exec_form(self):
        self.assertEqual(self.runtime.exec_form("ENTRYPOINT"), ["/usr/local/bin/softshockd"])
        self.assertEqual(self.runtime.exec_form("CMD"), [])

    def test_healthcheck_asks_grpc_health_through_the_cli(self):
        options, command = self.runtime.healthcheck()
        for key in ("interval", "timeout", "start-period", "retries"):
            self.assertIn(key, options)
        self.assertEqual(command[0], "/usr/local/bin/softshock")
        self.assertEqual(command[-1], "health")
        server = command[command.index("--server") + 1]
        self.assertEqual(server.split(":")[0], "127.0.0.1")
        self.assertEqual(port_of(server), port_of(self.runtime.env()["SOFTSHOCK_LISTEN"]))
        self.assertNotIn("--token-file", command)  # health is unauthenticated


class ComposeTest(unittest.TestCase):
    def setUp(self):
        (self.compose,) = load_yaml_documents("compose.yaml")
        self.service = self.compose["services"]["softshockd"]
        self.runtime = runtime_stage()

    def test_builds_the_dockerfile_with_a_base_image_argument(self):
        build = self.service["build"]
        self.assertEqual(os.path.normpath(os.path.join(DEPLOY_DIR, build["context"])),
                         os.path.normpath(SOURCE_DIR))
        self.assertEqual(build["dockerfile"], "deploy/Dockerfile")
        self.assertIn("BASE_IMAGE", build["args"])

    def test_named_volume_on_the_data_dir(self):
        volume, target = self.service["volumes"][0].split(":")[:2]
        self.assertEqual(target, self.runtime.env()["SOFTSHOCK_DATA_DIR"])
        self.assertIn(volume, self.compose["volumes"])  # named, not a host path

    def test_token_is_a_secret_file_where_the_image_expects_it(self):
        (secret,) = self.service["secrets"]
        self.assertIn("file", self.compose["secrets"][secret["source"]])
        token_file = self.service.get("environment", {}).get(
            "SOFTSHOCK_TOKEN_FILE", self.runtime.env()["SOFTSHOCK_TOKEN_FILE"])
        self.assertEqual(f"/run/secrets/{secret['target']}", token_file)
        for key, value in self.service.get("environment", {}).items():
            self.assertNotIn("TOKEN", key.replace("TOKEN_FILE", ""), "a token in the environment")

    def test_restart_limits_and_port(self):
        self.assertIn(self.service["restart"], {"always", "unless-stopped", "on-failure"})
        limits = self.service["deploy"]["resources"]["limits"]
        self.assertIn("memory", limits)
        cpus = float(limits["cpus"])
        workers = int(self.service["environment"]["SOFTSHOCK_WORKERS"])
        threads = int(self.service["environment"].get("SOFTSHOCK_SOLVER_THREADS", "1"))
        self.assertLessEqual(workers * threads, cpus, "more busy threads than CPUs")
        self.assertIn("memory", self.service["deploy"]["resources"]["reservations"])
        for port in self.service["ports"]:
            self.assertTrue(port.startswith("127.0.0.1:"), "published beyond the host")
            self.assertTrue(port.endswith(":50051"))

    def test_environment_names_daemon_settings(self):
        settings = daemon_settings().values()
        for key in self.service["environment"]:
            self.assertIn(key, settings)


class KubernetesTest(unittest.TestCase):
    def setUp(self):
        (self.sts,) = load_yaml_documents("k8s/statefulset.yaml")
        self.services = load_yaml_documents("k8s/service.yaml")
        self.pod = self.sts["spec"]["template"]["spec"]
        (self.container,) = self.pod["containers"]
        self.env = {e["name"]: e.get("value") for e in self.container["env"]}
        self.runtime = runtime_stage()
        self.port = port_of(self.runtime.env()["SOFTSHOCK_LISTEN"])

    def test_one_replica_with_its_own_volume(self):
        spec = self.sts["spec"]
        self.assertEqual(self.sts["kind"], "StatefulSet")
        self.assertEqual(spec["replicas"], 1)  # one SQLite writer
        (claim,) = spec["volumeClaimTemplates"]
        self.assertEqual(claim["spec"]["accessModes"], ["ReadWriteOnce"])
        self.assertIn("storage", claim["spec"]["resources"]["requests"])
        mounts = {m["name"]: m["mountPath"] for m in self.container["volumeMounts"]}
        self.assertEqual(mounts[claim["metadata"]["name"]],
                         self.env.get("SOFTSHOCK_DATA_DIR") or
                         self.runtime.env()["SOFTSHOCK_DATA_DIR"])
        self.assertEqual(spec["selector"]["matchLabels"],
                         {k: v for k, v in spec["template"]["metadata"]["labels"].items()
                          if k in spec["selector"]["matchLabels"]})

    def test_native_grpc_probes_on_the_health_service(self):
        (port,) = [p for p in self.container["ports"] if p["name"] == "grpc"]
        self.assertEqual(port["containerPort"], self.port)
        for probe in ("livenessProbe", "readinessProbe", "startupProbe"):
            self.assertEqual(self.container[probe]["grpc"]["port"], self.port, probe)
            self.assertNotIn("service", self.container[probe]["grpc"])  # "" = whole server

    def test_resources_fit_the_workers(self):
        resources = self.container["resources"]
        for kind in ("requests", "limits"):
            for what in ("cpu", "memory"):
                self.assertIn(what, resources[kind], f"{kind}.{what}")
        cpu_limit = float(str(resources["limits"]["cpu"]).rstrip("m")) / (
            1000 if str(resources["limits"]["cpu"]).endswith("m") else 1)
        workers = int(self.env["SOFTSHOCK_WORKERS"])
        threads = int(self.env.get("SOFTSHOCK_SOLVER_THREADS", "1"))
        self.assertLessEqual(workers * threads, cpu_limit)

    def test_non_root_security_context(self):
        pod_sc = self.pod["securityContext"]
        self.assertTrue(pod_sc["runAsNonRoot"])
        uid = int(self.runtime.user().split(":")[0])
        self.assertEqual(pod_sc["runAsUser"], uid)
        self.assertEqual(pod_sc["fsGroup"], int(self.runtime.user().split(":")[1]))
        sc = self.container["securityContext"]
        self.assertFalse(sc["allowPrivilegeEscalation"])
        self.assertTrue(sc["readOnlyRootFilesystem"])
        self.assertEqual(sc["capabilities"]["drop"], ["ALL"])

    def test_token_comes_from_a_secret_volume(self):
        token_file = self.env["SOFTSHOCK_TOKEN_FILE"]
        volumes = {v["name"]: v for v in self.pod["volumes"]}
        for mount in self.container["volumeMounts"]:
            secret = volumes.get(mount["name"], {}).get("secret")
            if secret and token_file.startswith(mount["mountPath"] + "/"):
                self.assertTrue(mount["readOnly"])
                (item,) = secret["items"]
                self.assertEqual(token_file, f"{mount['mountPath']}/{item['path']}")
                (example,) = load_yaml_documents("k8s/secret.example.yaml")
                self.assertEqual(example["metadata"]["name"], secret["secretName"])
                self.assertIn(item["key"], example["stringData"])
                break
        else:
            self.fail(f"{token_file} is not in a mounted Secret")
        for e in self.container["env"]:
            self.assertNotIn("valueFrom", e, "the token belongs in a file, not the environment")

    def test_environment_names_daemon_settings(self):
        settings = daemon_settings().values()
        for key in self.env:
            self.assertIn(key, settings)

    def test_services_select_the_pod(self):
        labels = self.sts["spec"]["template"]["metadata"]["labels"]
        names = {s["metadata"]["name"]: s for s in self.services}
        headless = names[self.sts["spec"]["serviceName"]]
        self.assertEqual(headless["spec"]["clusterIP"], "None")
        for s in self.services:
            self.assertEqual(s["kind"], "Service")
            for k, v in s["spec"]["selector"].items():
                self.assertEqual(labels[k], v)
            container_ports = {p["name"] for p in self.container["ports"]}
            for port in s["spec"]["ports"]:
                self.assertIn(port["targetPort"], container_ports)
            self.assertEqual(s["spec"]["ports"][0]["targetPort"], "grpc")

    def test_prometheus_scrapes_the_metrics_listener(self):
        # The annotations and the ServiceMonitor example point at the port the daemon serves
        # /metrics on (SOFTSHOCK_METRICS_LISTEN), which the container and the Service expose.
        annotations = self.sts["spec"]["template"]["metadata"]["annotations"]
        self.assertEqual(annotations["prometheus.io/scrape"], "true")
        self.assertEqual(annotations["prometheus.io/path"], "/metrics")
        port = port_of(self.env["SOFTSHOCK_METRICS_LISTEN"])
        self.assertEqual(int(annotations["prometheus.io/port"]), port)
        (container_port,) = [p for p in self.container["ports"] if p["name"] == "metrics"]
        self.assertEqual(container_port["containerPort"], port)
        service = {s["metadata"]["name"]: s for s in self.services}["softshockd"]
        (metrics,) = [p for p in service["spec"]["ports"] if p["name"] == "metrics"]
        self.assertEqual(metrics["targetPort"], "metrics")
        (monitor,) = load_yaml_documents("k8s/servicemonitor.example.yaml")
        self.assertEqual(monitor["kind"], "ServiceMonitor")
        for k, v in monitor["spec"]["selector"]["matchLabels"].items():
            self.assertEqual(service["metadata"]["labels"][k], v)
        (endpoint,) = monitor["spec"]["endpoints"]
        self.assertEqual(endpoint["port"], metrics["name"])
        self.assertEqual(endpoint["path"], "/metrics")
        (k,) = load_yaml_documents("k8s/kustomization.yaml")
        self.assertNotIn("servicemonitor.example.yaml", k["resources"])  # needs the operator

    def test_kustomization_lists_existing_manifests(self):
        (k,) = load_yaml_documents("k8s/kustomization.yaml")
        for r in k["resources"]:
            self.assertTrue(os.path.exists(os.path.join(DEPLOY_DIR, "k8s", r)), r)
        self.assertNotIn("secret.example.yaml", k["resources"])


class UsersOverlayTest(unittest.TestCase):
    """How users are added (docs/deploy.md, "Users"): compose.users.yaml over compose.yaml, and
    users-patch.yaml over the StatefulSet, both pointing SOFTSHOCK_USERS_FILE at a secret file."""

    def test_compose_overlay_mounts_the_users_file_it_names(self):
        (overlay,) = load_yaml_documents("compose.users.yaml")
        service = overlay["services"]["softshockd"]
        (secret,) = service["secrets"]
        self.assertIn("file", overlay["secrets"][secret["source"]])
        self.assertEqual(service["environment"]["SOFTSHOCK_USERS_FILE"],
                         f"/run/secrets/{secret['target']}")
        (base,) = load_yaml_documents("compose.yaml")
        self.assertNotIn(secret["source"], base["secrets"], "a second secret, not a replacement")
        settings = daemon_settings().values()
        for key in service["environment"]:
            self.assertIn(key, settings)

    def test_kubernetes_patch_mounts_the_users_secret_it_names(self):
        (patch,) = load_yaml_documents("k8s/users-patch.yaml")
        pod = patch["spec"]["template"]["spec"]
        (container,) = pod["containers"]
        (sts,) = load_yaml_documents("k8s/statefulset.yaml")
        self.assertEqual(container["name"], sts["spec"]["template"]["spec"]["containers"][0]["name"])
        env = {e["name"]: e["value"] for e in container["env"]}
        (mount,) = container["volumeMounts"]
        (volume,) = pod["volumes"]
        self.assertEqual(mount["name"], volume["name"])
        self.assertTrue(mount["readOnly"])
        (item,) = volume["secret"]["items"]
        self.assertEqual(env["SOFTSHOCK_USERS_FILE"], f"{mount['mountPath']}/{item['path']}")
        self.assertEqual(volume["secret"]["defaultMode"] & 0o007, 0, "others may read it")
        (example,) = load_yaml_documents("k8s/users.example.yaml")
        self.assertEqual(example["metadata"]["name"], volume["secret"]["secretName"])
        self.assertIn(item["key"], example["stringData"])
        (k,) = load_yaml_documents("k8s/kustomization.yaml")
        self.assertNotIn("users.example.yaml", k["resources"])
        self.assertIn("SOFTSHOCK_USERS_FILE", daemon_settings().values())


class DocumentationTest(unittest.TestCase):
    def test_deploy_doc_names_every_setting(self):
        with open(os.path.join(SOURCE_DIR, "docs", "deploy.md"), encoding="utf-8") as f:
            doc = f.read()
        for flag, env in daemon_settings().items():
            self.assertIn(f"--{flag}", doc)
            self.assertIn(env, doc)
        self.assertIn("SOFTSHOCK_CONFIG", doc)

    def test_readme_shows_how_to_run_in_a_container(self):
        with open(os.path.join(SOURCE_DIR, "README.md"), encoding="utf-8") as f:
            readme = f.read()
        section = readme.split("## Run in a container", 1)[1].split("\n## ", 1)[0]
        self.assertIn("compose -f deploy/compose.yaml up", section)
        self.assertIn("softshock_token", section)

    def test_readme_venv_recipe_is_the_one_that_works(self):
        # The recipe tests/integration/test_python_package.py runs, in README.md and
        # client/README.md: a plain venv fails (`invalid command 'bdist_wheel'`), and without
        # python3-wheel so does --no-build-isolation.
        with open(os.path.join(SOURCE_DIR, "README.md"), encoding="utf-8") as f:
            section = f.read().split("## Just the client", 1)[1].split("\n## ", 1)[0]
        with open(os.path.join(SOURCE_DIR, "client", "README.md"), encoding="utf-8") as f:
            client_readme = f.read()
        for doc in (section, client_readme):
            self.assertIn("python3-venv", doc)
            block = doc.split("python3-venv", 1)[1].split("```", 1)[0]
            for needed in ("python3-wheel", "python3-setuptools", "python3-grpcio",
                           "python3 -m venv --system-site-packages ~/softshock-venv",
                           "~/softshock-venv/bin/pip install --no-build-isolation ./client/python"):
                self.assertIn(needed, block)


if __name__ == "__main__":
    unittest.main()
