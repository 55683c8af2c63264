"""The report (--report) against independent computation, and the progress channels on stderr:
--log-json (one JSON object per line), plain lines when stderr is not a terminal, --quiet.

Independent figures: VTK's reader counts cells and points; vtkMeshQuality's scaled Jacobian binned
by numpy.histogram gives the histogram; vtkCellSizeFilter sums the volume; vtkNIFTIImageReader
reads dimensions, spacing and the qform of the scan (converted from NIfTI's RAS to ITK's LPS)."""
import json
import os
import subprocess
import sys
import unittest

import numpy as np
import vtk
from vtk.util import numpy_support as ns

sys.path.insert(0, os.path.dirname(__file__))
from common import SOURCE, run, workdir  # noqa: E402
from vtk_tools import read_vtu, vtk_sj, vtk_volumes  # noqa: E402

sys.path.insert(0, os.path.join(SOURCE, "samples"))
from make_phantoms import ramp, write_nifti  # noqa: E402

STAGES = ["load", "select", "octree", "extract", "pillow", "optimize", "fidelity", "write"]


def trilinear_volumes(grid):
    """Exact volume of each trilinear hex (2x2x2 Gauss points integrate its Jacobian determinant exactly)."""
    pts = ns.vtk_to_numpy(grid.GetPoints().GetData()).astype(float)
    x = pts[ns.vtk_to_numpy(grid.GetCells().GetConnectivityArray()).reshape(-1, 8)]  # (hexes, 8, 3), VTK order
    ref = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], float)
    g = (0.5 - 0.5 / np.sqrt(3), 0.5 + 0.5 / np.sqrt(3))
    vol = np.zeros(len(x))
    for p in ((u, v, w) for u in g for v in g for w in g):
        basis = np.where(ref == 1, p, 1 - np.array(p))  # (8, 3): each node's 1-D factors
        sign = np.where(ref == 1, 1.0, -1.0)
        dn = np.empty((8, 3))  # d(shape_i)/d(param_d)
        for d in range(3):
            others = [e for e in range(3) if e != d]
            dn[:, d] = sign[:, d] * basis[:, others[0]] * basis[:, others[1]]
        jac = np.einsum("id,nic->ndc", dn, x)
        vol += np.linalg.det(jac) / 8
    return vol


def nifti_geometry(path):
    """Dimensions, spacing, and LPS origin and direction of voxel (0,0,0) as VTK reads the NIfTI."""
    r = vtk.vtkNIFTIImageReader()
    r.SetFileName(path)
    r.Update()
    img = r.GetOutput()
    dims = list(img.GetDimensions())
    spacing = np.array(img.GetSpacing())
    m = r.GetQFormMatrix() or r.GetSFormMatrix()
    # no qform/sform (NIfTI "method 1", as VTK writes an image at the origin): voxel index times spacing
    q = np.array([[m.GetElement(i, j) for j in range(4)] for i in range(4)]) if m else np.eye(4)
    # VTK's image coordinates (origin + index * spacing) -> RAS through the 4x4 matrix; RAS -> LPS flips x, y
    lps = np.diag([-1.0, -1.0, 1.0])
    origin = lps @ (q[:3, :3] @ np.array(img.GetOrigin()) + q[:3, 3])
    direction = lps @ q[:3, :3]  # columns: the world direction of each index axis
    return dims, spacing, origin, direction


class Reports(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.dir = workdir("reports")
        subprocess.run(["/usr/bin/python3", os.path.join(SOURCE, "samples", "make_phantoms.py"), cls.dir,
                        "--size", "48"], check=True, capture_output=True)
        # An ellipsoid on anisotropic voxels away from the origin, so spacing and origin are not 1 and 0.
        n = (40, 36, 30)
        spacing = (1.2, 1.0, 1.5)
        origin = (12.5, -30.0, 7.25)
        idx = np.meshgrid(*(np.arange(k) for k in n), indexing="ij")
        c = [(k - 1) / 2 for k in n]
        x, y, z = ((i - ci) * s for i, ci, s in zip(idx, c, spacing))
        r = np.sqrt((x / 16) ** 2 + (y / 12) ** 2 + (z / 14) ** 2)
        cls.scan = os.path.join(cls.dir, "ellipsoid.nii.gz")
        write_nifti(cls.scan, ramp((r - 1) * 12), spacing=spacing, origin=origin)
        cls.vtu = os.path.join(cls.dir, "ellipsoid.vtu")
        cls.report_path = os.path.join(cls.dir, "ellipsoid.json")
        cls.proc = run(["mesh", cls.scan, "--iso", "50", "--size", "3", "-o", cls.vtu, "--report", cls.report_path,
                        "--log-json", "--threads", "2"])
        with open(cls.report_path) as f:
            cls.report = json.load(f)
        cls.grid = read_vtu(cls.vtu)

    # --- --log-json ------------------------------------------------------------------------------

    def test_log_json_is_one_object_per_line_with_every_stage(self):
        events = []
        for line in self.proc.stderr.splitlines():
            e = json.loads(line)  # every line, not just most
            self.assertIsInstance(e, dict, line)
            self.assertIn("event", e, line)
            self.assertIsInstance(e["time"], float)
            events.append(e)
        begins = [e["stage"] for e in events if e["event"] == "stage_begin"]
        ends = [e["stage"] for e in events if e["event"] == "stage_end"]
        for s in STAGES:
            self.assertIn(s, begins)
            self.assertIn(s, ends)
        self.assertEqual(begins[0], "load")
        self.assertEqual(ends[-1], "write")
        # begin and end alternate: each stage ends before the next begins
        seq = [(e["event"], e["stage"]) for e in events if e["event"] in ("stage_begin", "stage_end")]
        for (ev0, s0), (ev1, s1) in zip(seq[::2], seq[1::2]):
            self.assertEqual((ev0, ev1, s0), ("stage_begin", "stage_end", s1))
        self.assertTrue(all(e["seconds"] >= 0 for e in events if e["event"] == "stage_end"))
        times = [e["time"] for e in events]
        self.assertEqual(times, sorted(times))
        # the report's stage times are the logged ones (writing is timed around all outputs instead)
        logged = {}
        for e in events:
            if e["event"] == "stage_end":
                logged[e["stage"]] = logged.get(e["stage"], 0.0) + e["seconds"]
        for s in STAGES:
            if s != "write":
                self.assertAlmostEqual(self.report["timings_s"][s], logged[s], delta=1e-9, msg=s)
        self.assertGreaterEqual(self.report["timings_s"]["write"], logged["write"] * 0.99)

    def test_plain_lines_when_stderr_is_not_a_terminal_and_nothing_with_quiet(self):
        out = os.path.join(self.dir, "plain.vtu")
        p = run(["mesh", self.scan, "--iso", "50", "--size", "3", "-o", out, "--force"])
        lines = p.stderr.splitlines()
        self.assertNotIn("\r", p.stderr)
        self.assertNotIn("\033", p.stderr)
        for line in lines:
            self.assertTrue(line.startswith("isohex: "), line)
        done = [line.split()[1] for line in lines if " done in " in line]
        for s in STAGES:
            self.assertIn(s, done, p.stderr)
        q = run(["mesh", self.scan, "--iso", "50", "--size", "3", "-o", out, "--force", "-q"])
        # only warnings may remain with --quiet
        for line in q.stderr.splitlines():
            self.assertTrue(line.startswith("isohex: warning:"), line)
        self.assertNotIn("done in", q.stderr)
        self.assertIn("wrote", q.stdout)  # the result itself still goes to stdout

    # --- report contents -------------------------------------------------------------------------

    def test_counts_are_vtks(self):
        rep = self.report
        self.assertEqual(rep["hexes"], self.grid.GetNumberOfCells())
        self.assertEqual(rep["nodes"], self.grid.GetNumberOfPoints())
        types = {self.grid.GetCellType(i) for i in range(self.grid.GetNumberOfCells())}
        self.assertEqual(types, {vtk.VTK_HEXAHEDRON})
        mats = ns.vtk_to_numpy(self.grid.GetCellData().GetArray("material"))
        per = {m["material"]: m for m in rep["materials"]} if isinstance(rep["materials"], list) else None
        self.assertIsNotNone(per, rep["materials"])
        for m, count in zip(*np.unique(mats, return_counts=True)):
            self.assertEqual(per[int(m)]["hexes"], int(count))

    def test_histogram_and_statistics_are_numpys_over_vtk_quality(self):
        sj = vtk_sj(self.grid)
        h = self.report["scaled_jacobian"]
        self.assertEqual(h["degenerate"], 0)
        counts, _ = np.histogram(np.clip(sj, -1, 1), bins=np.array(h["histogram"]["edges"]))
        self.assertEqual(h["histogram"]["counts"], counts.tolist())
        self.assertEqual(sum(h["histogram"]["counts"]), len(sj))
        self.assertAlmostEqual(h["min"], sj.min(), delta=1e-9)
        self.assertAlmostEqual(h["max"], sj.max(), delta=1e-9)
        self.assertAlmostEqual(h["mean"], sj.mean(), delta=1e-9)
        self.assertEqual(h["below_0_2"], int((sj < 0.2).sum()))
        self.assertEqual(h["inverted"], int((sj < 0).sum()))

    def test_input_geometry_is_what_vtk_reads(self):
        dims, spacing, origin, direction = nifti_geometry(self.scan)
        i = self.report["input"]
        self.assertEqual(i["dimensions"], dims)
        np.testing.assert_allclose(i["spacing"], spacing, rtol=1e-6)
        np.testing.assert_allclose(i["origin"], origin, atol=1e-4)
        d = np.array(i["direction"], dtype=float).reshape(3, 3)
        np.testing.assert_allclose(d, direction, atol=1e-6)
        self.assertEqual(i["path"], self.scan)
        self.assertEqual(self.report["selection"]["iso"], 50)

    def test_timings_memory_and_versions_are_present(self):
        t = self.report["timings_s"]
        for s in STAGES + ["quality", "total"]:
            self.assertIsInstance(t[s], float, s)
            self.assertGreaterEqual(t[s], 0.0, s)
        self.assertGreaterEqual(t["total"], sum(t[s] for s in STAGES if s != "write") * 0.99)
        self.assertGreater(self.report["peak_memory_mb"], 1.0)
        v = self.report["versions"]
        first = run(["--version"]).stdout.splitlines()[0]
        self.assertEqual(first, "isohex " + v["isohex"])
        for lib in ("cli11", "tbb", "nlohmann_json"):
            self.assertIn(lib, v)
        for name, ver in v.items():
            self.assertIsInstance(ver, str, name)
            self.assertRegex(ver, r"\d", name)

    def test_fidelity_volume_is_vtks_and_close_to_the_ellipsoid(self):
        f = self.report["fidelity"]
        # isohex integrates each trilinear hex exactly; so does numpy here, from VTK's reading of the file
        self.assertAlmostEqual(f["volume_mesh"] / trilinear_volumes(self.grid).sum(), 1.0, delta=1e-9)
        # vtkCellSizeFilter splits each hex into tetrahedra, which differs from the trilinear volume where
        # boundary faces are warped; over the whole mesh it agrees to about 1e-4
        vol = vtk_volumes(self.grid).sum()
        self.assertAlmostEqual(f["volume_mesh"] / vol, 1.0, delta=1e-3)
        self.assertAlmostEqual(f["volume_change_percent"],
                               100 * (f["volume_mesh"] - f["volume_isosurface"]) / f["volume_isosurface"], delta=1e-9)
        exact = 4 / 3 * np.pi * 16 * 12 * 14
        self.assertAlmostEqual(f["volume_isosurface"] / exact, 1.0, delta=0.03)
        self.assertAlmostEqual(vol / exact, 1.0, delta=0.05)

    def test_label_map_report_per_material_against_vtk(self):
        scan = os.path.join(self.dir, "two_materials.nii.gz")
        out = os.path.join(self.dir, "labels.vtu")
        rep_path = os.path.join(self.dir, "labels.json")
        run(["mesh", scan, "--labels", "--size", "4", "-o", out, "--report", rep_path, "-q", "--force"])
        with open(rep_path) as f:
            rep = json.load(f)
        grid = read_vtu(out)
        mats = ns.vtk_to_numpy(grid.GetCellData().GetArray("material"))
        vols = vtk_volumes(grid)
        exact = trilinear_volumes(grid)
        per = {m["material"]: m for m in rep["fidelity"]["materials"]}
        self.assertEqual(sorted(per), sorted(set(mats.tolist())))
        for m, info in per.items():
            self.assertAlmostEqual(info["volume_mesh"] / exact[mats == m].sum(), 1.0, delta=1e-9, msg=str(m))
            # tetrahedra vs trilinear differ on warped interface faces, with opposite signs on their two sides
            self.assertAlmostEqual(info["volume_mesh"] / vols[mats == m].sum(), 1.0, delta=0.02, msg=str(m))
        self.assertAlmostEqual(rep["fidelity"]["volume_mesh"] / vols.sum(), 1.0, delta=1e-3)
        # the voxel count of each label, against numpy over VTK's reading of the label map
        r = vtk.vtkNIFTIImageReader()
        r.SetFileName(scan)
        r.Update()
        voxels = ns.vtk_to_numpy(r.GetOutput().GetPointData().GetScalars())
        for m in rep["selection"]["materials"]:
            self.assertEqual(m["voxels"], int((voxels == m["id"]).sum()), m)
        dims, spacing, _, _ = nifti_geometry(scan)
        self.assertEqual(rep["input"]["dimensions"], dims)
        np.testing.assert_allclose(rep["input"]["spacing"], spacing)
        self.assertEqual(rep["input"]["kind"], "labels")
        self.assertEqual(rep["hexes"], grid.GetNumberOfCells())

    def test_no_repair_no_repaired_surface_figures(self):
        # the ellipsoid needs no grid point changed: one surface, nothing to tell apart
        self.assertEqual(self.report["grid"]["repaired_field_points"], 0)
        self.assertNotIn("extracted_surface", self.report["fidelity"])
        self.assertNotIn("boundary_nodes_in_repaired_cells", self.report["fidelity"])


class FidelityWhereTheRepairChangedTheGrid(unittest.TestCase):
    """Two boxes of voxels that touch along one edge: the grid at voxel level is non-manifold there,
    the repair changes points, and the mesh follows the repaired field, which the scan's isosurface
    does not pass through. The report must put the nodes off the scan's isosurface in the repaired
    cells and measure them on the extracted surface too."""

    @classmethod
    def setUpClass(cls):
        cls.dir = workdir("repair_fidelity")
        a = np.zeros((28, 28, 20), np.float32)
        a[6:14, 6:14, 6:14] = 100
        a[14:22, 14:22, 6:14] = 100  # shares only the edge x = y = 13.5 (voxel coordinates) with the first box
        cls.scan = os.path.join(cls.dir, "pinch.nii.gz")
        # away from the origin, so the file has a qform and VTK and ITK place it alike (nifti_geometry)
        write_nifti(cls.scan, a, origin=(3.0, -2.0, 1.5))
        cls.vtu = os.path.join(cls.dir, "pinch.vtu")
        rep = os.path.join(cls.dir, "pinch.json")
        run(["mesh", cls.scan, "--iso", "50", "--level", "0", "-o", cls.vtu, "--report", rep, "-q"])
        with open(rep) as f:
            cls.report = json.load(f)

    def test_nodes_off_the_scans_isosurface_are_in_repaired_cells_and_on_the_extracted_surface(self):
        f = self.report["fidelity"]
        self.assertGreater(self.report["grid"]["repair"]["points_added"] + self.report["grid"]["repair"]["points_removed"], 0)
        off_scan = f["boundary_nodes_beyond_0_1_voxel"] + f["boundary_nodes_not_projected"]
        self.assertGreater(off_scan, 0)
        self.assertGreater(f["boundary_nodes_in_repaired_cells"], 0)
        self.assertLessEqual(f["boundary_nodes_beyond_0_1_voxel_or_not_projected_in_repaired_cells"],
                             f["boundary_nodes_in_repaired_cells"])
        own = f["extracted_surface"]
        # outside the repaired cells both surfaces are the same, so a node off the scan's is in such a
        # cell or off the extracted surface as well
        self.assertGreaterEqual(
            f["boundary_nodes_beyond_0_1_voxel_or_not_projected_in_repaired_cells"]
            + own["boundary_nodes_beyond_0_1_voxel"] + own["boundary_nodes_not_projected"], off_scan)
        # nothing here needs a node released from its surface: all of them are on the extracted one
        self.assertEqual(own["boundary_nodes_beyond_0_1_voxel"] + own["boundary_nodes_not_projected"], 0)
        self.assertLess(own["boundary_distance_max_voxels"], 0.1)

    def test_vtk_finds_the_nodes_off_the_scans_isosurface_only_at_the_pinch(self):
        # VTK's own isosurface of the scan (flying edges) and distances from the written surface nodes
        r = vtk.vtkNIFTIImageReader()
        r.SetFileName(self.scan)
        fe = vtk.vtkFlyingEdges3D()
        fe.SetInputConnection(r.GetOutputPort())
        fe.SetValue(0, 50.0)
        fe.Update()
        _, spacing, origin, direction = nifti_geometry(self.scan)
        iso = fe.GetOutput()
        pts = ns.vtk_to_numpy(iso.GetPoints().GetData()).astype(float)
        vtk_origin = np.array(r.GetOutput().GetOrigin())
        lps = origin + ((pts - vtk_origin) / spacing) @ (direction * spacing).T  # image index -> LPS world
        iso.GetPoints().SetData(ns.numpy_to_vtk(lps, deep=True))
        dist = vtk.vtkImplicitPolyDataDistance()
        dist.SetInput(iso)
        grid = read_vtu(self.vtu)
        xyz = ns.vtk_to_numpy(grid.GetPoints().GetData()).astype(float)
        cls_ = ns.vtk_to_numpy(grid.GetPointData().GetArray("node_class"))
        surface = np.where(cls_ == 1)[0]
        d = np.array([abs(dist.EvaluateFunction(xyz[i])) for i in surface])
        far = surface[d > 0.1]
        self.assertGreater(len(far), 0)
        # back to voxel coordinates: every such node is within two voxels of the shared edge
        ijk = np.linalg.solve(direction * spacing, (xyz[far] - origin).T).T
        self.assertTrue(np.all(np.hypot(ijk[:, 0] - 13.5, ijk[:, 1] - 13.5) < 2.0), ijk)
        # they are nodes the report puts in repaired cells (VTK's triangles and isohex's trilinear field
        # differ at the saddle the pinch makes, so VTK's count is not the report's to the node)
        self.assertLessEqual(len(far), self.report["fidelity"]["boundary_nodes_in_repaired_cells"])


def vtk_region_sizes(path):
    """Cells per connected region (cells joined through shared points), by VTK's vtkConnectivityFilter."""
    f = vtk.vtkConnectivityFilter()
    f.SetInputData(read_vtu(path))
    f.SetExtractionModeToAllRegions()
    f.ColorRegionsOn()
    f.Update()
    region = ns.vtk_to_numpy(f.GetOutput().GetCellData().GetArray("RegionId"))
    return sorted(np.bincount(region).tolist(), reverse=True)


class Pieces(unittest.TestCase):
    """A mesh in several pieces (each needs its own support in a finite-element model) is counted in the
    report, against VTK's connected regions, and said on stderr; one piece is not."""

    @classmethod
    def setUpClass(cls):
        cls.dir = workdir("pieces")
        subprocess.run(["/usr/bin/python3", os.path.join(SOURCE, "samples", "make_phantoms.py"), cls.dir],
                       check=True, capture_output=True)

    def mesh(self, name):
        vtu, rep = os.path.join(self.dir, name + ".vtu"), os.path.join(self.dir, name + ".json")
        p = run(["mesh", os.path.join(self.dir, name + ".nii.gz"), "--iso", "50", "--size", "3", "-o", vtu,
                 "--report", rep, "--force"])
        with open(rep) as f:
            return vtu, json.load(f), p.stderr

    def test_two_spheres_are_two_pieces_as_vtk_finds(self):
        vtu, rep, err = self.mesh("two_spheres")
        sizes = vtk_region_sizes(vtu)
        self.assertEqual(len(sizes), 2, sizes)
        pieces = rep["pieces"]
        self.assertEqual(pieces["count"], len(sizes))
        self.assertEqual(pieces["largest_hexes"], sizes[0])
        self.assertEqual(pieces["other_hexes"], sum(sizes[1:]))
        self.assertEqual([o["hexes"] for o in pieces["others"]], sizes[1:])
        self.assertIn("info: the mesh has 2 separate pieces: the largest has", err)
        self.assertIn("--keep-largest", err)
        # isohex quality on the written file finds the same
        q = json.loads(run(["quality", vtu, "--json"]).stdout)["pieces"]
        self.assertEqual((q["count"], q["largest_hexes"], q["other_hexes"]), (2, sizes[0], sizes[1]))
        np.testing.assert_allclose(q["others"][0]["at"], pieces["others"][0]["at"], atol=1e-4)

    def test_one_sphere_is_one_piece_without_a_note(self):
        vtu, rep, err = self.mesh("sphere")
        self.assertEqual(vtk_region_sizes(vtu), [rep["hexes"]])
        self.assertEqual(rep["pieces"]["count"], 1)
        self.assertEqual(rep["pieces"]["other_hexes"], 0)
        self.assertNotIn("separate pieces", err)


class LevelChoiceNote(unittest.TestCase):
    """With no --size the element size comes from the scan; an info line says why it is no coarser (the
    report's grid.rejected), so a run meshed at voxel size does not leave the user guessing."""

    @classmethod
    def setUpClass(cls):
        cls.dir = workdir("level-note")
        subprocess.run(["/usr/bin/python3", os.path.join(SOURCE, "samples", "make_phantoms.py"), cls.dir],
                       check=True, capture_output=True)

    def mesh(self, *extra):
        rep = os.path.join(self.dir, "plate.json")
        p = run(["mesh", os.path.join(self.dir, "thin_plate.nii.gz"), "--iso", "50", "-o",
                 os.path.join(self.dir, "plate.vtu"), "--report", rep, "--force", *extra])
        with open(rep) as f:
            return json.load(f), p.stderr

    def test_the_size_chosen_from_the_scan_says_why_it_is_no_coarser(self):
        rep, err = self.mesh()
        size = rep["grid"]["element_size"][0]
        rejected = rep["grid"]["rejected"]
        self.assertEqual(len(rejected), 1, rejected)
        # the thin plate: the next level's cells fail LBIE's tests
        self.assertRegex(rejected[0], r"^level \d+: \d+ coarse cells fail LBIE")
        cells = rejected[0].split(": ")[1].split()[0]
        line = next(l for l in err.splitlines() if "info: element size" in l)
        self.assertIn(f"element size {size:g} chosen from the scan, no coarser: at size {2 * size:g}, {cells} "
                      "coarse cells fail LBIE", line)
        self.assertIn("--size sets another size", line)

    def test_a_level_that_changes_the_volume_is_named_with_the_limit(self):
        # the torus at its chosen size: the next level changes the volume too much
        rep = os.path.join(self.dir, "torus.json")
        p = run(["mesh", os.path.join(self.dir, "torus.nii.gz"), "--iso", "50", "-o",
                 os.path.join(self.dir, "torus.vtu"), "--report", rep, "--force"])
        with open(rep) as f:
            grid = json.load(f)["grid"]
        size = grid["element_size"][0]
        self.assertRegex(grid["rejected"][0], r"^level \d+ changes the volume by \d+\.\d% \(more than 5\.0%\)$")
        percent = grid["rejected"][0].split(" by ")[1]
        self.assertIn(f"element size {size:g} chosen from the scan, no coarser: size {2 * size:g} changes the volume "
                      f"by {percent}. --size sets another size", p.stderr)

    def test_no_note_when_the_size_is_given(self):
        _, err = self.mesh("--size", "2")
        self.assertNotIn("info: element size", err)


if __name__ == "__main__":
    unittest.main(verbosity=2)
