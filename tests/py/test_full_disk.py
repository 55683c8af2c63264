"""A disk that fills up while isohex writes. Every mesh format and the report
fail with one error line that names the file and says the disk ran out of
space; the command exits non-zero and leaves neither the file nor its
temporary, and an output it was told to replace (--force) survives unchanged.
A batch does not run the later jobs that write to a disk it found full (each
would mesh and then fail), and runs those that write elsewhere.

The full disk is a small tmpfs mounted in a private mount namespace
(util-linux `unshare`), so nothing outside the test sees it."""
import os
import re
import shlex
import subprocess
import sys
import unittest

sys.path.insert(0, os.path.dirname(__file__))
from common import ISOHEX, phantoms, workdir  # noqa: E402

MARK = "--- folder after the run ---"


def in_small_disk(folder, command, size, filler_kb=0):
    """Runs `command` (a shell line) with a tmpfs of `size` mounted on `folder`
    holding kept.vtu ("old") and, if asked, a filler of `filler_kb` kB; then
    prints "status N", MARK and a line "name<TAB>first bytes" per file left
    there. Returns the CompletedProcess and the stderr of the tries that could
    not mount. The tmpfs goes when the namespace ends."""
    q = shlex.quote(folder)
    script = (f"mount -t tmpfs -o size={size} tmpfs {q} || exit 99; printf old > {q}/kept.vtu; "
              f"head -c {filler_kb}k /dev/zero > {q}/filler; "
              f"{command}; echo \"status $?\"; echo '{MARK}'; "
              f"for f in {q}/.[!.]* {q}/*; do [ -e \"$f\" ] && "
              f"printf '%s\\t%s\\n' \"$(basename \"$f\")\" \"$(head -c 8 \"$f\" | tr -dc '[:alnum:]')\"; done; true")
    # Root may mount in a new mount namespace; where that is not allowed
    # (a container without CAP_SYS_ADMIN, a user), a new user namespace gives
    # the right to mount a tmpfs.
    refused = []
    for unshare in (["unshare", "--mount"], ["unshare", "--user", "--map-root-user", "--mount"]):
        proc = subprocess.run(unshare + ["sh", "-c", script], capture_output=True, text=True, timeout=300)
        if "status " in proc.stdout:
            break
        refused.append(" ".join(unshare) + ": " + proc.stderr.strip())
    return proc, refused


def outcome(test, proc, refused):
    """(exit status, stderr, {file left: its first bytes}) of an in_small_disk run."""
    status = [line for line in proc.stdout.splitlines() if line.startswith("status ")]
    test.assertTrue(status, "could not mount a tmpfs: " + " | ".join(refused))
    left = dict(line.split("\t") for line in proc.stdout.split(MARK, 1)[1].strip().splitlines())
    left.pop("filler", None)
    return int(status[0].split()[1]), proc.stderr, left


class FullDisk(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.ph = phantoms("full_disk")
        cls.dir = workdir("full_disk_mount")

    def write(self, out, *extra, size="1m", mesh_size="1.25", filler_kb=0):
        sphere = os.path.join(self.ph, "sphere.nii.gz")
        cmd = " ".join(shlex.quote(a) for a in [ISOHEX, "mesh", sphere, "--size", mesh_size, "-q", "-o", out, *extra])
        return outcome(self, *in_small_disk(self.dir, cmd, size, filler_kb))

    def assert_refused(self, status, stderr, left, named):
        errors = [line for line in stderr.splitlines() if ": error: " in line]
        self.assertNotEqual(status, 0, stderr)
        self.assertEqual(len(errors), 1, stderr)
        self.assertIn(named, errors[0])
        self.assertIn("ran out of space while writing it", errors[0])
        self.assertIn("another disk", errors[0])
        self.assertEqual(left, {"kept.vtu": "old"}, f"files left behind: {left}")

    def test_every_mesh_format_says_the_disk_is_full_and_leaves_nothing(self):
        for ext in ("vtu", "msh", "exo", "inp", "mesh"):
            with self.subTest(ext=ext):
                status, stderr, left = self.write(os.path.join(self.dir, f"sphere.{ext}"))
                print(f"{ext}: {stderr.strip()}")
                self.assert_refused(status, stderr, left, os.path.join(self.dir, f"sphere.{ext}"))

    def test_a_disk_with_room_for_part_of_the_file_is_found_full(self):
        # 4.4 MB free of 8 MB, more than the 4 MB at which a disk counts as
        # full, for a 4.9 MB file: full only while the partial file is there.
        status, stderr, left = self.write(os.path.join(self.dir, "sphere.vtu"), size="8m", mesh_size="1.0",
                                          filler_kb=3700)
        self.assert_refused(status, stderr, left, os.path.join(self.dir, "sphere.vtu"))

    def test_a_file_to_replace_survives_a_full_disk(self):
        status, stderr, left = self.write(os.path.join(self.dir, "kept.vtu"), "--force")
        self.assert_refused(status, stderr, left, os.path.join(self.dir, "kept.vtu"))

    def test_a_report_or_plot_that_does_not_fit_says_the_disk_is_full_and_the_mesh_is_not_kept(self):
        # The mesh goes to a disk with room; the report or the plot to one
        # page of tmpfs that kept.vtu already fills.
        roomy = workdir("full_disk_roomy")
        for option, name in (("--report", "report.json"), ("--plot", "plot.svg")):
            with self.subTest(option=option):
                mesh = os.path.join(roomy, f"sphere_{name}.vtu")
                status, stderr, left = self.write(mesh, option, os.path.join(self.dir, name), size="4k")
                print(f"{option}: {stderr.strip()}")
                self.assert_refused(status, stderr, left, os.path.join(self.dir, name))
                self.assertFalse(os.path.exists(mesh), "the mesh was kept without its report")


class FullDiskBatch(unittest.TestCase):
    def test_a_batch_holds_back_the_jobs_for_a_full_disk_and_runs_the_others(self):
        ph = phantoms("full_disk_batch")
        full, roomy = workdir("full_disk_batch_mount"), workdir("full_disk_batch_roomy")
        jobs = [("sphere", full), ("torus", full), ("thin_plate", roomy), ("two_spheres", full)]
        manifest = os.path.join(roomy, "jobs.csv")
        with open(manifest, "w") as f:
            f.write("input,output\n")
            for name, folder in jobs:
                f.write(f"{os.path.join(ph, name + '.nii.gz')},{os.path.join(folder, name + '.vtu')}\n")
        cmd = " ".join(shlex.quote(a) for a in [ISOHEX, "batch", manifest, "--size", "1.25", "-q"])
        status, stderr, left = outcome(self, *in_small_disk(full, cmd, "1m"))
        print(stderr)
        self.assertNotEqual(status, 0)
        errors = {}
        for line in stderr.splitlines():
            m = re.search(r"\] (\S+): error: ", line)
            if m:
                errors[m.group(1)] = line
        self.assertEqual(sorted(errors), ["sphere", "torus", "two_spheres"], stderr)
        self.assertIn("ran out of space while writing it", errors["sphere"])
        for held in ("torus", "two_spheres"):
            self.assertIn("not run", errors[held])
            self.assertIn("ran out of space in the job of " + os.path.join(ph, "sphere.nii.gz"), errors[held])
            self.assertNotIn("could not write", errors[held])
        self.assertTrue(os.path.exists(os.path.join(roomy, "thin_plate.vtu")))
        self.assertEqual(left, {"kept.vtu": "old"})


if __name__ == "__main__":
    unittest.main()
