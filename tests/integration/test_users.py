"""A daemon shared by several users (issue 35), end to end through the CLI, the Python client and
raw gRPC: users from --users-file (and the old --token-file as an admin), owners shown and
filtered, PERMISSION_DENIED for another user's job or mesh, one audit line per mutating call,
unauthenticated calls refused before their body is parsed with a bounded log, SIGHUP reloading
the users, the per-user mesh quota, and a data folder from before users existed upgraded with
every job owned by the default user."""

import json
import os
import re
import signal
import sqlite3
import sys
import time

import grpc

from softshock_harness import DaemonTestCase, SoftshockError, small_spec, state_name

TOKENS = {"alice": "alice-token-0123456789abcdef0123456789",
          "bob": "bob-token-0123456789abcdef0123456789ab",
          "ops": "ops-token-0123456789abcdef0123456789ab",
          "default": "default-token-0123456789abcdef01234567"}
# A GetJobRequest whose name (field 2) is not UTF-8: parsing it makes protobuf log an error.
MALFORMED_GET = b"\x12\x02\xff\xfe"


def square_msh(tag: str = "") -> str:
    return ("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n4\n1 0 0 0\n2 1e-4 0 0\n"
            "3 1e-4 1e-4 0\n4 0 1e-4 0\n$EndNodes\n$Elements\n2\n1 2 2 0 1 1 2 3\n"
            "2 2 2 0 1 1 3 4\n$EndElements\n" + tag)


class SharedDaemon(DaemonTestCase):
    """alice and bob (users) and ops (admin) from --users-file; the old single token as the
    admin "default"."""
    start_daemon = False
    workers = 1
    extra = ()

    def setUp(self):
        super().setUp()
        self.users_file = self.write_json(
            f"# softshockd users\nalice:{TOKENS['alice']}\nbob:{TOKENS['bob']}:user\n"
            f"ops:{TOKENS['ops']}:admin\n", "users")
        self.token_file = self.write_json(TOKENS["default"] + "\n", "token")
        self.token_files = {u: self.write_json(t + "\n", f"{u}.token") for u, t in TOKENS.items()}
        self.daemon.extra_args += ["--users-file", self.users_file,
                                   "--token-file", self.token_file] + list(self.extra)
        self.start(health_token=TOKENS["ops"])

    def as_user(self, user, *args, **kw):
        return self.cli("--token-file", self.token_files[user], *args, **kw)

    def as_user_ok(self, user, *args, **kw):
        return self.cli_ok("--token-file", self.token_files[user], *args, **kw)

    def log(self) -> str:
        with open(self.daemon.log_path, encoding="utf-8", errors="replace") as f:
            return f.read()


class OwnersAndPermissionsTest(SharedDaemon):
    def test_owners_filters_permissions_and_the_audit_trail(self):
        for user, role in (("alice", "user"), ("ops", "admin"), ("default", "admin")):
            self.assertEqual(self.cli_json("--token-file", self.token_files[user], "whoami"),
                             {"user": user, "role": role})
        spec = self.write_json(small_spec(300, 1e-8))
        job = self.as_user_ok("alice", "submit", spec, "--wait").stdout.split()[0]
        self.assertRegex(self.as_user_ok("bob", "status", job).stdout, r"(?m)^owner\W+alice$")
        self.assertEqual(self.cli_json("--token-file", self.token_files["bob"], "status",
                                       job)["owner"], "alice")
        listing = self.as_user_ok("bob", "list").stdout
        self.assertRegex(listing.splitlines()[0], r"ID\s+STATE\s+REASON\s+PROGRESS\s+ELAPSED\s+OWNER")
        self.assertIn("alice", listing)
        self.assertEqual(self.cli_json("--token-file", self.token_files["bob"], "list",
                                       "--mine").get("jobs", []), [])
        mine = self.cli_json("--token-file", self.token_files["alice"], "list", "--mine")
        self.assertEqual([j["id"] for j in mine["jobs"]], [job])
        self.assertEqual(mine["jobs"][0]["owner"], "alice")

        for verb in ("cancel", "delete"):
            p = self.as_user("bob", verb, job)
            self.assertEqual(p.returncode, 1, p.stderr)
            self.assertIn("PERMISSION_DENIED", p.stderr)
            self.assertIn(f"jobs/{job} is owned by alice: bob may {verb} only their own", p.stderr)
        bob = self.client(token=TOKENS["bob"])
        with self.assertRaises(SoftshockError) as e:
            bob.delete(job)
        self.assertEqual(e.exception.code, grpc.StatusCode.PERMISSION_DENIED)
        self.assertEqual([j.id for j in bob.list(owner="alice")], [job])
        self.assertEqual(bob.whoami(), ("bob", "user"))
        self.assertEqual(bob.query(owner="alice")[0]["owner"], "alice")

        msh = self.write_json(square_msh(), "square.msh")
        mesh_id = self.as_user_ok("alice", "mesh", "upload", msh).stdout.strip()
        self.assertIn("alice", self.as_user_ok("bob", "mesh", "list").stdout)
        self.assertEqual(self.as_user_ok("bob", "mesh", "list", "--mine").stdout,
                         "no meshes uploaded by bob (softshock mesh upload FILE.msh)\n")
        self.assertEqual([m.owner for m in bob.list_meshes(owner="alice")], ["alice"])
        p = self.as_user("bob", "mesh", "delete", mesh_id)
        self.assertEqual(p.returncode, 1)
        self.assertIn("PERMISSION_DENIED", p.stderr)

        self.as_user_ok("ops", "delete", job)  # an admin may
        self.as_user_ok("alice", "mesh", "delete", mesh_id)  # the owner may

        # One audit line per mutating call, with who, what, which and how it went; no token.
        log = self.log()
        audit = re.findall(r"audit user=(\S+) role=(\S+) rpc=(\S+) resource=(\S+) "
                           r"outcome=(\S+)(?: \S+)* peer=\S+", log)
        self.assertEqual(audit, [
            ("alice", "user", "SubmitJob", f"jobs/{job}", "OK"),
            ("bob", "user", "CancelJob", f"jobs/{job}", "PERMISSION_DENIED"),
            ("bob", "user", "DeleteJob", f"jobs/{job}", "PERMISSION_DENIED"),
            ("bob", "user", "DeleteJob", f"jobs/{job}", "PERMISSION_DENIED"),
            ("alice", "user", "UploadMesh", f"meshes/{mesh_id}", "OK"),
            ("bob", "user", "DeleteMesh", f"meshes/{mesh_id}", "PERMISSION_DENIED"),
            ("ops", "admin", "DeleteJob", f"jobs/{job}", "OK"),
            ("alice", "user", "DeleteMesh", f"meshes/{mesh_id}", "OK"),
        ])
        for token in TOKENS.values():
            self.assertNotIn(token, log)

    def test_sighup_rereads_the_users(self):
        carol = "carol-token-0123456789abcdef0123456789"
        carol_file = self.write_json(carol + "\n", "carol.token")
        self.assertIn("UNAUTHENTICATED",
                      self.cli("--token-file", carol_file, "whoami").stderr)
        with open(self.users_file, "w", encoding="utf-8") as f:  # bob leaves, carol comes
            f.write(f"alice:{TOKENS['alice']}\ncarol:{carol}:admin\n")
        self.daemon.proc.send_signal(signal.SIGHUP)
        self.wait_for(lambda: "users reloaded: 3 user(s)" in self.log(), 10, what="reload")
        self.assertEqual(self.cli_json("--token-file", carol_file, "whoami"),
                         {"user": "carol", "role": "admin"})
        self.assertIn("UNAUTHENTICATED", self.as_user("bob", "whoami").stderr)
        # A broken file is refused and the users stay as they were.
        with open(self.users_file, "w", encoding="utf-8") as f:
            f.write("alice:short\n")
        self.daemon.proc.send_signal(signal.SIGHUP)
        self.wait_for(lambda: "users not reloaded" in self.log(), 10, what="refusal")
        self.assertEqual(self.cli_json("--token-file", carol_file, "whoami")["user"], "carol")


class UnauthenticatedFloodTest(SharedDaemon):
    CALLS = 2000

    def flood(self, metadata=()):
        """CALLS GetJob calls whose body protobuf cannot parse; returns their codes, the log's
        growth in bytes and lines, and the seconds it took."""
        channel = grpc.insecure_channel(self.daemon.address)
        self.addCleanup(channel.close)
        get = channel.unary_unary("/softshock.v1.SimulationService/GetJob")
        before = os.path.getsize(self.daemon.log_path)
        lines_before = self.log().count("\n")
        start = time.monotonic()
        codes = {}
        for batch in range(0, self.CALLS, 200):
            futures = [get.future(MALFORMED_GET, metadata=metadata, timeout=30)
                       for _ in range(batch, min(self.CALLS, batch + 200))]
            for f in futures:
                try:
                    f.result()
                    code = grpc.StatusCode.OK
                except grpc.RpcError as exc:
                    code = exc.code()
                codes[code] = codes.get(code, 0) + 1
        took = time.monotonic() - start
        time.sleep(0.2)
        grew = os.path.getsize(self.daemon.log_path) - before
        return codes, grew, self.log().count("\n") - lines_before, took

    def test_refused_before_parsing_and_logged_at_a_bounded_rate(self):
        codes, grew, lines, took = self.flood()
        print(f"\n{self.CALLS} unauthenticated malformed calls in {took:.2f} s: {codes}; "
              f"log +{grew} bytes, +{lines} lines", file=sys.stderr)
        self.assertEqual(codes, {grpc.StatusCode.UNAUTHENTICATED: self.CALLS})
        log = self.log()
        self.assertNotIn("invalid UTF-8", log, "a refused body was parsed")
        self.assertLessEqual(lines, 25)  # a burst of 20 and one a second, whatever the flood
        self.assertLess(grew, 8000)
        self.assertIn("unauthenticated call refused before its request was read: "
                      "method=/softshock.v1.SimulationService/GetJob reason=missing", log)
        # A client with a token may still send garbage: parsed then (gRPC must, to call the
        # handler), and protobuf's complaints go through the same kind of limit.
        codes, grew, lines, took = self.flood(
            metadata=(("authorization", "Bearer " + TOKENS["bob"]),))
        print(f"{self.CALLS} authenticated malformed calls in {took:.2f} s: {codes}; "
              f"log +{grew} bytes, +{lines} lines", file=sys.stderr)
        self.assertEqual(codes, {grpc.StatusCode.INTERNAL: self.CALLS})
        self.assertLessEqual(lines, 25)
        self.assertLess(grew, 12000)
        self.assertIn("invalid UTF-8", self.log())
        # Health and reflection stay open.
        self.assertEqual(self.cli("health").returncode, 0)


class MeshQuotaTest(SharedDaemon):
    extra = ("--max-meshes-per-user", "3", "--max-mesh-bytes", "1M")

    def test_uploads_stop_at_the_users_bound(self):
        accepted = []
        files = [self.write_json(square_msh(f"%{i}\n"), f"m{i}.msh") for i in range(6)]
        for msh in files:
            p = self.as_user("alice", "mesh", "upload", msh)
            if p.returncode != 0:
                self.assertIn("RESOURCE_EXHAUSTED", p.stderr)
                self.assertIn("user alice stores 3 mesh(es), the most max-meshes-per-user = 3",
                              p.stderr)
                break
            accepted.append(p.stdout.strip())
        self.assertEqual(len(accepted), 3)
        # Re-sending a stored mesh is not a new one; bob has his own bound.
        self.assertEqual(self.as_user_ok("alice", "mesh", "upload",
                                         os.path.join(self.tmp, "m0.msh")).stdout.strip(),
                         accepted[0])
        self.as_user_ok("bob", "mesh", "upload", os.path.join(self.tmp, "m5.msh"))
        self.as_user_ok("alice", "mesh", "delete", accepted[1])
        self.as_user_ok("alice", "mesh", "upload", os.path.join(self.tmp, "m4.msh"))


class UpgradeTest(DaemonTestCase):
    """A data folder of a softshockd from before users (catalogue schema 7, mesh records without
    an owner), made here by taking migrations 10, 9 and 8 back out of one, then served with users."""
    start_daemon = False
    workers = 1

    def test_every_job_is_kept_and_owned_by_the_default_user(self):
        token_file = self.write_json(TOKENS["default"] + "\n", "token")
        self.daemon.extra_args += ["--token-file", token_file]
        self.start(health_token=TOKENS["default"])
        old = self.client(token=TOKENS["default"])
        jobs = [old.submit(small_spec(300, 1e-8), wait=True).id for _ in range(2)]
        queued_grid = old.submit_grid(small_spec(300, 1e-8), axes=[{"name": "pbar",
                                                                    "values": [0.4, 0.5]}],
                                      wait=True)
        msh = self.write_json(square_msh(), "square.msh")
        mesh_id = old.upload_mesh(msh).id
        self.assertEqual(self.daemon.stop(), 0)

        db = sqlite3.connect(os.path.join(self.data_dir, "catalogue.sqlite"))
        # Migrations 10 (parent_id) and 9 (the damage figures) back out too, then 8.
        db.executescript("ALTER TABLE jobs DROP COLUMN parent_id; "
                         "ALTER TABLE job_summaries DROP COLUMN dimension; "
                         "ALTER TABLE job_summaries DROP COLUMN thickness;")
        db.executescript("".join(
            f"ALTER TABLE job_summaries DROP COLUMN {c}; " for c in (
                "damage", "damage_onset", "max_damaged_volume", "max_damaged_radius",
                "damage_dissipation", "crack_energy", "damage_time", "damage_solves")))
        db.executescript("DROP INDEX jobs_owner_state; ALTER TABLE jobs DROP COLUMN owner; "
                         "ALTER TABLE grids DROP COLUMN owner; "
                         "UPDATE schema_version SET version = 7;")
        db.close()
        record = os.path.join(self.data_dir, "meshes", "uploads", mesh_id + ".json")
        with open(record, encoding="utf-8") as f:
            mesh = json.load(f)
        del mesh["owner"]
        with open(record, "w", encoding="utf-8") as f:
            json.dump(mesh, f)

        users = self.write_json(f"alice:{TOKENS['alice']}\nops:{TOKENS['ops']}:admin\n", "users")
        self.daemon.extra_args += ["--users-file", users]
        self.start(health_token=TOKENS["ops"])
        self.assertIn("catalogue-schema=10", self.daemon.log_tail(200))
        ops, alice = self.client(token=TOKENS["ops"]), self.client(token=TOKENS["alice"])
        listed = ops.list()
        self.assertEqual(len(listed), 4)  # two jobs and two grid points, all kept
        self.assertEqual({j.owner for j in listed}, {"default"})
        self.assertEqual({state_name(j) for j in listed}, {"SUCCEEDED"})
        self.assertEqual(ops.grid(queued_grid.id).owner, "default")
        self.assertEqual([m.owner for m in ops.list_meshes()], ["default"])
        with self.assertRaises(SoftshockError) as e:
            alice.delete(jobs[0])
        self.assertEqual(e.exception.code, grpc.StatusCode.PERMISSION_DENIED)
        self.client(token=TOKENS["default"]).delete(jobs[0])  # the old token still owns them
        ops.delete(jobs[1])
        ops.delete_mesh(mesh_id)
        self.assertEqual(len(ops.list()), 2)
