"""End-to-end tests of the certified minimum quality (--min-quality, --allow-below,
--max-deviation) of `mesh`, `batch` and `insert-sheet`: the exit status, what is
written, and the report's certificate, judged by VTK's vtkMeshQuality on the
written files."""
import json
import os
import sys
import unittest

sys.path.insert(0, os.path.dirname(__file__))
from common import EXIT_BELOW_QUALITY, SHARED_DATA, SOURCE, phantoms, run, workdir  # noqa: E402
from vtk_tools import vtk_sj  # noqa: E402

JHU = os.path.join(SOURCE, "samples", "JHU-WhiteMatter-labels-2mm.nii.gz")


class MinQuality(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.dir = phantoms("min_quality")
        cls.sphere = os.path.join(cls.dir, "sphere.nii.gz")

    def paths(self, name):
        return os.path.join(self.dir, name + ".vtu"), os.path.join(self.dir, name + ".json")

    def test_unreachable_target_fails_names_places_and_writes_nothing(self):
        out, report = self.paths("unreachable")
        p = run(["mesh", self.sphere, "--iso", "50", "--size", "3", "--min-quality", "0.95", "-o", out,
                 "--report", report, "-q"], check=False)
        self.assertEqual(p.returncode, EXIT_BELOW_QUALITY, p.stderr)
        self.assertIn("below the minimum quality 0.95", p.stderr)
        # each place: position, material and cause
        self.assertRegex(p.stderr, r"at \([-0-9.e]+, [-0-9.e]+, [-0-9.e]+\), material 1, scaled Jacobian [0-9.e-]+: "
                                   r"(boundary node pinned to the isosurface|feature thinner than an element|"
                                   r"label junction|interior hex)")
        self.assertFalse(os.path.exists(out))
        self.assertFalse(os.path.exists(report))
        self.assertEqual([f for f in os.listdir(self.dir) if f.startswith(".") or "unreachable" in f], [])

    def test_without_the_optimiser_the_places_say_it_did_not_run(self):
        # the nodes' classes would blame a pinned boundary node or an
        # interior hex no placement lifts, but no node was moved at all
        out, report = self.paths("not_optimised")
        p = run(["mesh", self.sphere, "--iso", "50", "--size", "3", "--min-quality", "0.95", "--no-optimize",
                 "--allow-below", "-o", out, "--report", report, "-q", "--force"], check=False)
        self.assertEqual(p.returncode, EXIT_BELOW_QUALITY, p.stderr)
        places = [line for line in p.stderr.splitlines() if line.strip().startswith("at (")]
        self.assertGreater(len(places), 0, p.stderr)
        for line in places:
            self.assertTrue(line.endswith(": not optimised (--no-optimize leaves the hexes as extracted)"), line)
        with open(report) as f:
            q = json.load(f)["quality"]
        self.assertEqual({pl["cause"] for pl in q["places"]},
                         {"not optimised (--no-optimize leaves the hexes as extracted)"})
        # with the optimiser the causes are the nodes' classes again
        p = run(["mesh", self.sphere, "--iso", "50", "--size", "3", "--min-quality", "0.95", "-o", out,
                 "--report", report, "-q", "--force"], check=False)
        self.assertEqual(p.returncode, EXIT_BELOW_QUALITY, p.stderr)
        self.assertNotIn("not optimised", p.stderr)

    def test_allow_below_writes_the_mesh_and_certifies_false(self):
        out, report = self.paths("allowed")
        p = run(["mesh", self.sphere, "--iso", "50", "--size", "3", "--min-quality", "0.95", "--allow-below",
                 "-o", out, "--report", report, "-q", "--force"], check=False)
        self.assertEqual(p.returncode, EXIT_BELOW_QUALITY, p.stderr)
        sj = vtk_sj(out)
        with open(report) as f:
            q = json.load(f)["quality"]
        self.assertIs(q["min_quality_certified"], False)
        self.assertEqual(q["target"], 0.95)
        self.assertIs(q["default_target"], False)
        self.assertAlmostEqual(q["achieved"], sj.min(), delta=1e-9)
        self.assertAlmostEqual(q["mean"], sj.mean(), delta=1e-9)
        self.assertEqual(q["hexes_below_target"], int((sj < 0.95).sum()))
        self.assertEqual(sum(q["histogram"]["counts"]), len(sj))
        self.assertEqual(len(q["places"]), min(200, q["hexes_below_target"]))
        worst = q["places"][0]
        self.assertAlmostEqual(worst["scaled_jacobian"], sj.min(), delta=1e-9)
        self.assertEqual(worst["material"], 1)
        self.assertEqual(len(worst["at"]), 3)
        # the max-min pass aimed at the target
        self.assertIn({"mean": "worst_hex_pass", "target": 0.95}, q["means"])

    def test_reachable_target_certifies_true(self):
        out, report = self.paths("reachable")
        run(["mesh", self.sphere, "--iso", "50", "--size", "3", "--min-quality", "0.4", "-o", out,
             "--report", report, "-q", "--force"])
        sj = vtk_sj(out)
        with open(report) as f:
            q = json.load(f)["quality"]
        self.assertIs(q["min_quality_certified"], True)
        self.assertEqual(q["target"], 0.4)
        self.assertGreaterEqual(sj.min(), 0.4)
        self.assertEqual(q["hexes_below_target"], 0)
        self.assertEqual(q["places"], [])

    def test_default_target_is_certified_on_a_phantom(self):
        out, report = self.paths("default")
        run(["mesh", self.sphere, "--iso", "50", "--size", "3", "-o", out, "--report", report, "-q", "--force"])
        with open(report) as f:
            q = json.load(f)["quality"]
        self.assertIs(q["default_target"], True)
        self.assertIs(q["min_quality_certified"], True)
        self.assertGreaterEqual(vtk_sj(out).min(), q["target"])
        self.assertGreater(vtk_sj(out).min(), 0)

    def test_a_surface_is_certified_at_its_default_of_0_5(self):
        src = os.path.join(SHARED_DATA, "sphere966.off")
        out, report = self.paths("surface_default")
        run(["mesh", src, "-o", out, "--report", report, "-q", "--force"])
        with open(report) as f:
            q = json.load(f)["quality"]
        self.assertEqual((q["target"], q["default_target"], q["min_quality_certified"]), (0.5, True, True))
        self.assertGreaterEqual(vtk_sj(out).min(), 0.5)

    def test_a_surface_in_metres_gets_no_warning_about_flat_hexes_it_does_not_have(self):
        # femur.off is in metres: its interior cubes' scaled Jacobian came out a
        # rounding error above 1 and was taken for a collapsed hex, so every
        # femur mesh was written with "N hex(es) stay nearly flat, lowest 0"
        src = os.path.join(SHARED_DATA, "femur.off")
        out, report = self.paths("femur_default")
        p = run(["mesh", src, "-o", out, "--report", report, "--force"])
        with open(report) as f:
            rep = json.load(f)
        sj = vtk_sj(out)
        self.assertGreaterEqual(sj.min(), 0.5)
        self.assertNotIn("nearly flat", p.stderr)
        self.assertEqual([w for w in rep["warnings"] if "flat" in w or "inverted" in w], [])
        self.assertEqual(rep["retries"]["meshed_again"], 0)

    def test_boundary_relaxation_is_bounded_and_reported(self):
        # a label atlas whose worst hexes sit at junctions: above the surface
        # tolerance the relaxation runs and reports how far nodes went
        out, report = self.paths("relaxed")
        p = run(["mesh", JHU, "--labels", "--size", "4", "--min-quality", "0.3", "--max-deviation", "0.5",
                 "--allow-below", "-o", out, "--report", report, "-q", "--force"], check=False)
        self.assertIn(p.returncode, (0, EXIT_BELOW_QUALITY), p.stderr)
        with open(report) as f:
            whole = json.load(f)
        q = whole["quality"]
        relax = [m for m in q["means"] if m["mean"] == "boundary_relaxation"]
        self.assertEqual(len(relax), 1, q["means"])
        r = relax[0]
        # it worked on the hexes around those it lifts, not on the whole mesh
        self.assertGreater(r["region_hexes"], 0)
        self.assertLess(r["region_hexes"], whole["hexes"])
        self.assertEqual(r["max_deviation_voxels"], 0.5)
        self.assertLessEqual(r["largest_deviation_voxels"], 0.5 + 1e-6)
        self.assertGreaterEqual(r["min_scaled_jacobian_after"], r["min_scaled_jacobian_before"])
        sj = vtk_sj(out)
        self.assertAlmostEqual(q["achieved"], sj.min(), delta=1e-9)
        self.assertEqual(q["min_quality_certified"], bool(sj.min() >= 0.3))
        self.assertEqual(p.returncode == 0, q["min_quality_certified"])

    def certified_jhu(self, name, size):
        """The JHU atlas meshed at `size` with default options: it must exit 0, certified, with VTK's
        smallest scaled Jacobian at least 0.3. Returns the mesh's path and the report's quality."""
        out, report = self.paths(name)
        p = run(["mesh", JHU, "--labels", "--size", size, "-o", out, "--report", report, "-q", "--force"],
                check=False)
        self.assertEqual(p.returncode, 0, p.stderr)
        with open(report) as f:
            q = json.load(f)["quality"]
        self.assertTrue(q["min_quality_certified"])
        self.assertGreaterEqual(vtk_sj(out).min(), 0.3)
        return out, q

    def test_a_label_map_is_certified_at_0_3_by_default(self):
        # Label maps promise 0.3 by default, with their interface nodes free
        # to leave the isosurface by a voxel (half a voxel for scans): at
        # 3.5 mm the JHU atlas's junctions need more than half a voxel.
        out, q = self.certified_jhu("labels_default", "3.5")
        half, half_report = self.paths("labels_half_voxel")
        self.assertEqual((q["target"], q["default_target"]), (0.3, True))
        relax = [m for m in q["means"] if m["mean"] == "boundary_relaxation"]
        self.assertEqual(len(relax), 1, q["means"])
        self.assertEqual((relax[0]["target"], relax[0]["max_deviation_voxels"]), (0.3, 1.0))
        self.assertGreater(relax[0]["largest_deviation_voxels"], 0.5)
        self.assertLessEqual(relax[0]["largest_deviation_voxels"], 1.0 + 1e-6)
        self.assertAlmostEqual(q["achieved"], vtk_sj(out).min(), delta=1e-9)
        # the same run held to half a voxel stays below 0.3, says so and what to try
        p = run(["mesh", JHU, "--labels", "--size", "3.5", "--max-deviation", "0.5", "-o", half, "--report",
                 half_report, "-q", "--force"], check=False)
        self.assertEqual(p.returncode, EXIT_BELOW_QUALITY, p.stderr)
        self.assertIn("below the minimum quality 0.3", p.stderr)
        self.assertIn("a finer --size or a larger --max-deviation may reach it", p.stderr)
        self.assertFalse(os.path.exists(half))

    def test_a_label_map_relaxes_again_from_other_steps_at_junctions(self):
        # At 4 mm the JHU atlas's last hexes below 0.3 sit where labels meet,
        # and one relaxation from the max-min pass's own first step leaves
        # them at 0.296: the relaxation starts again from the same nodes with
        # finer and coarser steps and keeps the best, which reaches 0.3.
        self.certified_jhu("labels_4mm", "4")

    def test_a_label_map_left_below_at_a_junction_ran_every_relaxation_pass(self):
        # At 6 mm four JHU labels meet at nodes of 15 hexes and no relaxation
        # pass lifts them to 0.3. With the labels kept as they are
        # (--keep-features), the relaxation ran from each of its three first
        # steps, the report says so and which pass it kept, and the error names
        # the junctions and what to try.
        out, report = self.paths("labels_6mm_kept")
        p = run(["mesh", JHU, "--labels", "--size", "6", "--keep-features", "--allow-below", "-o", out, "--report",
                 report, "-q", "--force"], check=False)
        self.assertEqual(p.returncode, EXIT_BELOW_QUALITY, p.stderr)
        with open(report) as f:
            q = json.load(f)["quality"]
        self.assertFalse(q["min_quality_certified"])
        self.assertLess(vtk_sj(out).min(), 0.3)
        self.assertIn("label junction", [pl["cause"] for pl in q["places"]])
        relax = [m for m in q["means"] if m["mean"] == "boundary_relaxation"]
        self.assertEqual(relax[-1]["passes"], 3)
        self.assertIn(relax[-1]["first_step"], (0.25, 0.125, 0.5))
        self.assertEqual([m for m in q["means"] if m["mean"] == "feature_removal"], [])
        self.assertIn("a finer --size or a larger --max-deviation may reach it", p.stderr)

    def test_a_label_map_gives_a_junction_point_another_label_where_nothing_else_lifts_it(self):
        # The same run by default: after the relaxation and the fine features,
        # the grid points at the junction that no placement lifts take the
        # label of most of their face neighbours (each listed with its
        # position and volume), the labels are meshed again around them, and
        # the mesh reaches 0.3.
        out, q = self.certified_jhu("labels_6mm", "6")
        (removal,) = [m for m in q["means"] if m["mean"] == "feature_removal"]
        self.assertIs(removal["kept"], True)
        junction = [f for f in removal["features"] if f["shape"] == "label triple line"]
        self.assertGreater(len(junction), 0, removal["features"])
        for f in junction:
            self.assertEqual(f["grid_points"], 1)
            self.assertAlmostEqual(f["volume"], 6.0 ** 3)  # one 6 mm cell
            self.assertNotEqual(f["material"], f["replaced_by"])
        self.assertGreaterEqual(removal["min_scaled_jacobian_after"], 0.3)
        self.assertLess(removal["min_scaled_jacobian_before"], 0.3)
        self.assertIn("region", removal)  # meshed again around the edits, not the whole volume

    def test_a_label_map_without_the_optimiser_is_certified_at_0(self):
        # --no-optimize gives up the means that reach 0.3: Q is 0 (no
        # inverted or degenerate hex), as for scans, and a mesh below even
        # that does not advise --max-deviation, which the run refuses.
        out, report = self.paths("labels_no_optimize")
        p = run(["mesh", JHU, "--labels", "--size", "4", "--no-optimize", "--allow-below", "-o", out, "--report",
                 report, "-q", "--force"], check=False)
        self.assertEqual(p.returncode, EXIT_BELOW_QUALITY, p.stderr)  # hexes left inverted as extracted
        with open(report) as f:
            q = json.load(f)["quality"]
        self.assertEqual((q["target"], q["default_target"], q["min_quality_certified"]), (0.0, True, False))
        self.assertLessEqual(vtk_sj(out).min(), 0)
        self.assertIn("a finer --size may reach it", p.stderr)
        self.assertNotIn("--max-deviation", p.stderr)

    def test_max_deviation_needs_moving_surface_nodes(self):
        p = run(["mesh", self.sphere, "--iso", "50", "--max-deviation", "0.5", "--fix-boundary", "-o",
                 os.path.join(self.dir, "x.vtu")], check=False)
        self.assertEqual(p.returncode, 2)
        self.assertFalse(os.path.exists(os.path.join(self.dir, "x.vtu")))

    def test_batch_row_below_fails_with_its_cause(self):
        d = workdir("min_quality_batch")
        manifest = os.path.join(d, "jobs.csv")
        with open(manifest, "w") as f:
            f.write("input,output,min_quality\n")
            f.write(f"{self.sphere},ok.vtu,\n")
            f.write(f"{self.sphere},below.vtu,0.95\n")
        p = run(["batch", manifest, "--iso", "50", "--size", "3", "-q"], check=False)
        self.assertEqual(p.returncode, EXIT_BELOW_QUALITY, p.stdout + p.stderr)
        rows = [line for line in p.stdout.splitlines() if line.startswith(self.sphere[-30:]) or "sphere" in line]
        self.assertTrue(any(" ok " in r for r in rows), p.stdout)
        self.assertTrue(any(" below " in r and "below the minimum quality 0.95" in r for r in rows), p.stdout)
        self.assertIn("1 below the minimum quality", p.stdout)
        self.assertIn("scaled Jacobian", p.stderr)  # the places, on stderr
        self.assertTrue(os.path.exists(os.path.join(d, "ok.vtu")))
        self.assertFalse(os.path.exists(os.path.join(d, "below.vtu")))

    def test_default_stretch_lifts_the_torus_to_half_and_keeps_the_mean(self):
        # Default options: the max-min pass reaches 0.3 everywhere, so a second
        # pass aims at 0.5; with --worst-hex-target 0.3 set there is none.
        torus = os.path.join(self.dir, "torus.nii.gz")
        out, report = self.paths("torus_default")
        run(["mesh", torus, "-o", out, "--report", report, "-q", "--force"])
        fixed, fixed_report = self.paths("torus_target_0.3")
        run(["mesh", torus, "-o", fixed, "--report", fixed_report, "--worst-hex-target", "0.3", "-q", "--force"])
        sj, sj_fixed = vtk_sj(out), vtk_sj(fixed)
        self.assertEqual(len(sj), len(sj_fixed))
        self.assertLess(sj_fixed.min(), 0.5)
        self.assertGreaterEqual(sj.min(), 0.5)
        self.assertGreaterEqual(sj.mean(), sj_fixed.mean() - 0.005)
        with open(report) as f:
            stretch = json.load(f)["optimization"]["stretch"]
        self.assertEqual(stretch["target"], 0.5)
        self.assertIs(stretch["kept"], True)
        self.assertAlmostEqual(stretch["min_scaled_jacobian_after"], sj.min(), delta=1e-9)
        self.assertAlmostEqual(stretch["min_scaled_jacobian_before"], sj_fixed.min(), delta=1e-9)
        with open(fixed_report) as f:
            self.assertNotIn("stretch", json.load(f)["optimization"])

    def test_insert_sheet_below_writes_nothing(self):
        block = os.path.join(SOURCE, "samples", "spherical_cuts_block.vtu")
        cut = os.path.join(SOURCE, "samples", "spherical_cut_1.off")
        out = os.path.join(self.dir, "cut.vtu")
        p = run(["insert-sheet", "--mesh", block, "--surface", cut, "-o", out, "--min-quality", "0.95", "-q"],
                check=False)
        self.assertEqual(p.returncode, EXIT_BELOW_QUALITY, p.stderr)
        self.assertIn("below the minimum quality 0.95", p.stderr)
        self.assertFalse(os.path.exists(out))
        p = run(["insert-sheet", "--mesh", block, "--surface", cut, "-o", out, "--min-quality", "0.95",
                 "--allow-below", "-q"], check=False)
        self.assertEqual(p.returncode, EXIT_BELOW_QUALITY, p.stderr)
        self.assertTrue(os.path.exists(out))
        run(["insert-sheet", "--mesh", block, "--surface", cut, "-o", out, "--min-quality", "0.2", "-q", "--force"])
        self.assertGreaterEqual(vtk_sj(out).min(), 0.2)


if __name__ == "__main__":
    unittest.main()
