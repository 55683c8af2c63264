"""`isohex --version`, `--help` and `isohex quality` as a user runs them, including
the bad files a user feeds it: missing, garbage, truncated."""
import json
import os
import shutil
import subprocess
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

    def sample_with_corner_moved(self, name, k, where):
        """SAMPLE with corner k of hex 0 moved to where(corner), corner(i) giving
        corner i's position; written to name in the work folder. Returns the
        path and the VTK grid."""
        import vtk
        r = vtk.vtkXMLUnstructuredGridReader()
        r.SetFileName(SAMPLE)
        r.Update()
        g = r.GetOutput()
        ids = g.GetCell(0).GetPointIds()
        corner = lambda i: list(g.GetPoint(ids.GetId(i)))  # noqa: E731
        g.GetPoints().SetPoint(ids.GetId(k), where(corner))
        path = os.path.join(self.dir, name)
        w = vtk.vtkXMLUnstructuredGridWriter()
        w.SetFileName(path)
        w.SetInputData(g)
        w.Write()
        return path, g

    def test_a_reader_crash_in_the_mesh_commands_is_an_error_naming_the_file(self):
        # quality, convert, smooth and insert-sheet read meshes and surfaces
        # through VTK, Gmsh and Assimp; a crash there (ISOHEX_TEST_CRASH
        # raises SIGSEGV as the file's reading begins) ended isohex with the
        # shell's "Segmentation fault".
        import signal
        samples = os.path.join(SOURCE, "samples")
        block = os.path.join(samples, "spherical_cuts_block.vtu")
        cut = os.path.join(samples, "spherical_cut_1.off")
        out = os.path.join(self.dir, "crash_out.vtu")
        cases = [
            (["quality", SAMPLE, "--report", os.path.join(self.dir, "crash.json")], "load", SAMPLE),
            (["convert", SAMPLE, out], "load", SAMPLE),
            (["smooth", SAMPLE, "-o", out, "-q"], "load", SAMPLE),
            (["insert-sheet", "--mesh", block, "--surface", cut, "-o", out, "-q"], "load@spherical_cut_1", cut),
            (["smooth", SAMPLE, "-o", out, "-q"], "optimize", SAMPLE),
        ]
        for args, fault, named in cases:
            with self.subTest(command=args[0], fault=fault):
                env = dict(os.environ, ISOHEX_TEST_CRASH=fault)
                p = run(args, check=False, env=env)
                self.assertEqual(p.returncode, 1, p.stderr)
                if fault.startswith("load"):
                    self.assertIn(f"isohex: error: {named}: a library crashed reading it (SIGSEGV", p.stderr)
                else:
                    self.assertIn(f"isohex: error: {named}: isohex crashed in its {fault} stage (SIGSEGV", p.stderr)
                self.assertFalse(os.path.exists(out))
                self.assertFalse(os.path.exists(os.path.join(self.dir, "crash.json")))
                # without the child process the same fault ends isohex
                p = run(args, check=False, env=dict(env, ISOHEX_ISOLATE="0"))
                self.assertEqual(p.returncode, -signal.SIGSEGV, p.stderr)

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

    def test_msh_section_counts_that_disagree_with_the_blocks_are_errors_not_crashes(self):
        # Gmsh's reader crashed (segmentation fault) when the $Elements header
        # promised fewer elements than the blocks hold; convert and smooth
        # left a partial output behind.
        import meshio
        msh = os.path.join(self.dir, "counts.msh")
        run(["convert", SAMPLE, msh, "--force"])
        with open(msh) as f:
            lines = f.read().split("\n")
        at = lines.index("$Elements") + 1
        blocks, total, lo, hi = lines[at].split()
        lines[at] = " ".join([blocks, "10", lo, hi])
        bad41 = os.path.join(self.dir, "fewer41.msh")
        with open(bad41, "w") as f:
            f.write("\n".join(lines))
        m = meshio.read(SAMPLE)
        v22 = os.path.join(self.dir, "v22.msh")
        meshio.write(v22, meshio.Mesh(m.points, [("hexahedron", m.cells_dict["hexahedron"])]),
                     file_format="gmsh22", binary=False)
        with open(v22) as f:
            lines = f.read().split("\n")
        at = lines.index("$Elements") + 1
        lines[at] = str(int(lines[at]) + 5)
        bad22 = os.path.join(self.dir, "more22.msh")
        with open(bad22, "w") as f:
            f.write("\n".join(lines))
        self.assertEqual(run(["quality", v22]).returncode, 0)  # the file before the edit reads
        for bad, message in ((bad41, "the element blocks hold more than the 10 elements"),
                             (bad22, "the element section ends before")):
            outs = [os.path.join(self.dir, "c.exo"), os.path.join(self.dir, "s.vtu")]
            for args in (["quality", bad], ["convert", bad, outs[0]], ["smooth", bad, "-o", outs[1], "-q"]):
                p = run(args, check=False)
                self.assertEqual(p.returncode, 1, (args, p.stderr))
                self.assertIn(os.path.basename(bad) + ": line ", p.stderr)
                self.assertIn(message, p.stderr)
            for o in outs:
                self.assertFalse(os.path.exists(o))

    def test_unknown_extension(self):
        path = os.path.join(self.dir, "mesh.stp")
        with open(path, "w") as f:
            f.write("x")
        line = self.one_line_error(["quality", path], "mesh.stp")
        self.assertIn(".vtu", line)
        self.assertIn(".msh", line)
        # formats isohex writes but cannot read are not offered to a reader
        self.assertNotIn(".exo", line)
        self.assertNotIn(".inp", line)

    def test_degenerate_hexes_are_named_beside_the_statistics_that_leave_them_out(self):
        # A hex with a zero-length edge has no scaled Jacobian (VTK gives it
        # 1e30); the statistics leave it out, so a minimum of 1 beside
        # "degenerate: 1" read as a perfect mesh.
        import vtk
        from vtk.util.numpy_support import vtk_to_numpy
        bad, g = self.sample_with_corner_moved("collapsed.vtu", 1, lambda corner: corner(0))  # collapse edge 0-1
        q = vtk.vtkMeshQuality()
        q.SetInputData(g)
        q.SetHexQualityMeasureToScaledJacobian()
        q.Update()
        sj = vtk_to_numpy(q.GetOutput().GetCellData().GetArray("Quality"))
        degenerate = int((sj > 1).sum())
        self.assertGreaterEqual(degenerate, 1)
        j = json.loads(run(["quality", bad, "--json"]).stdout)
        self.assertEqual(j["scaled_jacobian"]["degenerate"], degenerate)
        self.assertAlmostEqual(j["scaled_jacobian"]["min"], float(sj[sj <= 1].min()), places=6)
        text = run(["quality", bad]).stdout
        self.assertIn("(of the %d hexes that are not degenerate)" % (len(sj) - degenerate), text)
        self.assertNotIn("not degenerate", run(["quality", SAMPLE]).stdout)

    def test_threads_do_not_change_the_report(self):
        one = json.loads(run(["quality", SAMPLE, "--json", "--threads", "1"]).stdout)
        two = json.loads(run(["quality", SAMPLE, "--json", "--threads", "2"]).stdout)
        for j in (one, two):
            j.pop("peak_memory_mb")
        self.assertEqual(one, two)
        self.assertEqual(run(["quality", SAMPLE, "--threads", "0"], check=False).returncode, 2)

    def test_strict_fails_on_an_inverted_hex(self):
        # corner 6 through the opposite corner 0
        bad, _ = self.sample_with_corner_moved("inverted.vtu", 6,
                                               lambda corner: [2 * a - b for a, b in zip(corner(0), corner(6))])
        self.assertEqual(run(["quality", SAMPLE, "--strict"], check=False).returncode, 0)
        p2 = run(["quality", bad, "--strict"], check=False)
        self.assertEqual(p2.returncode, 3)
        self.assertIn("inverted", p2.stdout)


class SmoothCommand(unittest.TestCase):
    def test_smooth_untangles_the_interior_and_keeps_the_boundary(self):
        import numpy as np
        import vtk
        from vtk.util import numpy_support as ns
        d = workdir("smooth_cli")
        r = vtk.vtkXMLUnstructuredGridReader()
        r.SetFileName(SAMPLE)
        r.Update()
        g = r.GetOutput()
        pts = ns.vtk_to_numpy(g.GetPoints().GetData()).copy()
        conn = ns.vtk_to_numpy(g.GetCells().GetConnectivityArray()).reshape(-1, 8)
        # an interior node of the bar: in 8 hexes
        counts = np.bincount(conn.ravel(), minlength=len(pts))
        v = int(np.nonzero(counts == 8)[0][0])
        hexes = np.nonzero((conn == v).any(axis=1))[0]
        far = conn[hexes[0]][np.argmax(np.linalg.norm(pts[conn[hexes[0]]] - pts[v], axis=1))]
        moved = pts.copy()
        moved[v] = pts[v] + 1.6 * (pts[far] - pts[v])  # through the opposite corner: inverts hexes
        g.GetPoints().SetData(ns.numpy_to_vtk(moved, deep=True))
        bad = os.path.join(d, "tangled.vtu")
        w = vtk.vtkXMLUnstructuredGridWriter()
        w.SetFileName(bad)
        w.SetInputData(g)
        w.Write()
        out = os.path.join(d, "smoothed.vtu")
        p = run(["smooth", bad, "-o", out, "-q"])
        self.assertIn("inverted", p.stdout)
        r2 = vtk.vtkXMLUnstructuredGridReader()
        r2.SetFileName(out)
        r2.Update()
        q = vtk.vtkMeshQuality()
        q.SetInputData(r2.GetOutput())
        q.SetHexQualityMeasureToScaledJacobian()
        q.Update()
        sj = ns.vtk_to_numpy(q.GetOutput().GetCellData().GetArray("Quality"))
        self.assertEqual((sj < 0).sum(), 0)
        after = ns.vtk_to_numpy(r2.GetOutput().GetPoints().GetData())
        boundary = counts < 8
        np.testing.assert_array_equal(after[boundary], moved[boundary])


    def test_smooth_never_returns_a_worse_mesh_and_refuses_a_mirrored_one(self):
        # The mean-ratio sweeps alone lowered the worst hex of a good mesh
        # (two_materials from isohex mesh: 0.300 -> 0.232 by VTK); and a mesh
        # in mirrored corner order (every hex inverted) came back scrambled
        # with exit 0.
        import meshio
        import numpy as np
        from vtk_tools import vtk_sj
        d = workdir("smooth_worse")
        subprocess.run(["/usr/bin/python3", os.path.join(SOURCE, "samples", "make_phantoms.py"), d], check=True,
                       capture_output=True)
        src = os.path.join(d, "tm.vtu")
        run(["mesh", os.path.join(d, "two_materials.nii.gz"), "--labels", "-o", src, "-q", "--force"])
        out = os.path.join(d, "tm_smoothed.vtu")
        run(["smooth", src, "-o", out, "-q", "--force"])
        before, after = vtk_sj(src), vtk_sj(out)
        print(f"two_materials smoothed: VTK min {before.min():.3f} -> {after.min():.3f}, "
              f"below 0.2 {(before < 0.2).sum()} -> {(after < 0.2).sum()}")
        self.assertGreaterEqual(after.min(), before.min() - 1e-9)
        self.assertEqual(int((after <= 0).sum()), 0)
        m = meshio.read(src)
        mirrored = os.path.join(d, "mirrored.vtu")
        meshio.write(mirrored, meshio.Mesh(m.points, [("hexahedron", m.cells_dict["hexahedron"][:, [4, 5, 6, 7, 0, 1, 2, 3]])]))
        bad_out = os.path.join(d, "mirrored_smoothed.vtu")
        p = run(["smooth", mirrored, "-o", bad_out, "-q"], check=False)
        self.assertEqual(p.returncode, 1, p.stderr)
        self.assertIn("mirrored.vtu:", p.stderr)
        self.assertIn("corner order is probably mirrored", p.stderr)
        self.assertFalse(os.path.exists(bad_out))


    def test_negative_material_ids_are_refused_on_reading(self):
        # A negative material id was taken for the outside: interfaces were
        # written as boundary surfaces with duplicate names (a CalculiX
        # pressure on one loaded internal faces).
        import meshio
        import numpy as np
        d = workdir("negative_material")
        m = meshio.read(SAMPLE)
        hexes = m.cells_dict["hexahedron"]
        mat = np.where(np.arange(len(hexes)) % 2 == 0, -3, 2).astype(np.int32)
        bad = os.path.join(d, "negative.vtu")
        meshio.write(bad, meshio.Mesh(m.points, [("hexahedron", hexes)], cell_data={"material": [mat]}))
        for args in (["convert", bad, os.path.join(d, "n.exo")], ["quality", bad],
                     ["smooth", bad, "-o", os.path.join(d, "n.vtu")]):
            p = run(args, check=False)
            self.assertEqual(p.returncode, 1, (args, p.stderr))
            self.assertIn("negative.vtu: hex 0 has material id -3", p.stderr)
            self.assertEqual(len(p.stderr.strip().splitlines()), 1, p.stderr)
        self.assertEqual(os.listdir(d), ["negative.vtu"])

    def test_coordinates_too_large_to_measure_are_refused_on_reading(self):
        # A mesh scaled by 1e300: the squared edge lengths overflow, and
        # smooth ran forever (quality and convert went through).
        import meshio
        d = workdir("huge_coordinates")
        m = meshio.read(SAMPLE)
        bad = os.path.join(d, "huge.vtu")
        meshio.write(bad, meshio.Mesh(m.points * 1e300, [("hexahedron", m.cells_dict["hexahedron"])]))
        for args in (["convert", bad, os.path.join(d, "h.exo")], ["quality", bad],
                     ["smooth", bad, "-o", os.path.join(d, "h.vtu")]):
            p = run(args, check=False, timeout=120)
            self.assertEqual(p.returncode, 1, (args, p.stderr))
            self.assertIn("huge.vtu: node", p.stderr)
            self.assertIn("up to 1e30", p.stderr)
        self.assertEqual(os.listdir(d), ["huge.vtu"])
        # an ordinary mesh in metres far from the origin still reads
        far = os.path.join(d, "far.vtu")
        meshio.write(far, meshio.Mesh(m.points * 1e-3 + 1e6, [("hexahedron", m.cells_dict["hexahedron"])]))
        self.assertEqual(run(["quality", far]).returncode, 0)
        os.remove(far)


    def test_a_mesh_without_hexes_is_an_error_and_other_formats_say_they_drop_the_fields(self):
        # quality judged a file of one point and no cells (exit 0, "unused
        # node"); -o x.msh silently left out the per-hex quality fields.
        import vtk
        d = workdir("nohex")
        g = vtk.vtkUnstructuredGrid()
        pts = vtk.vtkPoints()
        pts.InsertNextPoint(0, 0, 0)
        g.SetPoints(pts)
        empty = os.path.join(d, "nohex.vtu")
        w = vtk.vtkXMLUnstructuredGridWriter()
        w.SetFileName(empty)
        w.SetInputData(g)
        w.Write()
        for args in (["quality", empty], ["convert", empty, os.path.join(d, "x.msh")],
                     ["smooth", empty, "-o", os.path.join(d, "y.vtu")]):
            p = run(args, check=False)
            self.assertEqual(p.returncode, 1, (args, p.stderr))
            self.assertIn("nohex.vtu: the mesh holds no hexahedra", p.stderr)
        out = os.path.join(d, "annotated.msh")
        p = run(["quality", SAMPLE, "-o", out])
        self.assertIn("annotated.msh: the per-hex quality fields are written to .vtu files only", p.stderr)
        self.assertTrue(os.path.exists(out))
        p = run(["quality", SAMPLE, "-o", os.path.join(d, "annotated.vtu")])
        self.assertNotIn("written to .vtu files only", p.stderr)


if __name__ == "__main__":
    unittest.main(verbosity=2)
