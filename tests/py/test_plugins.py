"""The launcher and the plugins (cli/launcher/, core/include/isohex/core/Plugin.hpp):
`isohex --version` from the launcher equals the program's; a mesh format's
plugin is loaded only when that format is read or written, and ITK's not for
a NIfTI-1 scan meshed at a given iso value; a missing or damaged plugin is
one error line naming it and what to do, exit status 1, with no output or
temporary file left behind; the folder isohex runs from is never searched
for the libraries it loads."""
import os
import shutil
import subprocess
import sys
import unittest

sys.path.insert(0, os.path.dirname(__file__))
from common import ISOHEX, SHARED_DATA, phantoms, workdir  # noqa: E402

# The build tree's plugins are in BUILD/lib/isohex, beside BUILD/cli/isohex.
BUILD_PLUGINS = os.path.abspath(os.path.join(os.path.dirname(ISOHEX), "..", "lib", "isohex"))


def isohex(args, plugin_dir):
    env = dict(os.environ, ISOHEX_PLUGIN_DIR=plugin_dir)
    return subprocess.run([ISOHEX] + args, capture_output=True, text=True, env=env, timeout=300)


class Plugins(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.dir = workdir("plugins")
        helper = os.environ.get("ISOHEX_TEST_MESHES", "")
        if not helper:
            raise RuntimeError("make_test_meshes not found: set ISOHEX_TEST_MESHES (ctest does)")
        subprocess.run([helper, cls.dir], check=True, capture_output=True)
        cls.vtu = os.path.join(cls.dir, "block.vtu")

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.dir, ignore_errors=True)

    def folder(self, name, plugins=()):
        path = os.path.join(self.dir, name)
        os.mkdir(path)
        for p in plugins:
            os.symlink(os.path.join(BUILD_PLUGINS, p), os.path.join(path, p))
        return path

    def test_version_from_the_launcher_equals_the_program(self):
        launcher = subprocess.run([ISOHEX, "--version"], capture_output=True, text=True)
        program = subprocess.run([os.path.join(os.path.dirname(ISOHEX), "isohex-run"), "--version"],
                                 capture_output=True, text=True)
        self.assertEqual(launcher.returncode, 0)
        self.assertTrue(launcher.stdout.startswith("isohex ") and "openvdb" in launcher.stdout, launcher.stdout)
        self.assertEqual(launcher.stdout, program.stdout)

    def test_launcher_without_the_program_says_so(self):
        # The installed layout (bin/isohex, lib/isohex/) with bin/isohex-run missing.
        root = self.folder("launcher_alone")
        alone = os.path.join(root, "bin")
        os.mkdir(alone)
        os.mkdir(os.path.join(root, "lib"))
        os.symlink(BUILD_PLUGINS, os.path.join(root, "lib", "isohex"))
        shutil.copy(ISOHEX, alone)
        proc = subprocess.run([os.path.join(alone, os.path.basename(ISOHEX)), "quality", self.vtu],
                              capture_output=True, text=True)
        err = proc.stderr.strip()
        self.assertEqual(proc.returncode, 1)
        self.assertEqual(err.count("\n"), 0, err)
        self.assertIn(os.path.join(alone, "isohex-run"), err)

    def test_only_the_formats_plugins_are_loaded(self):
        only_vtu = self.folder("only_vtu", ["libisohex_vtu.so"])
        out = self.folder("out_inp")
        proc = isohex(["convert", self.vtu, os.path.join(out, "block.inp")], only_vtu)
        self.assertEqual(proc.returncode, 0, proc.stderr)
        self.assertGreater(os.path.getsize(os.path.join(out, "block.inp")), 0)

    def test_missing_plugin_is_one_line_and_leaves_nothing(self):
        only_vtu = self.folder("only_vtu_2", ["libisohex_vtu.so"])
        out = self.folder("out_msh")
        proc = isohex(["convert", self.vtu, os.path.join(out, "block.msh")], only_vtu)
        err = proc.stderr.strip()
        self.assertEqual(proc.returncode, 1, err)
        self.assertEqual(err.count("\n"), 0, err)
        for text in ("libisohex_msh.so", "missing", "ISOHEX_PLUGIN_DIR", "isohex_plugins"):
            self.assertIn(text, err)
        self.assertEqual(os.listdir(out), [])

    def test_a_scan_is_meshed_without_loading_the_surface_reader(self):
        # Assimp (with draco, minizip and the rest) is loaded only to read a
        # triangle surface: a scan meshes with no surface plugin present, and
        # the dynamic loader never opens libassimp on the way.
        no_assimp = self.folder("no_assimp", [p for p in sorted(os.listdir(BUILD_PLUGINS))
                                              if p.endswith(".so") and p != "libisohex_assimp.so"])
        sphere = os.path.join(phantoms("plugins"), "sphere.nii.gz")
        out = os.path.join(self.dir, "sphere.vtu")
        env = dict(os.environ, ISOHEX_PLUGIN_DIR=no_assimp, LD_DEBUG="files")
        proc = subprocess.run([ISOHEX, "mesh", sphere, "--iso", "50", "--size", "4", "-o", out, "--force", "-q"],
                              capture_output=True, text=True, env=env, timeout=300)
        self.assertEqual(proc.returncode, 0, proc.stderr[-2000:])
        self.assertGreater(os.path.getsize(out), 0)
        self.assertIn("libisohex_vtu.so", proc.stderr)  # LD_DEBUG names what was opened
        opened = [ln.strip() for ln in proc.stderr.splitlines() if "libassimp" in ln]
        self.assertEqual(opened[:3], [])

    def test_a_surface_without_its_reader_plugin_says_what_it_is_for(self):
        surface = os.path.join(SHARED_DATA, "sphere966.off")
        self.assertTrue(os.path.exists(surface), surface)
        only_vtu = self.folder("only_vtu_3", ["libisohex_vtu.so"])
        out = os.path.join(self.dir, "surface.vtu")
        proc = isohex(["mesh", surface, "-o", out, "-q"], only_vtu)
        err = proc.stderr.strip()
        self.assertEqual(proc.returncode, 1, err)
        self.assertEqual(err.count("\n"), 0, err)
        self.assertIn("libisohex_assimp.so (reads triangle surfaces", err)
        self.assertFalse(os.path.exists(out))

    def test_reading_without_the_plugin_says_what_it_is_for(self):
        proc = isohex(["quality", self.vtu], self.folder("empty"))
        self.assertEqual(proc.returncode, 1)
        self.assertIn("libisohex_vtu.so (reads and writes .vtu files", proc.stderr)

    def test_damaged_plugin_is_one_line_naming_it(self):
        damaged = self.folder("damaged")
        with open(os.path.join(damaged, "libisohex_vtu.so"), "wb") as f:
            f.write(b"not a shared object\n" * 10)
        proc = isohex(["quality", self.vtu], damaged)
        err = proc.stderr.strip()
        self.assertEqual(proc.returncode, 1)
        self.assertEqual(err.count("\n"), 0, err)
        self.assertIn("libisohex_vtu.so", err)
        self.assertIn("could not be loaded", err)

    def test_a_nifti1_scan_is_meshed_without_the_itk_plugin(self):
        # libnifti2 reads .nii.gz (imaging/src/NiftiRead.cpp); ITK's plugin is
        # loaded only for what needs it, such as Otsu's threshold.
        scans = phantoms("plugins_nifti")
        try:
            only_vtu = self.folder("only_vtu_nifti", ["libisohex_vtu.so"])
            out = os.path.join(self.dir, "sphere.vtu")
            sphere = os.path.join(scans, "sphere.nii.gz")
            proc = isohex(["mesh", sphere, "--iso", "50", "--size", "2", "-o", out, "--force", "-q"], only_vtu)
            self.assertEqual(proc.returncode, 0, proc.stderr)
            self.assertGreater(os.path.getsize(out), 0)
            proc = isohex(["mesh", sphere, "--size", "2", "-o", out, "--force", "-q"], only_vtu)
            self.assertEqual(proc.returncode, 1)
            self.assertIn("libisohex_itk.so", proc.stderr)
        finally:
            shutil.rmtree(scans, ignore_errors=True)

    def test_libraries_in_the_working_folder_are_not_loaded(self):
        # Files named like isohex's own library and a system dependency, in the
        # folder the command runs from: the loader must not look there (an
        # empty run-path entry means the current directory).
        cwd = self.folder("cwd_libraries")
        for name in ("libtbb.so.12", "libisohex_core.so", "libITKCommon-5.2.so.1"):
            with open(os.path.join(cwd, name), "wb") as f:
                f.write(b"not a shared object\n")
        env = dict(os.environ, ISOHEX_PLUGIN_DIR=BUILD_PLUGINS)
        for args in (["--version"], ["quality", self.vtu]):
            proc = subprocess.run([ISOHEX] + args, capture_output=True, text=True, env=env, cwd=cwd, timeout=300)
            self.assertEqual(proc.returncode, 0, proc.stderr)
            self.assertNotIn("error while loading shared libraries", proc.stderr)

    def test_run_paths_are_absolute_or_origin_relative(self):
        programs = [ISOHEX, os.path.join(os.path.dirname(ISOHEX), "isohex-run")]
        plugins = [os.path.join(BUILD_PLUGINS, f) for f in sorted(os.listdir(BUILD_PLUGINS)) if f.endswith(".so")]
        self.assertTrue(plugins)
        ldd = subprocess.run(["ldd", programs[1]], capture_output=True, text=True, check=True).stdout
        own = [ln.split("=>")[1].split("(")[0].strip() for ln in ldd.splitlines() if "libisohex_" in ln]
        self.assertEqual(len(own), 2, ldd)  # libisohex_core.so and libisohex_imaging.so
        for path in programs + plugins + own:
            out = subprocess.run(["readelf", "-d", path], capture_output=True, text=True, check=True).stdout
            for line in out.splitlines():
                if "(RUNPATH)" in line or "(RPATH)" in line:
                    entries = line.split("[", 1)[1].rsplit("]", 1)[0].split(":")
                    for e in entries:
                        self.assertTrue(e.startswith("/") or e.startswith("$ORIGIN"),
                                        f"{path}: run-path entry {e!r} in {entries}")


if __name__ == "__main__":
    unittest.main()
