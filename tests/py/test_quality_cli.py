"""`isohex --version`, `--help` and `isohex quality` as a user runs them, including
the bad files a user feeds it: missing, garbage, truncated."""
import json
import os
import shutil
import sys
import unittest

sys.path.insert(0, os.path.dirname(__file__))
from common import SOURCE, run, workdir  # noqa: E402

SAMPLE = os.path.join(SOURCE, "samples", "twisted_bar.vtu")


class QualityCommand(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.dir = workdir("quality_cli")

    def one_line_error(self, args, must_name):
        p = run(args, check=False)
        self.assertNotEqual(p.returncode, 0, p.stdout)
        lines = p.stderr.strip().splitlines()
        self.assertEqual(len(lines), 1, p.stderr)
        self.assertIn(must_name, lines[0])
        self.assertNotIn("internal error", lines[0])
        return lines[0]

    def test_version_and_help(self):
        v = run(["--version"])
        self.assertTrue(v.stdout.startswith("isohex "), v.stdout)
        self.assertIn("vtk", v.stdout)
        h = run(["--help"])
        for cmd in ("mesh", "quality", "compare", "convert", "smooth"):
            self.assertIn(cmd, h.stdout)

    def test_json_report_has_the_stable_keys(self):
        j = json.loads(run(["quality", SAMPLE, "--json"]).stdout)
        self.assertEqual(j["hexes"], 384)
        for key in ("min", "mean", "max", "below_0_2", "inverted", "histogram"):
            self.assertIn(key, j["scaled_jacobian"])
        self.assertEqual(len(j["scaled_jacobian"]["histogram"]["edges"]), 12)
        self.assertEqual(sum(j["scaled_jacobian"]["histogram"]["counts"]), 384)
        self.assertTrue(j["validity"]["ok"])

    def test_missing_file(self):
        self.one_line_error(["quality", os.path.join(self.dir, "absent.vtu")], "absent.vtu")

    def test_garbage_files(self):
        for name, data in (("garbage.vtu", b"\x00\x01garbage" * 50), ("garbage.msh", b"not a mesh at all\n" * 20)):
            path = os.path.join(self.dir, name)
            with open(path, "wb") as f:
                f.write(data)
            self.one_line_error(["quality", path], name)

    def test_truncated_files(self):
        vtu = os.path.join(self.dir, "bar.vtu")
        msh = os.path.join(self.dir, "bar.msh")
        shutil.copy(SAMPLE, vtu)
        run(["convert", vtu, msh, "--force"])
        for path in (vtu, msh):
            with open(path, "rb") as f:
                data = f.read()
            for frac in (0.3, 0.7, 0.95):
                cut = path.replace("bar.", f"cut{int(frac * 100)}.")
                with open(cut, "wb") as f:
                    f.write(data[: int(len(data) * frac)])
                self.one_line_error(["quality", cut], os.path.basename(cut))

    def test_unknown_extension(self):
        path = os.path.join(self.dir, "mesh.stp")
        with open(path, "w") as f:
            f.write("x")
        line = self.one_line_error(["quality", path], "mesh.stp")
        self.assertIn(".vtu", line)

    def test_strict_fails_on_an_inverted_hex(self):
        import vtk
        r = vtk.vtkXMLUnstructuredGridReader()
        r.SetFileName(SAMPLE)
        r.Update()
        g = r.GetOutput()
        ids = g.GetCell(0).GetPointIds()
        p = list(g.GetPoint(ids.GetId(6)))
        q = g.GetPoint(ids.GetId(0))
        g.GetPoints().SetPoint(ids.GetId(6), [2 * q[i] - p[i] for i in range(3)])  # through the opposite corner
        bad = os.path.join(self.dir, "inverted.vtu")
        w = vtk.vtkXMLUnstructuredGridWriter()
        w.SetFileName(bad)
        w.SetInputData(g)
        w.Write()
        self.assertEqual(run(["quality", SAMPLE, "--strict"], check=False).returncode, 0)
        p2 = run(["quality", bad, "--strict"], check=False)
        self.assertEqual(p2.returncode, 3)
        self.assertIn("inverted", p2.stdout)


if __name__ == "__main__":
    unittest.main(verbosity=2)
