"""A daemon whose disk fills up (issue 35): its data folder on a real tmpfs of a few dozen MiB,
filled to the last byte by a file beside it. New work is refused with RESOURCE_EXHAUSTED (the
reserve, --min-free-bytes), and space can still be freed through the API: DeleteJob and
DeleteMesh succeed, the catalogue committing through the room it keeps (DATA/catalogue.room).
Before, SubmitJob and DeleteJob both answered UNAVAILABLE ("database or disk is full").

Mounting needs root (CI runs as root); elsewhere the test is skipped. SOFTSHOCK_FULL_DISK_SIZE
sets the tmpfs size (default 48m) and SOFTSHOCK_FULL_DISK_ARGS replaces the daemon flags (default
"--min-free-bytes 1M"): the same scenario can then be run against an older softshockd (with a
tmpfs above its fixed 256 MiB reserve) to see what it did."""

import errno
import os
import shlex
import subprocess
import sys
import time

import grpc

from softshock_harness import DaemonTestCase, SoftshockError, small_spec, state_name

TOKEN = "full-disk-token-0123456789abcdef0123456"


def square_msh(tag: str = "") -> str:
    return ("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n4\n1 0 0 0\n2 1e-4 0 0\n"
            "3 1e-4 1e-4 0\n4 0 1e-4 0\n$EndNodes\n$Elements\n2\n1 2 2 0 1 1 2 3\n"
            "2 2 2 0 1 1 3 4\n$EndElements\n" + tag)


def fill(path: str) -> int:
    """Writes `path` until the file system refuses another byte; returns the bytes written."""
    written = 0
    with open(path, "wb", buffering=0) as f:
        for size in (1 << 20, 4096, 1):
            block = b"\0" * size
            while True:
                try:
                    f.write(block)
                    written += size
                except OSError as exc:
                    if exc.errno not in (errno.ENOSPC, errno.EDQUOT):
                        raise
                    break
    return written


class FullDiskTest(DaemonTestCase):
    start_daemon = False
    workers = 1

    def setUp(self):
        super().setUp()
        if os.geteuid() != 0:
            self.skipTest("mounting a tmpfs needs root")
        os.makedirs(self.data_dir)
        size = os.environ.get("SOFTSHOCK_FULL_DISK_SIZE", "48m")
        subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", self.data_dir],
                       check=True)
        self.addCleanup(self.unmount)
        token_file = self.write_json(TOKEN + "\n", "token")
        args = shlex.split(os.environ.get("SOFTSHOCK_FULL_DISK_ARGS", "--min-free-bytes 1M"))
        self.daemon.extra_args += ["--token-file", token_file] + args
        self.start(health_token=TOKEN)
        self.filler = os.path.join(self.data_dir, "filler")

    def unmount(self):
        self.daemon.stop()
        subprocess.run(["umount", self.data_dir], check=False)

    def free(self) -> int:
        st = os.statvfs(self.data_dir)
        return st.f_bavail * st.f_frsize

    def test_new_work_refused_and_space_freed_through_the_api(self):
        c = self.client(token=TOKEN)
        jobs = [c.submit(small_spec(300, 1e-8), wait=True) for _ in range(6)]
        self.assertEqual({state_name(j) for j in jobs}, {"SUCCEEDED"})
        msh = self.write_json(square_msh(), "square.msh")
        mesh_id = c.upload_mesh(msh).id
        room = os.path.join(self.data_dir, "catalogue.room")
        print(f"\nbefore: {self.free() >> 10} KiB free, room "
              f"{os.path.getsize(room) >> 10 if os.path.exists(room) else 0} KiB",
              file=sys.stderr)

        filled = fill(self.filler)
        print(f"filled {filled >> 10} KiB; {self.free()} bytes free", file=sys.stderr)
        with self.assertRaises(SoftshockError) as e:
            c.submit(small_spec(300, 1e-8))
        print(f"SubmitJob: {e.exception.code.name}: {e.exception.details}", file=sys.stderr)
        self.assertEqual(e.exception.code, grpc.StatusCode.RESOURCE_EXHAUSTED)
        with self.assertRaises(SoftshockError) as e:
            c.upload_mesh(self.write_json(square_msh("%other\n"), "other.msh"))
        print(f"UploadMesh: {e.exception.code.name}: {e.exception.details}", file=sys.stderr)
        self.assertEqual(e.exception.code, grpc.StatusCode.RESOURCE_EXHAUSTED)

        # Space can be freed through the API, one deletion after another.
        started = time.monotonic()
        for job in jobs:
            c.delete(job.id)
        c.delete_mesh(mesh_id)
        print(f"6 DeleteJob + 1 DeleteMesh on the full disk: OK in "
              f"{time.monotonic() - started:.2f} s; {self.free() >> 10} KiB free now",
              file=sys.stderr)
        self.assertEqual(c.list(), [])
        self.assertEqual(c.list_meshes(), [])
        self.assertIn("used its reserved room", self.daemon.log_tail(400))

        # Once the disk has room again, the catalogue takes its room back and work resumes.
        os.unlink(self.filler)
        job = c.submit(small_spec(300, 1e-8), wait=True)
        self.assertEqual(state_name(job), "SUCCEEDED")
        self.assertEqual(os.path.getsize(room), 8 << 20)
