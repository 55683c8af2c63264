"""End-to-end tests of `isohex mesh`, `compare` and `quality` run as a user would,
with the results judged by VTK (vtkMeshQuality, vtkCellSizeFilter) rather than by
isohex's own numbers."""
import json
import os
import shutil
import subprocess
import sys
import unittest

import numpy as np
from vtk.util import numpy_support as ns

sys.path.insert(0, os.path.dirname(__file__))
from common import ISOHEX, SHARED_DATA, SOURCE, polygon_topology, run, run_below_allowed, workdir, EXIT_BELOW_QUALITY  # noqa: E402
from vtk_tools import read_vtu as read, vtk_sj, vtk_volumes  # noqa: E402


def vtk_volume(grid):
    return float(vtk_volumes(grid).sum())




class Phantoms(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.dir = workdir("cli_mesh")
        subprocess.run(["/usr/bin/python3", os.path.join(SOURCE, "samples", "make_phantoms.py"), cls.dir],
                       check=True, capture_output=True)

    def mesh(self, name, *extra, out=None, allow_below=False):
        out = out or os.path.join(self.dir, f"{name}{abs(hash(extra))}.vtu")
        report = out.replace(".vtu", ".json")
        args = ["mesh", os.path.join(self.dir, f"{name}.nii.gz"), "-o", out, "--report", report, "--force", "-q",
                *extra]
        if allow_below:  # a case meant to leave poor hexes: written, exit status 4 exactly when VTK finds them
            run_below_allowed(args, out)
        else:
            run(args)
        with open(report) as f:
            return read(out), json.load(f)

    def test_sphere_is_valid_convex_and_close_to_the_ball(self):
        grid, rep = self.mesh("sphere", "--iso", "50", "--size", "3")
        sj = vtk_sj(grid)
        print(f"sphere: {len(sj)} hexes, VTK scaled Jacobian min {sj.min():.3f} mean {sj.mean():.3f}")
        self.assertEqual((sj < 0).sum(), 0)
        self.assertGreaterEqual(sj.min(), 0.3)
        self.assertGreaterEqual(sj.mean(), 0.85)
        self.assertTrue(rep["validity"]["ok"], rep["validity"])
        # volume: VTK's own cell volumes against the isosurface volume of the report and the exact ball
        vol = vtk_volume(grid)
        self.assertAlmostEqual(vol / rep["fidelity"]["volume_mesh"], 1.0, delta=1e-3)
        self.assertAlmostEqual(vol / (4 / 3 * np.pi * 20 ** 3), 1.0, delta=0.03)
        self.assertLess(rep["fidelity"]["boundary_distance_max_voxels"], 0.1)
        # the report's figures are VTK's
        self.assertEqual(rep["hexes"], grid.GetNumberOfCells())
        self.assertAlmostEqual(rep["scaled_jacobian"]["min"], sj.min(), delta=1e-9)

    def test_pillowing_beats_no_pillowing_with_the_same_optimiser(self):
        # --retries 0: the comparison is the sheet's, with one grid for both
        g1, r1 = self.mesh("torus", "--iso", "50", "--size", "2.5", "--fix-boundary", "--retries", "0",
                           allow_below=True)
        g0, r0 = self.mesh("torus", "--iso", "50", "--size", "2.5", "--fix-boundary", "--no-pillow", "--retries", "0",
                           allow_below=True)
        s1, s0 = vtk_sj(g1), vtk_sj(g0)
        print(f"torus without sheet: min {s0.min():.3f}, <0.2: {(s0 < 0.2).sum()}, inverted {(s0 < 0).sum()}; "
              f"with sheet: min {s1.min():.3f}, <0.2: {(s1 < 0.2).sum()}, inverted {(s1 < 0).sum()}")
        self.assertGreater(s1.min(), s0.min())
        self.assertLessEqual((s1 < 0.2).sum(), (s0 < 0.2).sum())
        self.assertEqual(r1["pillow"]["hexes_added"], len(s1) - len(s0))  # one sheet hex per boundary quad

    def test_labels_give_one_material_per_label_with_interfaces(self):
        grid, rep = self.mesh("two_materials", "--labels", "--size", "3")
        mats = ns.vtk_to_numpy(grid.GetCellData().GetArray("material"))
        self.assertEqual(sorted(set(mats.tolist())), [1, 2, 3])
        sj = vtk_sj(grid)
        self.assertEqual((sj < 0).sum(), 0)
        self.assertTrue(rep["validity"]["ok"], rep["validity"])

    def test_output_is_identical_for_one_and_two_threads(self):
        a = os.path.join(self.dir, "t1.vtu")
        b = os.path.join(self.dir, "t2.vtu")
        for path, n in ((a, "1"), (b, "2")):
            run(["mesh", os.path.join(self.dir, "torus.nii.gz"), "--iso", "50", "--size", "3", "-o", path,
                 "--threads", n, "--force", "-q"])
        ga, gb = read(a), read(b)
        pa = ns.vtk_to_numpy(ga.GetPoints().GetData())
        pb = ns.vtk_to_numpy(gb.GetPoints().GetData())
        np.testing.assert_array_equal(pa, pb)
        np.testing.assert_array_equal(ns.vtk_to_numpy(ga.GetCells().GetConnectivityArray()),
                                      ns.vtk_to_numpy(gb.GetCells().GetConnectivityArray()))

    def test_huge_pages_are_requested_and_change_nothing_in_the_output(self):
        with open("/sys/kernel/mm/transparent_hugepage/enabled") as f:
            thp = "[never]" not in f.read()
        out = {}
        for label, env in (("on", {}), ("off", {"ISOHEX_HUGEPAGES": "0"})):
            path = os.path.join(self.dir, f"hp_{label}.vtu")
            run(["mesh", os.path.join(self.dir, "torus.nii.gz"), "--iso", "50", "--size", "3", "-o", path,
                 "--report", path.replace(".vtu", ".json"), "--force", "-q"],
                env={k: v for k, v in os.environ.items() if k != "GLIBC_TUNABLES"} | env)
            with open(path.replace(".vtu", ".json")) as f:
                out[label] = (read(path), json.load(f))
        self.assertEqual(out["on"][1]["huge_pages"], thp)
        self.assertFalse(out["off"][1]["huge_pages"])
        ga, gb = out["on"][0], out["off"][0]
        np.testing.assert_array_equal(ns.vtk_to_numpy(ga.GetPoints().GetData()),
                                      ns.vtk_to_numpy(gb.GetPoints().GetData()))
        np.testing.assert_array_equal(ns.vtk_to_numpy(ga.GetCells().GetConnectivityArray()),
                                      ns.vtk_to_numpy(gb.GetCells().GetConnectivityArray()))

    def test_compare_writes_four_variants_with_matching_counts(self):
        js = os.path.join(self.dir, "cmp.json")
        svg = os.path.join(self.dir, "cmp.svg")
        p = run(["compare", os.path.join(self.dir, "torus.nii.gz"), "--iso", "50", "--size", "3", "--json", js,
                 "--plot", svg, "--force", "--log-json"])
        with open(js) as f:
            c = json.load(f)
        # each variant's optimisation is labelled with it (so are its warnings)
        events = [json.loads(line) for line in p.stderr.splitlines() if line.startswith("{")]
        optimised = [e.get("job") for e in events if e.get("stage") == "optimize" and e.get("event") == "stage_end"]
        self.assertEqual(optimised, ["variant a", "variant b", "variant c", "variant d"], events[-5:])
        v = {x["variant"]: x for x in c["variants"]}
        self.assertEqual(sorted(v), ["a", "b", "c", "d"])
        self.assertGreaterEqual(v["c"]["hexes"], v["b"]["hexes"])          # diced up to b's count
        self.assertLessEqual(v["d"]["hexes"], v["a"]["hexes"] * 1.0 + 1e-9)  # extracted down to a's count
        for key in "abcd":
            self.assertEqual(sum(v[key]["scaled_jacobian"]["histogram"]["counts"]) + v[key]["scaled_jacobian"]["degenerate"],
                             v[key]["hexes"])
        with open(svg) as f:
            text = f.read()
        self.assertIn("<svg", text)
        for key in "abcd":
            self.assertIn(f"{key}: ", text)

    def test_compare_variants_a_and_b_are_those_of_the_full_comparison(self):
        # --variants b,a makes only those (in the order a, b), and they are
        # the full comparison's: c and d are made after them and from b.
        torus = os.path.join(self.dir, "torus.nii.gz")
        full, part = os.path.join(self.dir, "cmp_full"), os.path.join(self.dir, "cmp_ab")
        run(["compare", torus, "--iso", "50", "--size", "3", "--mesh-dir", full, "--force", "-q"])
        js = os.path.join(self.dir, "cmp_ab.json")
        run(["compare", torus, "--iso", "50", "--size", "3", "--variants", "b,a", "--mesh-dir", part, "--json", js,
             "--force", "-q"])
        self.assertEqual(sorted(os.listdir(part)), ["variant_a.vtu", "variant_b.vtu"])
        with open(js) as f:
            self.assertEqual([v["variant"] for v in json.load(f)["variants"]], ["a", "b"])
        for key in "ab":
            with open(os.path.join(full, f"variant_{key}.vtu"), "rb") as f, \
                    open(os.path.join(part, f"variant_{key}.vtu"), "rb") as g:
                self.assertEqual(f.read(), g.read(), key)

    def test_compare_refuses_a_variant_list_it_cannot_make(self):
        torus = os.path.join(self.dir, "torus.nii.gz")
        for given, why in (("a,e", "'e', which is not a, b, c or d"), ("b,b", "names b twice"), ("", "''")):
            p = run(["compare", torus, "--variants", given, "--json", os.path.join(self.dir, "never.json")],
                    check=False)
            self.assertNotEqual(p.returncode, 0)
            self.assertIn("--variants takes some of a, b, c, d", p.stderr)
            self.assertIn(why, p.stderr)
            self.assertFalse(os.path.exists(os.path.join(self.dir, "never.json")))

    def test_compare_warnings_name_its_own_option(self):
        # compare fixes the boundary unless --move-boundary; its warnings told
        # the user to drop --fix-boundary, an option they never passed.
        p = run(["compare", os.path.join(SHARED_DATA, "skull_ct.nii.gz"), "--iso", "2.9", "--size", "6", "--json",
                 os.path.join(self.dir, "skull_cmp.json"), "--force"])
        left = [line for line in p.stderr.splitlines() if "stay inverted" in line]
        self.assertGreater(len(left), 0)  # the case this test is about
        for line in left:
            self.assertIn("--move-boundary lets them move", line)
            self.assertNotIn("--fix-boundary", line)


def off_topology(path):
    """Components and Euler characteristic V - E + F of an .off surface, counted
    here from the file (vertices welded at identical positions)."""
    with open(path) as f:
        words = [w for line in f for w in line.split("#")[0].split()]
    assert words[0] == "OFF"
    nv, nf = int(words[1]), int(words[2])
    pts = np.array(words[4:4 + 3 * nv], dtype=float).reshape(nv, 3)
    _, weld = np.unique(pts, axis=0, return_inverse=True)
    weld = weld.ravel()
    tris, i = [], 4 + 3 * nv
    for _ in range(nf):
        n = int(words[i])
        tris.append([weld[int(w)] for w in words[i + 1:i + 1 + n]])
        i += 1 + n
    return polygon_topology(np.array(tris))


class SurfaceTopology(unittest.TestCase):
    """A triangle surface's own topology is what its mesh is held to: a --size
    too coarse for the knot's tube must say so, whatever the level set's voxels."""

    def test_a_size_too_coarse_for_the_knot_warns_and_the_default_does_not(self):
        d = workdir("cli_surface_topology")
        src = os.path.join(SHARED_DATA, "knot1.off")
        comps, euler = off_topology(src)
        self.assertEqual((comps, euler), (1, 0))  # a knotted tube: one torus
        for name, extra, warns in [("default", [], False), ("coarse", ["--size", "0.3"], True)]:
            out = os.path.join(d, f"knot_{name}.vtu")
            # (a surface's default minimum quality is 0.5; without the optimiser it is not met)
            p = run_below_allowed(["mesh", src, *extra, "--no-optimize", "-o", out, "--report", out + ".json",
                                   "--force", "-q"], out, 0.5)
            with open(out + ".json") as f:
                rep = json.load(f)
            self.assertEqual(rep["input"]["surface"]["components"], comps)
            self.assertEqual(rep["input"]["surface"]["euler_characteristic"], euler)
            topo = rep["grid"]["topology"][0]
            changed = (topo["components"], topo["euler"]) != (comps, euler)
            self.assertEqual(changed, warns, f"{name}: mesh {topo}")
            named = [w for w in rep["warnings"] if "changes the topology" in w]
            self.assertEqual(len(named), 1 if warns else 0, rep["warnings"])
            if warns:
                self.assertIn("input surface: 1 component(s), Euler characteristic 0", named[0])
                self.assertIn("changes the topology", p.stderr)


class FailurePaths(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.dir = workdir("cli_fail")
        subprocess.run(["/usr/bin/python3", os.path.join(SOURCE, "samples", "make_phantoms.py"), cls.dir],
                       check=True, capture_output=True)

    def test_missing_input_is_one_clear_line(self):
        p = run(["mesh", os.path.join(self.dir, "nope.nii.gz"), "-o", os.path.join(self.dir, "x.vtu")], check=False)
        self.assertNotEqual(p.returncode, 0)
        self.assertIn("nope.nii.gz", p.stderr)
        self.assertEqual(len(p.stderr.strip().splitlines()), 1, p.stderr)
        self.assertFalse(os.path.exists(os.path.join(self.dir, "x.vtu")))

    def test_existing_output_is_not_clobbered(self):
        out = os.path.join(self.dir, "keep.vtu")
        with open(out, "w") as f:
            f.write("precious")
        p = run(["mesh", os.path.join(self.dir, "sphere.nii.gz"), "--iso", "50", "-o", out, "-q"], check=False)
        self.assertNotEqual(p.returncode, 0)
        self.assertIn("--force", p.stderr)
        with open(out) as f:
            self.assertEqual(f.read(), "precious")

    def test_iso_outside_the_data_states_the_range(self):
        p = run(["mesh", os.path.join(self.dir, "sphere.nii.gz"), "--iso", "500", "-o",
                 os.path.join(self.dir, "y.vtu"), "-q"], check=False)
        self.assertNotEqual(p.returncode, 0)
        self.assertIn("range", p.stderr)
        self.assertFalse(os.path.exists(os.path.join(self.dir, "y.vtu")))

    def test_every_output_path_is_checked_before_meshing_and_a_failed_job_leaves_none(self):
        src = os.path.join(self.dir, "sphere.nii.gz")
        d = os.path.join(self.dir, "outs")
        os.makedirs(os.path.join(d, "afolder"), exist_ok=True)
        mesh = os.path.join(d, "m.vtu")
        existing = os.path.join(d, "old.json")
        with open(existing, "w") as f:
            f.write("keep")
        cases = [
            (["--report", os.path.join(d, "nope", "r.json")], "does not exist"),
            (["--plot", os.path.join(d, "nope", "p.svg")], "does not exist"),
            (["--report", existing], "--force"),
            (["--report", os.path.join(d, "afolder")], "is a folder"),
            ([os.path.join(d, "m.vtu")], "named twice"),
        ]
        for extra, message in cases:
            opts = extra if extra[0].startswith("--") else []
            more = [] if opts else extra
            p = run(["mesh", src, "--size", "3", "-o", mesh, *more, *opts, "-q"], check=False)
            self.assertEqual(p.returncode, 1, extra)
            self.assertIn(message, p.stderr, extra)
            self.assertEqual(len(p.stderr.strip().splitlines()), 1, p.stderr)  # refused before meshing
            self.assertFalse(os.path.exists(mesh), extra)
        with open(existing) as f:
            self.assertEqual(f.read(), "keep")
        # A later output that cannot be written (procfs takes no new files):
        # the mesh written before it is removed again.
        p = run(["mesh", src, "--size", "3", "-o", mesh, "/proc/isohex_test.msh", "-q"], check=False)
        self.assertEqual(p.returncode, 1, p.stderr)
        self.assertIn("isohex_test", p.stderr)
        self.assertFalse(os.path.exists(mesh))
        # and with the paths in order, the same job succeeds
        p = run(["mesh", src, "--size", "3", "-o", mesh, "--report", os.path.join(d, "r.json"), "--plot",
                 os.path.join(d, "p.svg"), "-q"])
        for f in (mesh, os.path.join(d, "r.json"), os.path.join(d, "p.svg")):
            self.assertTrue(os.path.exists(f), f)

    def test_an_element_larger_than_the_object_is_a_clear_error(self):
        # Nothing of the sphere is left on a 100 mm grid (or at level 6): this
        # crashed in the worst-hex pass on the empty mesh (exit 139), with and
        # without the sheet; --mesh-exterior would have meshed only the box.
        for extra in (["--size", "100"], ["--level", "6"], ["--size", "100", "--no-pillow"],
                      ["--size", "100", "--mesh-exterior"]):
            out = os.path.join(self.dir, "empty.vtu")
            p = run(["mesh", os.path.join(self.dir, "sphere.nii.gz"), *extra, "-o", out, "-q"], check=False)
            self.assertEqual(p.returncode, 1, (extra, p.stderr))
            self.assertIn("sphere.nii.gz", p.stderr)
            self.assertIn("nothing to mesh", p.stderr)
            self.assertIn("smaller --size", p.stderr)
            self.assertFalse(os.path.exists(out), extra)

    def test_a_gzip_file_without_gz_and_an_iso_off_a_surface_are_explained(self):
        src = os.path.join(self.dir, "zipped.nii")
        shutil.copyfile(os.path.join(self.dir, "sphere.nii.gz"), src)
        p = run(["mesh", src, "-o", os.path.join(self.dir, "g.vtu"), "-q"], check=False)
        self.assertEqual(p.returncode, 1)
        self.assertIn("zipped.nii: the file is gzip-compressed", p.stderr)
        self.assertIn("zipped.nii.gz", p.stderr)
        # --iso on a triangle surface offsets its signed distance; Otsu has nothing to do with it
        p = run(["mesh", os.path.join(SHARED_DATA, "femur.off"), "--iso", "100", "-o", os.path.join(self.dir, "g.vtu"),
                 "-q"], check=False)
        self.assertEqual(p.returncode, 1)
        self.assertIn("signed distance", p.stderr)
        self.assertNotIn("Otsu", p.stderr)
        self.assertFalse(os.path.exists(os.path.join(self.dir, "g.vtu")))

    def test_an_intensity_scan_read_as_labels_is_refused_up_front(self):
        # ch2bet stores its intensities as uint8. Read as a label map, every
        # grey value was a material of scattered voxels: --labels ran the
        # repair for four minutes and then failed, --label 100 wrote a mesh of
        # specks with 1010 inverted hexes. Both are refused at selection now.
        out = os.path.join(self.dir, "lab.vtu")
        for extra in (["--labels"], ["--label", "100"]):
            p = run(["mesh", os.path.join(SHARED_DATA, "ch2bet.nii.gz"), *extra, "-o", out, "-q"], check=False)
            self.assertEqual(p.returncode, 1, (extra, p.stderr))
            self.assertIn("ch2bet.nii.gz: this does not look like a label map", p.stderr)
            self.assertIn("without --labels or --label; choose the surface with --iso", p.stderr)
            self.assertEqual(len(p.stderr.strip().splitlines()), 1, p.stderr)
            self.assertFalse(os.path.exists(out), extra)
        # a real segmentation passes the same check
        p = run_below_allowed(["mesh", os.path.join(SHARED_DATA, "JHU-WhiteMatter-labels-2mm.nii.gz"), "--label",
                               "5", "--no-optimize", "-o", out, "-q"], out)
        self.assertTrue(os.path.exists(out))

    def test_an_element_size_whose_mesh_cannot_fit_in_memory_is_refused_before_meshing(self):
        # --size 0.05 on the 1 mm sphere is about 300 M hexes: refused at once
        # (it used to run until memory ran out), with a size that would fit.
        src = os.path.join(self.dir, "sphere.nii.gz")
        out = os.path.join(self.dir, "fine.vtu")
        p = run(["mesh", src, "--size", "0.05", "-o", out, "-q"], check=False)
        self.assertEqual(p.returncode, 1, p.stderr)
        self.assertIn("sphere.nii.gz: at this element size", p.stderr)
        self.assertIn("--size of at least", p.stderr)
        self.assertFalse(os.path.exists(out))
        # --max-memory is the budget; the estimated hex count is the real one's
        # (the job's process needs about 180 MB at this size; 170 MB measured)
        p = run(["mesh", src, "--size", "0.5", "--max-memory", "120", "-o", out, "-q"], check=False)
        self.assertEqual(p.returncode, 1, p.stderr)
        self.assertIn("--max-memory budget", p.stderr)
        self.assertFalse(os.path.exists(out))
        estimate = float(p.stderr.split("about ")[1].split(" million")[0]) * 1e6
        rep = os.path.join(self.dir, "fine.json")
        run(["mesh", src, "--size", "0.5", "--max-memory", "400", "-o", out, "--report", rep, "--force", "-q"])
        with open(rep) as f:
            r = json.load(f)
        self.assertLess(abs(estimate - r["hexes"]) / r["hexes"], 0.15, (estimate, r["hexes"]))
        self.assertLess(r["peak_memory_mb"], 400)

    def test_an_off_file_that_breaks_its_header_is_a_clear_error_not_an_abort(self):
        # Assimp aborted the process (exit 134, taking a whole batch with it)
        # on an OFF file with fewer face lines than its header says, and read
        # a face index past the vertices as something else.
        tet = "0 0 0\n1 0 0\n0 1 0\n0 0 1\n"
        cases = {
            "short.off": ("OFF\n4 4 0\n" + tet + "3 0 2 1\n", "the header promises 4 vertices and 4 faces"),
            "index.off": ("OFF\n4 4 0\n" + tet + "3 0 2 1\n3 0 1 3\n3 0 3 9\n3 1 2 3\n", "face 2 uses vertex 9"),
        }
        good = os.path.join(self.dir, "tet.off")
        with open(good, "w") as f:
            f.write("OFF\n4 4 0\n" + tet + "3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n")
        outdir = os.path.join(self.dir, "off_out")
        for name, (text, message) in cases.items():
            src = os.path.join(self.dir, name)
            with open(src, "w") as f:
                f.write(text)
            for method in ("dual", "sheets"):
                out = os.path.join(self.dir, "off.vtu")
                p = run(["mesh", src, "--method", method, "-o", out, "-q"], check=False)
                self.assertEqual(p.returncode, 1, (name, method, p.stderr))
                self.assertIn(f"{name}: {message}", p.stderr)
                self.assertEqual(len(p.stderr.strip().splitlines()), 1, p.stderr)
                self.assertFalse(os.path.exists(out))
        # several inputs: the bad one fails, the good one is meshed, exit 1
        p = run(["mesh", os.path.join(self.dir, "short.off"), good, "--out-dir", outdir, "--force"], check=False)
        self.assertEqual(p.returncode, 1, p.stderr)
        self.assertTrue(os.path.exists(os.path.join(outdir, "tet.vtu")))
        self.assertFalse(os.path.exists(os.path.join(outdir, "short.vtu")))

    def test_a_ply_file_cut_short_or_with_a_bad_index_is_a_clear_error_not_a_crash(self):
        # Assimp crashed (segmentation fault) on a binary PLY cut short, and
        # read an ASCII one cut short, or with an index past the vertices, as
        # an open surface: the error blamed holes in the surface.
        import struct
        verts = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)]
        faces = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]

        def ply(fmt, faces):
            head = ("ply\nformat %s 1.0\ncomment a tetrahedron\nelement vertex 4\nproperty float x\n"
                    "property float y\nproperty float z\nelement face %d\n"
                    "property list uchar int vertex_indices\nend_header\n" % (fmt, len(faces))).encode()
            if fmt == "ascii":
                body = "".join("%g %g %g\n" % v for v in verts) + "".join("3 %d %d %d\n" % f for f in faces)
                return head + body.encode()
            e = "<" if fmt == "binary_little_endian" else ">"
            body = b"".join(struct.pack(e + "3f", *v) for v in verts)
            body += b"".join(struct.pack(e + "B3i", 3, *f) for f in faces)
            return head + body

        bad_index = faces[:2] + [(0, 3, 9)] + faces[3:]
        cases = {
            "cut_le.ply": (ply("binary_little_endian", faces)[:-7], "promises 4 face item(s) but the data ends at face 3"),
            "cut_ascii.ply": (ply("ascii", faces)[:-8], "promises 4 face item(s) but the data ends at face 3"),
            "index_be.ply": (ply("binary_big_endian", bad_index), "face 2 uses vertex 9"),
            "index_ascii.ply": (ply("ascii", bad_index), "face 2 uses vertex 9"),
        }
        for name, (data, message) in cases.items():
            src = os.path.join(self.dir, name)
            with open(src, "wb") as f:
                f.write(data)
            out = os.path.join(self.dir, "ply.vtu")
            p = run(["mesh", src, "-o", out, "-q"], check=False)
            self.assertEqual(p.returncode, 1, (name, p.stderr))
            self.assertIn(f"{name}: the header {message}" if "promises" in message else f"{name}: {message}", p.stderr)
            self.assertEqual(len(p.stderr.strip().splitlines()), 1, p.stderr)
            self.assertFalse(os.path.exists(out))
        # a binary header cut right after end_header, before its newline: read past the buffer
        cut = os.path.join(self.dir, "cut_header.ply")
        whole = ply("binary_little_endian", faces)
        with open(cut, "wb") as f:
            f.write(whole[:whole.index(b"end_header") + len(b"end_header")])
        p = run(["mesh", cut, "-o", os.path.join(self.dir, "ply.vtu"), "-q"], check=False)
        self.assertEqual(p.returncode, 1, p.stderr)
        self.assertIn("cut_header.ply: the header promises 4 vertex item(s) but the data ends at vertex 0", p.stderr)
        # valid files the walk must not refuse: nan in a normal, and a face list that is not vertex indices
        odd = os.path.join(self.dir, "odd.ply")
        with open(odd, "w") as f:
            f.write("ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
                    "property float nx\nelement face 4\nproperty list uchar int vertex_indices\n"
                    "property list uchar int texcoord_indices\nelement nothing 1000000000000\nend_header\n")
            for i, v in enumerate(verts):
                f.write("%g %g %g %s\n" % (*v, "nan" if i == 1 else "0"))
            for fc in faces:
                f.write("3 %d %d %d 3 100 200 300\n" % fc)
        self.assertEqual(run(["mesh", odd, "-o", os.path.join(self.dir, "odd.vtu"), "-q", "--force"]).returncode, 0)
        # the same layouts whole are read and meshed, both byte orders
        for fmt in ("ascii", "binary_little_endian", "binary_big_endian"):
            src = os.path.join(self.dir, "tet_%s.ply" % fmt)
            with open(src, "wb") as f:
                f.write(ply(fmt, faces))
            out = os.path.join(self.dir, "tet_%s.vtu" % fmt)
            p = run(["mesh", src, "-o", out, "-q", "--force"], check=False)
            self.assertEqual(p.returncode, 0, (fmt, p.stderr))
            self.assertTrue(os.path.exists(out))

    def test_surface_coordinates_that_are_not_finite_are_refused(self):
        # Assimp reads "nan" in an OBJ as a coordinate; the mesh came out of it
        src = os.path.join(self.dir, "nan.obj")
        with open(src, "w") as f:
            f.write("v nan 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n")
        out = os.path.join(self.dir, "nan.vtu")
        p = run(["mesh", src, "-o", out, "-q"], check=False)
        self.assertEqual(p.returncode, 1, p.stderr)
        self.assertIn("nan.obj: vertex 0 has coordinate nan", p.stderr)
        self.assertFalse(os.path.exists(out))
        good = os.path.join(self.dir, "tet.obj")
        with open(good, "w") as f:
            f.write("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n")
        self.assertEqual(run(["mesh", good, "-o", out, "-q", "--force"]).returncode, 0)

    def test_a_library_message_quoting_the_whole_input_is_cut_to_a_readable_length(self):
        # Assimp quotes the rest of an ASCII STL after a bad number (262 kB of
        # stderr for a 2,000-triangle file); OpenVDB quoted gigabytes of a
        # damaged .vdb.
        tri = "facet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\n"
        src = os.path.join(self.dir, "badnumber.stl")
        with open(src, "w") as f:
            f.write("solid s\n" + tri.replace("vertex 0 0 0", "vertex abc 0 0", 1) + tri * 5000 + "endsolid s\n")
        out = os.path.join(self.dir, "badnumber.vtu")
        p = run(["mesh", src, "-o", out, "-q"], check=False)
        self.assertEqual(p.returncode, 1, p.stderr[:500])
        self.assertTrue(p.stderr.startswith("isohex: error: " + src), p.stderr[:300])
        self.assertLess(len(p.stderr), 2500)
        self.assertIn("characters left out", p.stderr)
        self.assertFalse(os.path.exists(out))

    def test_every_command_checks_its_outputs_before_working_and_never_writes_over_an_input(self):
        # compare wrote two variant meshes and then stopped on an existing
        # third; quality wrote its report and then refused the mesh; --report
        # could name the input (replaced by JSON); two inputs of one name
        # under --out-dir wrote one file, the second run's.
        d = os.path.join(self.dir, "outs_all")
        os.makedirs(d, exist_ok=True)
        src = os.path.join(self.dir, "sphere.nii.gz")
        mesh = os.path.join(d, "m.vtu")
        run(["mesh", src, "--size", "4", "-o", mesh, "-q", "--force"])
        with open(mesh, "rb") as f:
            original = f.read()
        existing = os.path.join(d, "old.json")
        with open(existing, "w") as f:
            f.write("keep")
        new = os.path.join(d, "new.vtu")
        pdir = os.path.join(d, "variants")
        os.makedirs(pdir, exist_ok=True)
        with open(os.path.join(pdir, "variant_c.vtu"), "w") as f:
            f.write("keep")
        cases = [
            (["quality", mesh, "--report", mesh, "--force"], "is the input"),
            (["quality", mesh, "--report", existing, "-o", new], "file exists"),
            (["quality", mesh, "-o", os.path.join(d, "nope", "a.vtu")], "does not exist"),
            (["smooth", mesh, "-o", mesh, "--force"], "is the input"),
            (["convert", mesh, os.path.join(d, ".", "m.vtu"), "--force"], "is the input"),
            (["mesh", src, "--size", "4", "-o", new, "--report", src, "--force"], "is the input"),
            (["compare", src, "--size", "4", "--mesh-dir", pdir, "--json", os.path.join(d, "c.json")], "file exists"),
            (["compare", src, "--size", "4", "--json", os.path.join(d, "nope", "c.json")], "does not exist"),
            (["insert-sheet", "--mesh", mesh, "--surface", os.path.join(SHARED_DATA, "sphere966.off"), "-o", mesh,
              "--force"], "is the input"),
        ]
        for args, message in cases:
            p = run([*args, "-q"] if args[0] in ("mesh", "compare", "smooth", "insert-sheet") else args, check=False)
            self.assertEqual(p.returncode, 1, (args, p.stderr))
            self.assertIn(message, p.stderr, args)
            self.assertEqual(len(p.stderr.strip().splitlines()), 1, p.stderr)
            self.assertFalse(os.path.exists(new), args)
            self.assertFalse(os.path.exists(os.path.join(d, "c.json")), args)
            self.assertEqual(sorted(os.listdir(pdir)), ["variant_c.vtu"], args)
        with open(mesh, "rb") as f:
            self.assertEqual(f.read(), original)
        with open(existing) as f:
            self.assertEqual(f.read(), "keep")
        with open(src, "rb") as f:
            self.assertEqual(f.read(2), b"\x1f\x8b")  # still the gzip scan
        # two inputs of one name into one --out-dir
        other = os.path.join(d, "elsewhere")
        os.makedirs(other, exist_ok=True)
        shutil.copyfile(src, os.path.join(other, "sphere.nii.gz"))
        out = os.path.join(d, "both")
        p = run(["mesh", src, os.path.join(other, "sphere.nii.gz"), "--size", "4", "--out-dir", out, "--force", "-q"],
                check=False)
        self.assertEqual(p.returncode, 1, p.stderr)
        self.assertIn("would both write", p.stderr)
        self.assertFalse(os.path.exists(os.path.join(out, "sphere.vtu")))

    def test_an_interrupted_job_leaves_no_output_and_no_temporary(self):
        # SIGINT while the second of three outputs was being written left the
        # first output and a hidden .<name>.tmp<pid>_<n> file behind, and a
        # rerun without --force then refused the output it found.
        import signal
        import time
        d = os.path.join(self.dir, "interrupt")
        os.makedirs(d, exist_ok=True)
        outs = [os.path.join(d, "big" + e) for e in (".exo", ".msh", ".inp")]
        args = [ISOHEX, "mesh", os.path.join(self.dir, "sphere.nii.gz"), "--size", "0.5", "--no-optimize", "-q",
                "--allow-below"]
        for o in outs:
            args += ["-o", o]
        p = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        while not os.path.exists(outs[0]) and p.poll() is None:
            time.sleep(0.002)
        self.assertIsNone(p.poll(), "finished before the first output appeared: nothing to interrupt")
        p.send_signal(signal.SIGINT)
        p.communicate()
        self.assertEqual(p.returncode, -signal.SIGINT)
        self.assertEqual(os.listdir(d), [])
        # the same job then runs without --force
        q = subprocess.run(args, capture_output=True, text=True)
        # (written either way with --allow-below; status 4 only with hexes below the minimum, which it names)
        self.assertEqual(q.returncode, EXIT_BELOW_QUALITY if "below the minimum quality" in q.stderr else 0, q.stderr)
        self.assertEqual(sorted(os.listdir(d)), sorted(os.path.basename(o) for o in outs))

    def test_a_crash_inside_the_pipeline_is_an_error_that_names_the_input_and_stage(self):
        # The shell's "Segmentation fault" was all a user got when a library
        # crashed. ISOHEX_TEST_CRASH raises SIGSEGV as the stage begins.
        import signal
        out = os.path.join(self.dir, "crash.vtu")
        args = ["mesh", os.path.join(self.dir, "sphere.nii.gz"), "--size", "4", "-o", out, "-q"]
        p = run(args, check=False, env=dict(os.environ, ISOHEX_TEST_CRASH="extract"))
        self.assertEqual(p.returncode, 1, p.stderr)
        self.assertEqual(p.stderr.strip(), "isohex: error: " + os.path.join(self.dir, "sphere.nii.gz") +
                         ": isohex crashed in its extract stage (SIGSEGV, segmentation fault). This is a bug: please "
                         "report it with the command line and the input.")
        self.assertFalse(os.path.exists(out))
        # A dangling symbolic link at the output path is not the job's to remove.
        link = os.path.join(self.dir, "link.vtu")
        if os.path.lexists(link):
            os.remove(link)
        os.symlink(os.path.join(self.dir, "nowhere", "x.vtu"), link)
        p = run(["mesh", os.path.join(self.dir, "sphere.nii.gz"), "--size", "4", "-o", link, "-q"], check=False,
                env=dict(os.environ, ISOHEX_TEST_CRASH="load"))
        self.assertEqual(p.returncode, 1, p.stderr)
        self.assertTrue(os.path.islink(link))
        # A limit the user set is not a bug: the file size limit (ulimit -f)
        import resource
        big = os.path.join(self.dir, "fsize.vtu")
        p = subprocess.run([ISOHEX, "mesh", os.path.join(self.dir, "sphere.nii.gz"), "--size", "2", "-o", big, "-q"],
                           capture_output=True, text=True,
                           preexec_fn=lambda: resource.setrlimit(resource.RLIMIT_FSIZE, (20000, 20000)))
        self.assertEqual(p.returncode, 1, p.stderr)
        self.assertIn("was stopped (SIGXFSZ", p.stderr)
        self.assertIn("size limit", p.stderr)
        self.assertNotIn("bug", p.stderr)
        self.assertEqual([n for n in os.listdir(self.dir) if n.startswith(".fsize")], [])
        self.assertFalse(os.path.exists(big))
        # The injected fault is a real crash: without the child process it ends isohex.
        p = run(args, check=False, env=dict(os.environ, ISOHEX_TEST_CRASH="extract", ISOHEX_ISOLATE="0"))
        self.assertEqual(p.returncode, -signal.SIGSEGV, p.stderr)
        # compare reads the scan the same way: a reader's crash there fails it alone too.
        js = os.path.join(self.dir, "crash.json")
        p = run(["compare", os.path.join(self.dir, "sphere.nii.gz"), "--size", "4", "--json", js, "-q"], check=False,
                env=dict(os.environ, ISOHEX_TEST_CRASH="load"))
        self.assertEqual(p.returncode, 1, p.stderr)
        self.assertIn("sphere.nii.gz: a library crashed reading it (SIGSEGV, segmentation fault)", p.stderr)
        self.assertFalse(os.path.exists(js))
        # Errors of the job itself keep their message and exit status.
        p = run(["mesh", os.path.join(self.dir, "sphere.nii.gz"), "--iso", "1e9", "-o", out, "-q"], check=False)
        self.assertEqual(p.returncode, 1, p.stderr)
        self.assertTrue(p.stderr.startswith("isohex: error: "), p.stderr)
        self.assertNotIn("crash", p.stderr)

    def test_killing_isohex_ends_its_meshing_process_and_a_hangup_it_ignores_does_not(self):
        # The job runs in a child process; a batch manager's SIGKILL or SIGTERM
        # to isohex must not leave that child meshing on as an orphan.
        import signal
        import time
        d = os.path.join(self.dir, "orphan")
        os.makedirs(d, exist_ok=True)
        out = os.path.join(d, "s.vtu")
        args = [ISOHEX, "mesh", os.path.join(self.dir, "sphere.nii.gz"), "--size", "0.5", "-o", out, "-q", "--force"]

        def started(p):
            path = f"/proc/{p.pid}/task/{p.pid}/children"
            for _ in range(5000):
                with open(path) as f:
                    kids = f.read().split()
                if kids:
                    return int(kids[0])
                time.sleep(0.002)
            self.fail("no meshing process started")

        def gone(pid):
            try:
                with open(f"/proc/{pid}/stat") as f:
                    return f.read().rsplit(")", 1)[1].split()[0] in ("Z", "X")  # a zombie has ended
            except FileNotFoundError:
                return True

        for sig in (signal.SIGKILL, signal.SIGTERM):
            p = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
            child = started(p)
            time.sleep(0.5)
            p.send_signal(sig)
            p.communicate()
            self.assertEqual(p.returncode, -sig)
            deadline = time.time() + 3  # the whole run takes about 6 s
            while not gone(child) and time.time() < deadline:
                time.sleep(0.05)
            self.assertTrue(gone(child), f"the meshing process outlived isohex's {sig.name}")
            self.assertEqual(os.listdir(d), [], "outputs or temporaries left behind")
        # Started the way nohup starts it, isohex ignores the hangup and finishes.
        p = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                             preexec_fn=lambda: signal.signal(signal.SIGHUP, signal.SIG_IGN))
        started(p)
        p.send_signal(signal.SIGHUP)
        _, err = p.communicate()
        self.assertEqual(p.returncode, 0, err)
        self.assertTrue(os.path.exists(out))

    def test_damaged_gzip_data_in_a_nifti_is_named_as_damage_not_truncation(self):
        # A .nii.gz whose gzip check bytes were damaged was reported as
        # "truncated" (or, damaged in the CRC only, meshed).
        with open(os.path.join(self.dir, "sphere.nii.gz"), "rb") as f:
            good = f.read()
        out = os.path.join(self.dir, "gz.vtu")
        for name, at in (("badcrc", len(good) - 6), ("baddata", len(good) // 2)):
            src = os.path.join(self.dir, name + ".nii.gz")
            b = bytearray(good)
            b[at] ^= 0x5A
            with open(src, "wb") as f:
                f.write(bytes(b))
            p = run(["mesh", src, "--size", "4", "-o", out, "-q"], check=False)
            self.assertEqual(p.returncode, 1, p.stderr)
            self.assertTrue(p.stderr.startswith(f"isohex: error: {src}: the compressed data is damaged (zlib: "),
                            p.stderr)
            self.assertIn("Copy or export the file again", p.stderr)
            self.assertNotIn("truncated", p.stderr)
            self.assertEqual(p.stderr.count(src), 1, p.stderr)  # zlib's own text starts with the path too
            if name == "badcrc":
                self.assertIn("incorrect data check", p.stderr)
            self.assertFalse(os.path.exists(out))

    def test_a_volume_index_the_file_does_not_have_is_refused(self):
        # --volume-index 5 on a 3-D scan was silently ignored (volume 0 meshed)
        out = os.path.join(self.dir, "vi.vtu")
        p = run(["mesh", os.path.join(self.dir, "sphere.nii.gz"), "--volume-index", "5", "-o", out, "-q"], check=False)
        self.assertEqual(p.returncode, 1, p.stderr)
        self.assertIn("sphere.nii.gz: volume index 5 does not exist", p.stderr)
        self.assertFalse(os.path.exists(out))
        run(["mesh", os.path.join(self.dir, "sphere.nii.gz"), "--volume-index", "0", "--size", "4", "-o", out, "-q"])
        self.assertTrue(os.path.exists(out))

    def test_memory_budget_and_volume_index_take_only_meaningful_values(self):
        # --max-memory 0 and nan, and --volume-index -1, were accepted (0 and
        # -1 silently meant the defaults)
        out = os.path.join(self.dir, "opts.vtu")
        src = os.path.join(self.dir, "sphere.nii.gz")
        for args, message in ((["--max-memory", "0"], "above 0 (got '0')"),
                              (["--max-memory", "nan"], "above 0 (got 'nan')"),
                              (["--volume-index", "-1"], "between 0 and")):
            p = run(["mesh", src, *args, "-o", out, "-q"], check=False)
            self.assertEqual(p.returncode, 2, (args, p.stderr))
            self.assertIn(message, p.stderr)
            self.assertFalse(os.path.exists(out))
        manifest = os.path.join(self.dir, "opts.csv")
        with open(manifest, "w") as f:
            f.write("input,output,max_memory\n%s,%s,0\n" % (src, out))
        p = run(["batch", manifest], check=False)
        self.assertNotEqual(p.returncode, 0)
        self.assertIn("opts.csv:2:", p.stderr)
        self.assertIn("above 0", p.stderr)

    def test_otsu_failures_name_the_scan(self):
        # a flat scan's message did not say which file (a batch has many), and
        # values near the float limits gave "iso value -nan"
        sys.path.insert(0, os.path.join(SOURCE, "samples"))
        from make_phantoms import write_nifti
        flat = os.path.join(self.dir, "flat.nii.gz")
        write_nifti(flat, np.full((8, 8, 8), 7.0, dtype=np.float32))
        extreme = np.zeros((8, 8, 8), dtype=np.float32)
        extreme[:4] = -3.0e38
        extreme[4:] = 3.0e38
        huge = os.path.join(self.dir, "extreme.nii.gz")
        write_nifti(huge, extreme)
        out = os.path.join(self.dir, "otsu.vtu")
        for src, message in ((flat, "flat.nii.gz: Otsu threshold: every voxel has the value 7"),
                             (huge, "extreme.nii.gz: Otsu's method found no threshold")):
            p = run(["mesh", src, "-o", out, "-q"], check=False)
            self.assertEqual(p.returncode, 1, p.stderr)
            self.assertIn(message, p.stderr)
            self.assertNotIn("nan", p.stderr)
        self.assertFalse(os.path.exists(out))

    def test_compare_refuses_a_seed_that_is_not_a_whole_number(self):
        # --seed -1 was taken as 18446744073709551615 (an unsigned wrap) and 1.5 as 1
        js = os.path.join(self.dir, "seed.json")
        for seed in ("-1", "1.5", "99999999999999999999999"):
            p = run(["compare", os.path.join(self.dir, "sphere.nii.gz"), "--size", "4", "--seed", seed, "--json", js,
                     "-q"], check=False)
            self.assertEqual(p.returncode, 2, (seed, p.stderr))
            self.assertIn("--seed takes a whole number", p.stderr)
            self.assertIn("(got '%s')" % seed, p.stderr)
            self.assertFalse(os.path.exists(js))

    def test_unknown_output_format_fails_before_meshing(self):
        p = run(["mesh", os.path.join(self.dir, "sphere.nii.gz"), "-o", os.path.join(self.dir, "z.stp"), "-q"],
                check=False)
        self.assertNotEqual(p.returncode, 0)
        self.assertIn(".vtu", p.stderr)

    def test_several_inputs_continue_past_a_failure_and_resume(self):
        bad = os.path.join(self.dir, "garbage.nii.gz")
        with open(bad, "wb") as f:
            f.write(b"this is not a scan")
        out = os.path.join(self.dir, "batch")
        args = ["mesh", os.path.join(self.dir, "sphere.nii.gz"), bad, os.path.join(self.dir, "torus.nii.gz"),
                "--iso", "50", "--size", "4", "--out-dir", out, "--format", "vtu,inp", "-q"]
        p = run(args, check=False)
        self.assertNotEqual(p.returncode, 0)
        for name in ("sphere", "torus"):
            for ext in ("vtu", "inp", "report.json"):
                self.assertTrue(os.path.exists(os.path.join(out, f"{name}.{ext}")), (name, ext))
        self.assertFalse(os.path.exists(os.path.join(out, "garbage.vtu")))
        self.assertIn("1 failed", p.stdout)
        again = run(args, check=False)
        self.assertIn("2 skipped", again.stdout)
        self.assertIn("1 failed", again.stdout)


if __name__ == "__main__":
    unittest.main(verbosity=2)
