"""Issue 6 on real inputs: the default pipeline (fundamental sheet + untangling +
mean-ratio optimisation) judged from the written .vtu files by VTK's
vtkMeshQuality, against the same optimiser without the sheet (the seed's
comparison), and for thread-count independence.

Asserted below, pillowed + optimised, VTK scaled Jacobian:
  phantoms (sphere, torus, two spheres, thin plate, two materials) and
      skull_ct (iso 2.9), JHU labels, ch2bet at 4 mm, femur.off: no inverted
      hex; the scans except the label atlas have fewer hexes below 0.2 than
      without the sheet (on the atlas the two sheets per interface meet at
      curves of three labels and it has more); the skull's smallest scaled
      Jacobian is at least 0.3 (issue 6's target) after the max-min pass on
      the worst hexes. The figures of every run are in bench/RESULTS.md.
"""
import json
import os
import subprocess
import sys
import unittest

import numpy as np
from vtk.util import numpy_support as ns

sys.path.insert(0, os.path.dirname(__file__))
from common import SHARED_DATA, SOURCE, run, run_below_allowed, workdir  # noqa: E402
from vtk_tools import read_vtu, vtk_hex_quality, vtk_sj  # noqa: E402


class SmoothingOnRealInputs(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.dir = workdir("smooth_real")
        ph = os.path.join(cls.dir, "phantoms")
        subprocess.run(["/usr/bin/python3", os.path.join(SOURCE, "samples", "make_phantoms.py"), ph],
                       check=True, capture_output=True)
        cls.ph = ph

    def tearDown(self):
        """Each test's meshes go when it ends (up to 300 MB for the ch2bet 2 mm ones)."""
        if os.environ.get("ISOHEX_KEEP_TEST_FILES"):
            return
        for entry in os.listdir(self.dir):
            path = os.path.join(self.dir, entry)
            if os.path.isfile(path):
                os.remove(path)

    def mesh(self, name, src, *opts, threads=2, allow_below=False, target=0.0):
        out = os.path.join(self.dir, f"{name}.vtu")
        args = ["mesh", src, *opts, "--threads", threads, "-o", out, "--report", out + ".json", "-q", "--force"]
        if allow_below:  # a case meant to leave hexes inverted: written, exit status 4 (common.py)
            run_below_allowed(args, out, target)
        else:
            run(args)
        with open(out + ".json") as f:
            rep = json.load(f)
        return out, rep

    def check_clean(self, name, src, *opts):
        out, rep = self.mesh(name, src, *opts)
        sj = vtk_sj(out)
        f = rep["fidelity"]
        print(f"{name}: {len(sj)} hexes, VTK SJ min {sj.min():.3f} mean {sj.mean():.3f}, "
              f"inverted {(sj < 0).sum()}, boundary distance mean {f['boundary_distance_mean_voxels']:.4f} "
              f"max {f['boundary_distance_max_voxels']:.3f} voxels, "
              f"{rep['optimization']['surface_nodes_off_surface']} nodes off the surface")
        self.assertEqual(int((sj <= 0).sum()), 0, name)
        self.assertTrue(rep["validity"]["ok"], f"{name}: {rep['validity']}")
        self.assertEqual(rep["optimization"]["inverted_after"], 0)
        self.assertLess(f["boundary_distance_mean_voxels"], 0.1, name)
        return sj, rep

    def test_worst_hex_pass_keeps_edges_from_collapsing(self):
        # The worst-hex pass raises the scaled Jacobian, which is blind to edge
        # lengths: without WorstHexOptions::minEdge it pulled nodes almost onto
        # each other (VTK edge ratio max / condition max: JHU 1402 / 1108,
        # skull 124 / 75, against about 12 after the mean-ratio sweeps alone).
        for name, src, opts in (
                ("jhu", "JHU-WhiteMatter-labels-2mm.nii.gz", ["--labels"]),
                ("skull", "skull_ct.nii.gz", ["--iso", "2.9"])):
            out, rep = self.mesh(f"{name}_edges", os.path.join(SHARED_DATA, src), *opts)
            er, cn, sj = (vtk_hex_quality(out, m) for m in ("EdgeRatio", "Condition", "ScaledJacobian"))
            print(f"{name}: VTK edge ratio max {er.max():.1f}, above 20: {(er > 20).sum()}; condition max "
                  f"{cn.max():.1f}; scaled Jacobian min {sj.min():.3f}")
            self.assertEqual(rep["optimization"]["worst_hexes"]["min_edge"], 0.2)
            self.assertLess(er.max(), 30, name)
            self.assertLess(cn.max(), 30, name)
            self.assertGreater(sj.min(), 0.1, name)

    def test_fixed_boundary_warning_names_the_option(self):
        # The seed's protocol (--fix-boundary) cannot untangle hexes on a
        # folded surface: the warning says so instead of suggesting a size.
        out, rep = self.mesh("skull_fixed", os.path.join(SHARED_DATA, "skull_ct.nii.gz"), "--iso", "2.9", "--size",
                             "4", "--fix-boundary", allow_below=True)
        inverted = int((vtk_sj(out) <= 0).sum())
        left = [w for w in rep["warnings"] if "stay inverted" in w]
        print(f"skull 4 mm --fix-boundary: {inverted} inverted (VTK); {left}")
        self.assertGreater(inverted, 0)  # the case this test is about
        self.assertEqual(len(left), 1)
        self.assertIn("--fix-boundary keeps every surface node", left[0])
        self.assertNotIn("another --size may avoid them", left[0])

    def test_label_map_with_gaussian_smoothing(self):
        # --smooth blurs each label's indicator on its own. On the JHU atlas
        # two labels' points then kept trading places at one block until both
        # had used up their flips, and the repair stopped with "non-manifold
        # repair is stuck" at every sigma from 0.5 to 1.5 mm; the outside now
        # takes one of them.
        src = os.path.join(SHARED_DATA, "JHU-WhiteMatter-labels-2mm.nii.gz")
        sj, rep = self.check_clean("jhu_smooth1", src, "--labels", "--smooth", "1")
        self.assertGreater(rep["grid"]["repair"]["nonmanifold_blocks_before"], 0)
        f = rep["fidelity"]
        print(f"JHU --smooth 1: mesh {f['volume_mesh']:.0f}, union isosurface {f['volume_isosurface']:.0f}, "
              f"sum of the labels' {f['volume_labels_isosurfaces']:.0f} mm^3; VTK SJ min {sj.min():.3f}")
        # blurred one by one, each label's surface cuts the corners where labels
        # meet, more than without blur; the mesh partitions the region between
        self.assertLess(f["volume_labels_isosurfaces"], f["volume_mesh"])
        self.assertLess(f["volume_mesh"], f["volume_isosurface"])
        self.assertEqual(len(rep["selection"]["materials"]), len({m["material"] for m in rep["materials"]}))

    def test_phantoms_have_no_inverted_hex(self):
        for name, opts in [("sphere", ["--size", "1.5"]), ("torus", ["--size", "1.5"]),
                           ("two_spheres", ["--size", "1.5"]), ("thin_plate", ["--size", "1.5"]),
                           ("two_materials", ["--labels", "--size", "1.5"])]:
            sj, rep = self.check_clean(name, os.path.join(self.ph, f"{name}.nii.gz"), *opts)
            if name != "two_materials":  # smooth single surfaces: every node back on the isosurface
                self.assertEqual(rep["optimization"]["surface_nodes_off_surface"], 0, name)
            else:
                # the 1|2 interface (x = 31.5) runs through grid points of the
                # 1.5-voxel grid; it once went half a cell into label 1, which
                # lost 5.5% of its volume to label 2
                for m in rep["fidelity"]["materials"]:
                    self.assertLess(abs(m["volume_change_percent"]), 1.0, f"{name} material {m['material']}")
                self.check_curve_nodes(os.path.join(self.dir, f"{name}.vtu"), rep)

    def check_curve_nodes(self, path, rep):
        """two_materials' only curve is where labels 1, 2 and 3 meet: the
        circle where the 1|2 plane x = 31.5 cuts the ball. Its nodes form a
        chain (no boundary or interface quad holds three of them; extraction
        marks a band two cells wide where the circle runs diagonally to the
        grid) and lie on that plane within 0.1 voxel."""
        grid = read_vtu(path)
        pts = ns.vtk_to_numpy(grid.GetPoints().GetData())
        kind = ns.vtk_to_numpy(grid.GetPointData().GetArray("node_class"))
        hexes = ns.vtk_to_numpy(grid.GetCells().GetConnectivityArray()).reshape(-1, 8)
        curve = kind == 2
        self.assertGreater(int(curve.sum()), 40)
        off = np.abs(pts[curve, 0] - 31.5)
        self.assertLessEqual(float(off.max()), 0.1, f"{(off > 0.1).sum()} curve nodes off the x = 31.5 plane")
        self.assertEqual(rep["fidelity"]["curve_nodes"], int(curve.sum()))
        self.assertEqual(rep["fidelity"]["curve_nodes_beyond_0_1_voxel"], 0)
        self.assertEqual(rep["fidelity"]["curve_nodes_not_projected"], 0)
        faces = [(0, 1, 2, 3), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)]
        quads = np.concatenate([hexes[:, list(f)] for f in faces])
        on = curve[quads].sum(axis=1)
        self.assertEqual(int((on >= 3).sum()), 0, "quads with three or more curve nodes")

    def test_scans_with_the_sheet_beat_the_scans_without(self):
        # (--min-quality 0 for the scans and the label atlas: the seed's
        # comparison is of the optimiser with and without the sheet, without
        # the relaxation and feature removal a default Q of 0.3 adds to both)
        cases = [("skull", os.path.join(SHARED_DATA, "skull_ct.nii.gz"), ["--iso", "2.9", "--min-quality", "0"]),
                 ("jhu", os.path.join(SHARED_DATA, "JHU-WhiteMatter-labels-2mm.nii.gz"),
                  ["--labels", "--min-quality", "0"]),
                 ("brain_4mm", os.path.join(SHARED_DATA, "ch2bet.nii.gz"),
                  ["--size", "4", "--keep-largest", "--min-quality", "0"]),
                 ("femur", os.path.join(SHARED_DATA, "femur.off"), [])]
        for name, src, opts in cases:
            with_sheet, r1 = self.mesh(name, src, *opts)
            # without the sheet a surface may stay below its default 0.5 (written, exit status 4)
            without, r0 = self.mesh(name + "_nosheet", src, *opts, "--no-pillow", allow_below=True,
                                    target=0.5 if src.endswith(".off") else 0.0)
            s1, s0 = vtk_sj(with_sheet), vtk_sj(without)
            inv1, inv0 = int((s1 <= 0).sum()), int((s0 <= 0).sum())
            low1, low0 = int((s1 < 0.2).sum()), int((s0 < 0.2).sum())
            print(f"{name}: without sheet {inv0} inverted, {low0} below 0.2; with it {inv1} inverted, "
                  f"{low1} below 0.2 ({len(s1)} hexes)")
            # the seed's comparison: fewer poor hexes with the sheet. Not
            # for the label atlas: there the two sheets per interface meet at
            # curves of three labels whose nodes stay put, and the pillowed
            # mesh has more hexes below 0.2 than the plain one (issue 6 open).
            # From the valid start the femur and the brain at 4 mm without the
            # sheet also end with few or no hexes below 0.2 (femur 0, brain 3,
            # as with the sheet): there the sheet must not be worse, and on
            # the femur its mean is higher (0.905 against 0.780).
            if name != "jhu":
                self.assertLessEqual(low1, low0, name)
            if name == "skull":
                self.assertLess(low1, low0, name)
            if name == "femur":
                self.assertGreater(float(s1.mean()), float(s0.mean()), name)
            if name == "skull":
                self.assertGreaterEqual(float(s1.min()), 0.3, name)
                w = r1["optimization"]["worst_hexes"]
                self.assertGreaterEqual(w["min_scaled_jacobian_after"], w["min_scaled_jacobian_before"])
            # nothing left inverted with the sheet (issue 6), almost nothing
            # without it (the released surface nodes often untangle
            # everything, at the price of thousands of flat hexes)
            self.assertEqual(inv1, 0, name)
            self.assertLess(inv0, 1e-3 * len(s0), name)
            # the report's final count is VTK's; the worst-hex pass after the
            # optimiser may lift an inverted hex but never inverts one
            self.assertEqual(r1["scaled_jacobian"]["inverted"] + r1["scaled_jacobian"]["degenerate"], inv1, name)
            self.assertGreaterEqual(r1["optimization"]["inverted_after"], inv1, name)
            # nodes released from the surface stay near it: a node thrown off
            # would show in the volume (ch2bet at 2 mm once gained 12%)
            if name != "jhu":  # labels: volume against the union isosurface, see tests/pipeline
                self.assertLess(abs(r1["fidelity"]["volume_change_percent"]), 2.0, name)

    def test_the_optimiser_starts_almost_untangled(self):
        # Contouring holds back the vertices whose place inverts a hex (as
        # far as towards their cell centres, where the hexes are the grid's
        # cubes), the sheet's copies step inside every boundary quad corner,
        # and after the sheet the held-back vertices and their copies go back
        # as far as the hexes allow: at most 0.5% of the hexes are inverted
        # when the optimiser starts (issue 39), against several percent with
        # --tangled-start, and the result is no worse on the surface.
        for name, src, opts in [("skull", os.path.join(SHARED_DATA, "skull_ct.nii.gz"), ["--iso", "2.9"]),
                                ("jhu", os.path.join(SHARED_DATA, "JHU-WhiteMatter-labels-2mm.nii.gz"),
                                 ["--labels"])]:
            good, rg = self.mesh(name + "_start", src, *opts, "--valid-start")
            bad, rb = self.mesh(name + "_tangled_start", src, *opts, "--tangled-start")
            hexes = rg["hexes"]
            held = rg["pillow"]["held_back"]
            print(f"{name}: {rg['optimization']['inverted_before']} of {hexes} inverted at the optimiser's start, "
                  f"{rb['optimization']['inverted_before']} with --tangled-start; {held['vertices']} vertices held "
                  f"back, {held['at_target']} back at their target after the sheet")
            self.assertLessEqual(rg["optimization"]["inverted_before"], 0.005 * hexes, name)
            self.assertGreater(rb["optimization"]["inverted_before"], 0.01 * rb["hexes"], name)
            self.assertNotIn("held_back", rb["pillow"])
            self.assertGreater(held["vertices"], 0)
            self.assertEqual(held["at_target"] + held["part_way"] + held["not_moved"], held["vertices"])
            self.assertEqual(int((vtk_sj(good) <= 0).sum()), 0, name)
            self.assertLess(rg["fidelity"]["boundary_distance_mean_voxels"], 0.1, name)

    def test_untangling_keeps_nodes_near_where_they_started(self):
        # ch2bet at 2 mm has thousands of hexes inverted when the sheet goes
        # in. Untangling once sized its target determinant by the current edge
        # lengths, so a node that stretched its hexes raised its own target
        # and kept going: surface nodes ended 80 mm away, in hexes with
        # 100 mm edges, yet the report saw only their scaled Jacobian.
        # (--tangled-start: the default start leaves a few dozen inverted;
        # --min-quality 0: this is about untangling, not the certified minimum)
        size = 2.0
        out, rep = self.mesh("brain_2mm", os.path.join(SHARED_DATA, "ch2bet.nii.gz"),
                             "--size", str(size), "--keep-largest", "--tangled-start", "--min-quality", "0")
        grid = read_vtu(out)
        pts = ns.vtk_to_numpy(grid.GetPoints().GetData())
        hexes = ns.vtk_to_numpy(grid.GetCells().GetConnectivityArray()).reshape(-1, 8)
        longest = np.zeros(len(hexes))
        for a, b in [(0, 1), (1, 2), (2, 3), (3, 0), (4, 5), (5, 6), (6, 7), (7, 4),
                     (0, 4), (1, 5), (2, 6), (3, 7)]:
            longest = np.maximum(longest, np.linalg.norm(pts[hexes[:, a]] - pts[hexes[:, b]], axis=1))
        print(f"brain 2 mm: longest hex edge {longest.max():.2f} mm, "
              f"{rep['optimization']['inverted_before']} inverted before untangling, "
              f"{rep['optimization']['inverted_after']} after")
        self.assertGreater(rep["optimization"]["inverted_before"], 1000)  # the case this test is about
        self.assertLess(longest.max(), 4 * size)
        self.assertLess(rep["optimization"]["inverted_after"], 1e-4 * len(hexes))

    def test_filling_one_cell_pits_keeps_the_topology_and_the_volume(self):
        # A pit or well one element wide has a floor quad with four corners of
        # three boundary quads each; the sheet struggles to put a good hex
        # over it. The brain at 3 mm has a few hundred such points (narrow
        # sulci). Whether filling them gives better hexes depends on the
        # optimiser's path (it did before the worst-hex pass's joint release;
        # since then 3 mm gives 74 against 70 below 0.2, docs/DESIGN.md), so
        # this checks what filling guarantees: same topology, volume kept.
        # (--min-quality 0: no feature removal, which changes the topology)
        src = os.path.join(SHARED_DATA, "ch2bet.nii.gz")
        _, filled = self.mesh("brain_3mm_pits_filled", src, "--size", "3", "--keep-largest", "--fill-pits",
                              "--min-quality", "0")
        _, kept = self.mesh("brain_3mm_pits_kept", src, "--size", "3", "--keep-largest", "--min-quality", "0")
        print(f"brain 3 mm: {filled['grid']['pits_filled']} pit points filled; below 0.2 "
              f"{filled['scaled_jacobian']['below_0_2']} against {kept['scaled_jacobian']['below_0_2']} without "
              f"--fill-pits, inverted {filled['scaled_jacobian']['inverted']} against {kept['scaled_jacobian']['inverted']}")
        self.assertGreater(filled["grid"]["pits_filled"], 0)
        self.assertEqual(kept["grid"]["pits_filled"], 0)
        self.assertEqual(filled["grid"]["topology"], kept["grid"]["topology"])
        self.assertLess(abs(filled["fidelity"]["volume_change_percent"]), 2.0)
        self.assertLess(abs(filled["fidelity"]["volume_change_percent"] - kept["fidelity"]["volume_change_percent"]), 1.0)

    def test_joint_release_clears_the_hexes_the_optimiser_leaves_inverted_at_3mm(self):
        # ch2bet kept a few sheet hexes at scaled Jacobian about -1e-4 over
        # the floors of one-cell pits whose isosurface is a pocket of about a
        # voxel: node by node, lifting one tipped its neighbours. The joint
        # release of the worst-hex pass (two rings of nodes moved together,
        # surface nodes within half an edge of the surface) clears them. At
        # 3 mm the optimiser leaves 2 (4 mm, where this was first seen, has
        # none left since the optimiser takes three Newton steps per visit).
        # (--retries 0: the grid-edit retries must not hide a joint release
        # that fails; --tangled-start: the optimiser's start as when this was
        # seen, the default start leaves the optimiser nothing there)
        out, rep = self.mesh("brain_3mm_joint", os.path.join(SHARED_DATA, "ch2bet.nii.gz"),
                             "--size", "3", "--keep-largest", "--retries", "0", "--tangled-start", "--min-quality", "0")
        sj = vtk_sj(out)
        w = rep["optimization"]["worst_hexes"]
        print(f"brain 3 mm: {int((sj <= 0).sum())} inverted, VTK SJ min {sj.min():.3f}, "
              f"{w['joint_regions_improved']} regions improved jointly, "
              f"{w['surface_nodes_released']} surface nodes released by the pass")
        self.assertGreater(rep["optimization"]["inverted_after"], 0)  # the case this test is about
        self.assertGreaterEqual(w["joint_regions_improved"], 1)
        self.assertEqual(int((sj <= 0).sum()), 0)
        self.assertLess(rep["fidelity"]["boundary_distance_mean_voxels"], 0.1)

    def test_joint_release_clears_flat_regions_and_the_neighbours_it_leaves_inverted(self):
        # Three sizes where the joint release used to leave one hex at a
        # scaled Jacobian of about -1e-5 (session 13): ch2bet at 5 mm (the
        # corner hex under a convex corner of the sheet pressed flat: only
        # the ascent on determinants opens it), JHU at 5 mm (a kept joint
        # move left a neighbour of its hex inverted, which now gets a pass of
        # its own) and ch2bet at 2.5 mm (a knife-edge gyrus: only the
        # one-ring region clears it).
        # (--min-quality 0: this is about inverted hexes, not the certified minimum)
        cases = [("brain_5mm_joint", os.path.join(SHARED_DATA, "ch2bet.nii.gz"),
                  ["--size", "5", "--keep-largest", "--min-quality", "0"]),
                 ("jhu_5mm_joint", os.path.join(SHARED_DATA, "JHU-WhiteMatter-labels-2mm.nii.gz"),
                  ["--labels", "--size", "5", "--min-quality", "0"]),
                 ("brain_2.5mm_joint", os.path.join(SHARED_DATA, "ch2bet.nii.gz"),
                  ["--size", "2.5", "--keep-largest", "--min-quality", "0"])]
        for name, src, opts in cases:  # (the start as when they were seen)
            out, rep = self.mesh(name, src, *opts, "--retries", "0", "--tangled-start")
            sj = vtk_sj(out)
            w = rep["optimization"]["worst_hexes"]
            print(f"{name}: {rep['optimization']['inverted_after']} inverted after untangling, "
                  f"{w['joint_regions_tried']} joint moves, {w['joint_regions_improved']} kept; "
                  f"VTK: {int((sj <= 0).sum())} inverted, SJ min {sj.min():.3f}")
            self.assertGreater(rep["optimization"]["inverted_after"], 0, name)  # the case this test is about
            self.assertGreaterEqual(w["joint_regions_improved"], 1, name)
            self.assertEqual(int((sj <= 0).sum()), 0, name)
            self.assertTrue(rep["validity"]["ok"], f"{name}: {rep['validity']}")

    def test_a_higher_worst_hex_target_lifts_the_femurs_worst_hexes(self):
        # --worst-hex-target sets the scaled Jacobian the max-min pass aims
        # at (default 0.3). On the femur's smooth surface a target of 0.6
        # works on every hex below 0.6; they end higher, so VTK's minimum
        # rises and fewer hexes stay below 0.6, with the surface kept.
        src = os.path.join(SHARED_DATA, "femur.off")
        a, ra = self.mesh("femur_target_default", src)
        b, rb = self.mesh("femur_target_06", src, "--worst-hex-target", "0.6")
        sa, sb = vtk_sj(a), vtk_sj(b)
        print(f"femur: VTK SJ min {sa.min():.3f} / {sb.min():.3f}, mean {sa.mean():.4f} / {sb.mean():.4f}, "
              f"below 0.6 {(sa < 0.6).sum()} / {(sb < 0.6).sum()} (target 0.3 / 0.6)")
        self.assertEqual(rb["optimization"]["worst_hexes"]["target"], 0.6)
        self.assertGreater((sa < 0.6).sum(), 0)  # there is something to lift
        self.assertGreater(sb.min(), sa.min())
        self.assertLess((sb < 0.6).sum(), (sa < 0.6).sum())
        self.assertEqual(int((sb <= 0).sum()), 0)
        self.assertLess(rb["fidelity"]["boundary_distance_mean_voxels"], 0.1)
        # out of range: refused before anything is read or written
        bad = os.path.join(self.dir, "femur_target_bad.vtu")
        p = run(["mesh", src, "--worst-hex-target", "1.5", "-o", bad, "-q"], check=False)
        self.assertNotEqual(p.returncode, 0)
        self.assertIn("--worst-hex-target", p.stderr)
        self.assertFalse(os.path.exists(bad))
        p = run(["mesh", src, "--worst-hex-target", "0.5", "--no-worst-hex-pass", "-o", bad, "-q"], check=False)
        self.assertNotEqual(p.returncode, 0)
        self.assertIn("excludes", p.stderr)
        self.assertFalse(os.path.exists(bad))

    def test_the_surface_tolerance_lifts_the_worst_hexes_of_the_jhu_labels(self):
        # --surface-tolerance (default 0.09 voxel, under the report's 0.1-voxel
        # fidelity bound) lets the max-min pass move boundary and interface
        # nodes of hexes below the target off their surface by that much. On
        # the JHU atlas (2 mm voxels) the worst hexes sit on folds of the
        # label interfaces finer than an element: with the tolerance the
        # minimum rises and fewer hexes stay below 0.3; with 0 every node
        # stays on its surface.
        # (The boundary relaxation after the pass, up to --max-deviation, and
        # the certified minimum are off in both: not what this test is about.)
        src = os.path.join(SHARED_DATA, "JHU-WhiteMatter-labels-2mm.nii.gz")
        a, ra = self.mesh("jhu_tolerance_0", src, "--labels", "--surface-tolerance", "0", "--max-deviation", "0",
                          "--min-quality", "0")
        b, rb = self.mesh("jhu_tolerance_default", src, "--labels", "--max-deviation", "0.09", "--min-quality", "0")
        sa, sb = vtk_sj(a), vtk_sj(b)
        wa, wb = ra["optimization"]["worst_hexes"], rb["optimization"]["worst_hexes"]
        print(f"JHU: VTK SJ min {sa.min():.3f} / {sb.min():.3f}, below 0.2 {(sa < 0.2).sum()} / {(sb < 0.2).sum()}, "
              f"below 0.3 {(sa < 0.3).sum()} / {(sb < 0.3).sum()} (tolerance 0 / default); "
              f"{wb['surface_nodes_within_slack']} nodes left within {wb['surface_slack']} mm of their surface")
        self.assertEqual(wa["surface_tolerance_voxels"], 0)
        self.assertEqual(wa["surface_nodes_within_slack"], 0)
        self.assertAlmostEqual(wb["surface_tolerance_voxels"], 0.09)
        self.assertAlmostEqual(wb["surface_slack"], 0.09 * 2.0)  # voxels of 2 mm
        self.assertGreater(wb["surface_nodes_within_slack"], 0)
        self.assertGreater(sb.min(), sa.min())
        self.assertLess((sb < 0.3).sum(), (sa < 0.3).sum())
        self.assertEqual(int((sb <= 0).sum()), 0)
        self.assertTrue(rb["validity"]["ok"], rb["validity"])
        # refused before anything is read or written: out of range or NaN,
        # with the pass or the optimiser off or the boundary fixed, and with
        # --method sheets (no voxels; its volume fit moves the surface nodes
        # afterwards)
        bad = os.path.join(self.dir, "jhu_tolerance_bad.vtu")
        for opts, says in [(["--surface-tolerance", "1.5"], "--surface-tolerance"),
                           (["--surface-tolerance", "-0.1"], "--surface-tolerance"),
                           (["--surface-tolerance", "nan"], "--surface-tolerance"),
                           (["--surface-tolerance", "0.05", "--no-worst-hex-pass"], "excludes"),
                           (["--surface-tolerance", "0.05", "--no-optimize"], "excludes"),
                           (["--surface-tolerance", "0.05", "--fix-boundary"], "excludes")]:
            p = run(["mesh", src, "--labels", *opts, "-o", bad, "-q"], check=False)
            self.assertNotEqual(p.returncode, 0, opts)
            self.assertIn(says, p.stderr, opts)
            self.assertFalse(os.path.exists(bad), opts)
        p = run(["mesh", os.path.join(SHARED_DATA, "femur.off"), "--method", "sheets", "--surface-tolerance", "0.05",
                 "-o", bad, "-q"], check=False)
        self.assertNotEqual(p.returncode, 0)
        self.assertIn("--surface-tolerance", p.stderr)
        self.assertFalse(os.path.exists(bad))
        # compare keeps surface nodes fixed unless --move-boundary
        p = run(["compare", src, "--labels", "--surface-tolerance", "0.05", "-q"], check=False)
        self.assertNotEqual(p.returncode, 0)
        self.assertIn("--move-boundary", p.stderr)

    def test_grid_edits_clear_the_hexes_no_node_move_clears(self):
        # The JHU labels at 3.5 mm keep one hex inverted whatever the nodes do
        # (a bump one grid point wide where three labels and the outside
        # meet; docs/DESIGN.md). --retries (default 3) gives a grid point next
        # to it another material, a change that keeps every label's
        # components and tunnels, and meshes again. (--tangled-start: the
        # optimiser's start as when this was seen; from the default start it
        # leaves none there.)
        src = os.path.join(SHARED_DATA, "JHU-WhiteMatter-labels-2mm.nii.gz")
        a = os.path.join(self.dir, "jhu_3.5mm_no_retry.vtu")
        # (--max-deviation 0 and --keep-features: no boundary relaxation or
        # feature removal after the retries either, so the hex the retries
        # are for stays inverted)
        p = run_below_allowed(["mesh", src, "--labels", "--size", "3.5", "--retries", "0", "--max-deviation", "0",
                               "--keep-features", "--tangled-start", "--threads", 2, "-o", a, "--report", a + ".json", "-q", "--force"], a)
        with open(a + ".json") as f:
            ra = json.load(f)
        # (--min-quality 0: the retries alone, without the feature removal a
        # certified 0.3 adds, which changes the labels' topology on purpose)
        b, rb = self.mesh("jhu_3.5mm_retry", src, "--labels", "--size", "3.5", "--tangled-start", "--min-quality", "0")
        sa, sb = vtk_sj(a), vtk_sj(b)
        tries = rb["retries"]["attempts"]
        print(f"JHU 3.5 mm: VTK inverted {int((sa <= 0).sum())} -> {int((sb <= 0).sum())}, "
              f"SJ min {sa.min():.4f} -> {sb.min():.3f}, below 0.2 {(sa < 0.2).sum()} -> {(sb < 0.2).sum()}, "
              f"attempts {[(t['before'], t.get('after'), t['kept']) for t in tries]}")
        self.assertGreater(int((sa <= 0).sum()), 0)  # the case this test is about
        self.assertGreaterEqual(ra["retries"].pop("seconds"), 0)
        self.assertEqual(ra["retries"], {"allowed": 0, "floor": 0.05, "attempts": [], "points_edited": 0,
                                         "meshed_again": 0})
        self.assertEqual(int((sb <= 0).sum()), 0)
        # the retries add no defect: a local retry keeps the nodes away from
        # its edits, so a defect of the first meshing there (from the tangled
        # start: two boundary nodes at one place) stays, where meshing the
        # whole again happened to move them apart
        self.assertNotIn("inverted_hex", rb["validity"].get("defects", {}))
        self.assertLessEqual(set(rb["validity"].get("defects", {})), set(ra["validity"].get("defects", {})))
        self.assertEqual(rb["retries"]["allowed"], 3)
        kept = [t for t in tries if t["kept"]]
        self.assertGreaterEqual(len(kept), 1)
        self.assertEqual(kept[-1]["after"]["inverted"], 0)
        self.assertEqual(rb["retries"]["points_edited"], sum(len(t["edits"]) for t in kept))
        self.assertEqual(rb["retries"]["meshed_again"], sum(1 for t in tries if "after" in t))
        for t in tries:
            for e in t["edits"]:
                self.assertNotEqual(e["from"], e["to"])
        # a retry first optimises a neighbourhood of its edits, the rest
        # keeping its optimised nodes (LocalRetry.hpp); an attempt meshed
        # whole again (the neighbourhood did not help) has no region
        for t in tries:
            if "region" not in t:
                continue
            reg = t["region"]
            print(f"  attempt {t['attempt']}: {reg['hexes']} of {reg['mesh_hexes']} hexes optimised again, "
                  f"{reg['nodes']} nodes free, {reg['nodes_carried']} carried over")
            self.assertGreater(reg["hexes"], 0)
            self.assertLess(reg["hexes"], 0.5 * reg["mesh_hexes"])
            self.assertGreater(reg["nodes_carried"], 0.9 * len(sa))
        # the edits keep every label's topology (counted again on the edited
        # grid) and hardly move the volume (one grid point of 3.5 mm is about
        # 43 mm^3; a small label's own volume moves by several percent from any
        # re-optimisation at this size, so the whole mesh's is compared)
        self.assertEqual(ra["grid"]["topology"], rb["grid"]["topology"])
        self.assertLess(abs(ra["fidelity"]["volume_change_percent"] - rb["fidelity"]["volume_change_percent"]), 0.5)
        self.assertLess(rb["fidelity"]["boundary_distance_mean_voxels"], 0.1)
        # the warning goes with the inverted hex, on stderr and in the report
        self.assertIn("1 hex(es) stay inverted", p.stderr)
        self.assertEqual([w for w in ra["warnings"] if "stay inverted" in w], [
            line.split("warning: ", 1)[1] for line in p.stderr.splitlines() if "stay inverted" in line])
        self.assertFalse([w for w in rb["warnings"] if "stay inverted" in w])

    def test_grid_edits_lift_nearly_flat_hexes(self):
        # At 3 mm the JHU labels end with no hex inverted but a few nearly
        # flat (scaled Jacobian below 0.05, the default --retry-below), at the
        # same kind of places: the retries lift them, with every label's
        # topology kept; --retry-below 0 leaves them. (--tangled-start: the
        # start as when this was seen; no surface tolerance and no boundary
        # relaxation, which lift them by moving label-junction nodes.)
        src = os.path.join(SHARED_DATA, "JHU-WhiteMatter-labels-2mm.nii.gz")
        on = ("--labels", "--size", "3", "--tangled-start", "--surface-tolerance", "0", "--max-deviation", "0",
              "--min-quality", "0")
        c, rc = self.mesh("jhu_3mm_retry", src, *on)
        d, rd = self.mesh("jhu_3mm_inverted_only", src, *on, "--retry-below", "0")
        sc, sd = vtk_sj(c), vtk_sj(d)
        print(f"JHU 3 mm: VTK SJ min {sd.min():.3f} -> {sc.min():.3f}, below 0.05 {(sd < 0.05).sum()} -> "
              f"{(sc < 0.05).sum()}, below 0.2 {(sd < 0.2).sum()} -> {(sc < 0.2).sum()}")
        self.assertGreater(int((sd < 0.05).sum()), 0)  # the case this test is about
        self.assertEqual(rd["retries"]["attempts"], [])
        self.assertEqual(rd["retries"]["floor"], 0)
        self.assertEqual(int((sc <= 0).sum()), 0)
        self.assertLess(int((sc < 0.05).sum()), int((sd < 0.05).sum()))
        self.assertGreater(sc.min(), sd.min())
        self.assertLessEqual(int((sc < 0.2).sum()), int((sd < 0.2).sum()))
        self.assertGreater(rc["retries"]["points_edited"], 0)
        self.assertEqual(rc["grid"]["topology"], rd["grid"]["topology"])
        self.assertTrue(rc["validity"]["ok"], rc["validity"])
        # the retries, and the joint release they run (its steps are parallel
        # within a region), are deterministic: one thread gives the same file
        self.assertGreater(rc["optimization"]["worst_hexes"]["joint_regions_tried"], 0)
        e, re_ = self.mesh("jhu_3mm_retry_t1", src, *on, threads=1)
        with open(c, "rb") as fc, open(e, "rb") as fe:
            self.assertEqual(fc.read(), fe.read())
        # where there is no grid to edit, the options are refused before anything is written
        bad = os.path.join(self.dir, "retries_refused.vtu")
        for args, why in [(["mesh", os.path.join(SHARED_DATA, "femur.off"), "--method", "sheets"], "--method sheets"),
                          (["compare", src, "--labels"], "compare meshes every variant from one grid"),
                          (["mesh", src, "--labels", "--no-optimize"], "--no-optimize"),
                          (["mesh", src, "--labels", "--method", "voxel"], "--method voxel")]:
            for opt in (["--retries", "2"], ["--retry-below", "0.2"]):
                p = run([*args, *opt, "-o", bad, "-q"] if args[0] == "mesh" else [*args, *opt, "-q"], check=False)
                self.assertNotEqual(p.returncode, 0, args + opt)
                self.assertIn(why, p.stderr)
                self.assertIn(opt[0], p.stderr)
                self.assertFalse(os.path.exists(bad))

    def test_hexes_left_nearly_flat_are_warned_about_and_retries_are_named(self):
        # JHU at 3.5 mm with one retry: the retry clears the inverted hex and
        # five hexes stay below 0.05. Both used to pass without a word (the
        # stages' progress just started over for the retry). The boundary
        # relaxation and the surface tolerance, which lift them, are off here
        # (--max-deviation 0, --surface-tolerance 0); the end of the test runs
        # the relaxation and the warning must then be gone.
        src = os.path.join(SHARED_DATA, "JHU-WhiteMatter-labels-2mm.nii.gz")
        out = os.path.join(self.dir, "jhu_35_flat.vtu")
        p = run(["mesh", src, "--labels", "--size", "3.5", "--retries", "1", "--tangled-start", "--min-quality", "0",
                 "--max-deviation", "0",
                 "--surface-tolerance", "0", "-o", out, "--report", out + ".json", "--force"])
        with open(out + ".json") as f:
            rep = json.load(f)
        sj = vtk_sj(out)
        flat = int(((sj > 0) & (sj < 0.05)).sum())
        print(f"JHU 3.5 mm --retries 1: {flat} hexes below 0.05 (VTK), min {sj.min():.4f}")
        self.assertGreater(flat, 0)  # the case this test is about
        self.assertIn("meshing again (retry 1 of 1)", p.stderr)
        warned = [w for w in rep["warnings"] if "stay nearly flat" in w]
        self.assertEqual(len(warned), 1, rep["warnings"])
        self.assertIn("stay nearly flat", p.stderr)
        self.assertTrue(warned[0].startswith(f"{flat} hex(es) stay nearly flat"), warned[0])
        self.assertIn(f"lowest {sj.min():.4f}"[:-1], warned[0])
        # where: the centre of a hex whose VTK value is the lowest
        at = np.array([float(v) for v in warned[0].split(" at (")[1].split(")")[0].split(",")])
        g = read_vtu(out)
        pts = ns.vtk_to_numpy(g.GetPoints().GetData())
        conn = ns.vtk_to_numpy(g.GetCells().GetConnectivityArray()).reshape(-1, 8)
        worst = int(np.argmin(sj))
        self.assertLess(np.linalg.norm(pts[conn[worst]].mean(axis=0) - at), 1e-3)
        # --retry-below 0: only inverted hexes count as stuck, and no flat warning
        q = run(["mesh", src, "--labels", "--size", "3.5", "--retries", "1", "--retry-below", "0", "--tangled-start",
                 "--min-quality", "0", "--max-deviation", "0", "--surface-tolerance", "0", "-o", out, "--force", "-q"])
        self.assertNotIn("nearly flat", q.stderr)
        # With the relaxation (the default) the hexes the retries left flat
        # are lifted after them: the warnings describe the file written, so
        # none is left, and the file has no hex below 0.05.
        lifted = os.path.join(self.dir, "jhu_35_lifted.vtu")
        q = run(["mesh", src, "--labels", "--size", "3.5", "--retries", "1", "--tangled-start", "-o", lifted,
                 "--report", lifted + ".json", "--force"])
        with open(lifted + ".json") as f:
            rep = json.load(f)
        self.assertTrue(any(m["mean"] == "boundary_relaxation" for m in rep["quality"]["means"]), rep["quality"])
        self.assertEqual(int((vtk_sj(lifted) < 0.05).sum()), 0)
        self.assertNotIn("nearly flat", q.stderr)
        self.assertEqual([w for w in rep["warnings"] if "nearly flat" in w], [])

    def test_output_is_identical_for_one_and_two_threads(self):
        # The skull exercises every stage: untangling rounds, the release of
        # surface nodes and the mean-ratio sweeps.
        src = os.path.join(SHARED_DATA, "skull_ct.nii.gz")
        a, ra = self.mesh("skull_t1", src, "--iso", "2.9", threads=1)
        b, rb = self.mesh("skull_t2", src, "--iso", "2.9", threads=2)
        pa = ns.vtk_to_numpy(read_vtu(a).GetPoints().GetData())
        pb = ns.vtk_to_numpy(read_vtu(b).GetPoints().GetData())
        np.testing.assert_array_equal(pa, pb)
        self.assertEqual(ra["optimization"]["sweeps"], rb["optimization"]["sweeps"])

    def test_label_junctions_move_the_same_for_one_and_two_threads_and_are_reported(self):
        # The JHU labels at 3.5 mm: the slack rounds move curve and junction
        # nodes (several materials meeting in one cell) in parallel colour
        # classes; the file is the same for any thread count, and the report
        # measures the junction nodes against their surfaces and counts the
        # curve and junction nodes the relaxation took off.
        src = os.path.join(SHARED_DATA, "JHU-WhiteMatter-labels-2mm.nii.gz")
        a, ra = self.mesh("jhu_3.5mm_t1", src, "--labels", "--size", "3.5", threads=1)
        b, rb = self.mesh("jhu_3.5mm_t2", src, "--labels", "--size", "3.5", threads=2)
        with open(a, "rb") as fa, open(b, "rb") as fb:
            self.assertEqual(fa.read(), fb.read())
        f = rb["fidelity"]
        print(f"JHU 3.5 mm: {f['junction_nodes']} junction nodes, {f['junction_nodes_beyond_0_1_voxel']} beyond 0.1 voxel "
              f"of their farthest surface (mean {f['junction_distance_mean_voxels']:.3f}, max "
              f"{f['junction_distance_max_voxels']:.3f} voxel)")
        self.assertGreater(f["junction_nodes"], 50)
        # (a junction whose farthest surface is more than 3 voxels away, or
        # whose projection fails, is counted apart, as for surface nodes)
        self.assertLessEqual(f["junction_nodes_beyond_0_1_voxel"] + f["junction_nodes_not_projected"],
                             f["junction_nodes"])
        self.assertLessEqual(f["junction_distance_mean_voxels"], f["junction_distance_max_voxels"])
        relax = [m for m in rb["quality"]["means"] if m["mean"] == "boundary_relaxation"]
        self.assertEqual(len(relax), 1, rb["quality"]["means"])
        self.assertGreater(relax[0]["curve_nodes_off"], 0)
        self.assertLessEqual(relax[0]["largest_deviation_voxels"], relax[0]["max_deviation_voxels"] + 1e-6)


if __name__ == "__main__":
    unittest.main(verbosity=2)
