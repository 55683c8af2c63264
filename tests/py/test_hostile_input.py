"""Hostile inputs to `isohex mesh` at the command line: a file the user may not
read says "permission denied" (not "damaged"), a named pipe is refused at once
(it blocked for ever), a header's data file outside its folder needs
--allow-data-outside (flag and batch column); each refusal is one line naming
the file, and nothing is written."""
import os
import shutil
import stat
import subprocess
import sys
import unittest

sys.path.insert(0, os.path.dirname(__file__))
from common import ISOHEX, run, workdir  # noqa: E402

NRRD = "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 12 12 12\nencoding: raw\ndata file: {}\n"


def ball():
    """12^3 uint8 voxels: 200 inside a ball of radius 4, 0 outside."""
    out = bytearray(12 ** 3)
    for z in range(12):
        for y in range(12):
            for x in range(12):
                if (x - 5.5) ** 2 + (y - 5.5) ** 2 + (z - 5.5) ** 2 < 16:
                    out[x + 12 * (y + 12 * z)] = 200
    return bytes(out)


def unprivileged(args):
    """The command run as a user without root's power to read any file: as
    `nobody` through setpriv when this runs as root, as it is otherwise."""
    if os.geteuid() != 0:
        return args
    return ["setpriv", "--reuid=65534", "--regid=65534", "--clear-groups", "--"] + args


class HostileInput(unittest.TestCase):
    def setUp(self):
        self.dir = workdir("hostile_input")
        os.chmod(self.dir, 0o777)  # `nobody` may enter and write here

    def tearDown(self):
        shutil.rmtree(self.dir, ignore_errors=True)

    def refused(self, args, *pieces, runner=None):
        out = os.path.join(self.dir, "out.vtu")
        cmd = [ISOHEX, "mesh", *map(str, args), "-o", out, "--iso", "100"]
        proc = subprocess.run(runner(cmd) if runner else cmd, capture_output=True, text=True, timeout=60)
        self.assertNotEqual(proc.returncode, 0, proc.stdout + proc.stderr)
        errors = [line for line in proc.stderr.splitlines() if "error" in line]
        self.assertEqual(len(errors), 1, proc.stderr)
        for piece in pieces:
            self.assertIn(piece, errors[0])
        self.assertFalse(os.path.exists(out), "an output was written")
        self.assertEqual([f for f in os.listdir(self.dir) if f.startswith("out.")], [])
        return errors[0]

    def test_a_file_without_read_permission_says_permission_denied(self):
        scan = os.path.join(self.dir, "scan.nhdr")
        with open(os.path.join(self.dir, "scan.raw"), "wb") as f:
            f.write(ball())
        with open(scan, "w") as f:
            f.write(NRRD.format("scan.raw"))
        os.chmod(os.path.join(self.dir, "scan.raw"), 0o644)
        # Readable, it meshes (as the unprivileged user too): the control.
        proc = subprocess.run(unprivileged([ISOHEX, "mesh", scan, "-o", os.path.join(self.dir, "ok.vtu"),
                                            "--iso", "100", "-q"]), capture_output=True, text=True, timeout=120)
        self.assertEqual(proc.returncode, 0, proc.stderr)
        os.remove(os.path.join(self.dir, "ok.vtu"))
        os.chmod(scan, 0)
        line = self.refused([scan], "scan.nhdr", "permission denied", "chmod", runner=unprivileged)
        self.assertNotIn("damaged", line)

    def test_a_named_pipe_is_refused_without_blocking(self):
        pipe = os.path.join(self.dir, "scan.nii")
        os.mkfifo(pipe)
        self.refused([pipe], "scan.nii", "named pipe")

    def test_a_data_file_outside_the_header_folder_needs_the_option(self):
        inner = os.path.join(self.dir, "scan")
        os.mkdir(inner)
        with open(os.path.join(self.dir, "outside.raw"), "wb") as f:
            f.write(ball())
        scan = os.path.join(inner, "scan.nhdr")
        with open(scan, "w") as f:
            f.write(NRRD.format("../outside.raw"))
        self.refused([scan], "scan.nhdr", "'../outside.raw'", "outside the header's folder", "--allow-data-outside")
        run(["mesh", scan, "-o", os.path.join(self.dir, "allowed.vtu"), "--iso", "100", "--allow-data-outside", "-q"])
        self.assertTrue(os.path.exists(os.path.join(self.dir, "allowed.vtu")))
        with open(scan, "w") as f:
            f.write(NRRD.format("/dev/urandom"))
        self.refused([scan, "--allow-data-outside"], "scan.nhdr", "/dev/urandom, a device")
        # The batch column: refused without it, meshed with it.
        manifest = os.path.join(self.dir, "jobs.csv")
        with open(scan, "w") as f:
            f.write(NRRD.format("../outside.raw"))
        with open(manifest, "w") as f:
            f.write("input,output,iso,allow-data-outside\n")
            f.write(f"{scan},{self.dir}/b0.vtu,100,false\n{scan},{self.dir}/b1.vtu,100,true\n")
        proc = run(["batch", manifest, "-q"], check=False)
        self.assertFalse(os.path.exists(os.path.join(self.dir, "b0.vtu")))
        self.assertTrue(os.path.exists(os.path.join(self.dir, "b1.vtu")), proc.stdout + proc.stderr)
        self.assertRegex(proc.stdout + proc.stderr, "allow[-_]data[-_]outside")


if __name__ == "__main__":
    unittest.main()
