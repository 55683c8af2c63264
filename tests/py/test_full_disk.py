"""A disk that fills up while isohex writes. Every mesh format and the report
fail with one error line that names the file and says the disk is full; the
command exits non-zero and leaves neither the file nor its temporary, and an
output it was told to replace (--force) survives unchanged. A batch does not
run the later jobs that write to a disk it found full (each would mesh and
then fail), and runs those that write elsewhere.

The full disk is a 1 MB tmpfs mounted in a private mount namespace (util-linux
`unshare`), so nothing outside the test sees it; the 20 k-hex sphere's mesh
needs several MB in every format."""
import os
import shlex
import subprocess
import sys
import unittest

sys.path.insert(0, os.path.dirname(__file__))
from common import ISOHEX, phantoms, workdir  # noqa: E402

MARK = "--- folder after the run ---"


def in_small_disk(folder, command, size):
    """Runs `command` (a shell line) with a tmpfs of `size` mounted on `folder`, then
    prints MARK and each file left there with its first bytes; returns the
    CompletedProcess. The tmpfs goes when the namespace ends."""
    script = (f"mount -t tmpfs -o size={size} tmpfs {shlex.quote(folder)} || exit 99; "
              f"printf old > {shlex.quote(folder)}/kept.vtu; "
              f"{command}; echo \"status $?\"; echo '{MARK}'; "
              f"for f in {shlex.quote(folder)}/.[!.]* {shlex.quote(folder)}/*; do "
              f"[ -e \"$f\" ] && echo \"$(basename \"$f\") $(head -c 8 \"$f\" | tr -dc '[:print:]')\"; done; true")
    # Root may mount in a new mount namespace; where that is not allowed
    # (a container without CAP_SYS_ADMIN, a user), a new user namespace gives
    # the right to mount a tmpfs.
    for unshare in (["unshare", "--mount"], ["unshare", "--user", "--map-root-user", "--mount"]):
        proc = subprocess.run(unshare + ["sh", "-c", script], capture_output=True, text=True, timeout=300)
        if "status" in proc.stdout:
            break
    return proc


class FullDisk(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.ph = phantoms("full_disk")
        cls.dir = workdir("full_disk_mount")

    def write(self, out, *extra, size="1m"):
        sphere = os.path.join(self.ph, "sphere.nii.gz")
        cmd = " ".join(shlex.quote(a) for a in [ISOHEX, "mesh", sphere, "--size", "1.25", "-q", "-o", out, *extra])
        proc = in_small_disk(self.dir, cmd, size)
        status = [line for line in proc.stdout.splitlines() if line.startswith("status ")]
        self.assertTrue(status, "could not mount a tmpfs: " + proc.stderr)
        left = proc.stdout.split(MARK, 1)[1].split()
        return int(status[0].split()[1]), proc.stderr, dict(zip(left[::2], left[1::2]))

    def assert_refused(self, status, stderr, left, named):
        errors = [line for line in stderr.splitlines() if "error" in line]
        self.assertNotEqual(status, 0, stderr)
        self.assertEqual(len(errors), 1, stderr)
        self.assertIn(named, errors[0])
        self.assertIn("is full", errors[0])
        self.assertIn("another disk", errors[0])
        self.assertEqual(left, {"kept.vtu": "old"}, f"files left behind: {left}")

    def test_every_mesh_format_says_the_disk_is_full_and_leaves_nothing(self):
        for ext in ("vtu", "msh", "exo", "inp", "mesh"):
            with self.subTest(ext=ext):
                status, stderr, left = self.write(os.path.join(self.dir, f"sphere.{ext}"))
                print(f"{ext}: {stderr.strip()}")
                self.assert_refused(status, stderr, left, os.path.join(self.dir, f"sphere.{ext}"))

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
        proc = in_small_disk(full, cmd, "1m")
        status = [line for line in proc.stdout.splitlines() if line.startswith("status ")]
        self.assertTrue(status, "could not mount a tmpfs: " + proc.stderr)
        print(proc.stderr)
        self.assertNotEqual(int(status[0].split()[1]), 0)
        errors = {line.split("] ")[1].split(":")[0]: line for line in proc.stderr.splitlines() if "error" in line}
        self.assertEqual(sorted(errors), ["sphere", "torus", "two_spheres"], proc.stderr)
        self.assertIn("is full", errors["sphere"])
        for held in ("torus", "two_spheres"):
            self.assertIn("not run", errors[held])
            self.assertIn("filled up in the job of " + os.path.join(ph, "sphere.nii.gz"), errors[held])
            self.assertNotIn("could not write", errors[held])
        self.assertTrue(os.path.exists(os.path.join(roomy, "thin_plate.vtu")))
        self.assertRegex(proc.stdout, r"4 job\(s\): 1 ok, 0 skipped, 3 failed")
        left = proc.stdout.split(MARK, 1)[1].split()
        self.assertEqual(dict(zip(left[::2], left[1::2])), {"kept.vtu": "old"})


if __name__ == "__main__":
    unittest.main()
