"""The mesher on the real scans in shared/data (issues 4 and 5), judged from the
written files with numpy/VTK: topological validity after dual contouring, volume
against the isosurface, and what pillowing must guarantee (one new hex per surface
quad, surface nodes bit-identical, at most one face per hex on each surface, two
sheets on every interface between labels)."""
import json
import os
import sys
import unittest

import numpy as np
import vtk
from vtk.util import numpy_support as ns

sys.path.insert(0, os.path.dirname(__file__))
from common import SHARED_DATA, SOURCE, polygon_topology, run, run_below_allowed, workdir  # noqa: E402
from vtk_tools import read_vtu, vtk_volumes  # noqa: E402

sys.path.insert(0, os.path.join(SOURCE, "samples"))
from make_phantoms import write_nifti  # noqa: E402

FACES = np.array([[0, 4, 7, 3], [1, 2, 6, 5], [0, 1, 5, 4], [3, 7, 6, 2], [0, 3, 2, 1], [4, 5, 6, 7]])

CASES = [
    # name, file, options
    ("skull", "skull_ct.nii.gz", ["--iso", "2.9"]),
    ("brain_2mm", "ch2bet.nii.gz", ["--size", "2", "--keep-largest"]),
    ("jhu_labels", "JHU-WhiteMatter-labels-2mm.nii.gz", ["--labels"]),
    # closed triangle surfaces, meshed through their signed-distance level sets
    ("femur", "femur.off", []),
    ("sphere966", "sphere966.off", []),
    ("knot1", "knot1.off", []),
    ("fandisk", "fandisk.off", []),
]


def read(path):
    r = vtk.vtkXMLUnstructuredGridReader()
    r.SetFileName(path)
    r.Update()
    g = r.GetOutput()
    pts = ns.vtk_to_numpy(g.GetPoints().GetData()).astype(float)
    hexes = ns.vtk_to_numpy(g.GetCells().GetConnectivityArray()).reshape(-1, 8)
    mat = ns.vtk_to_numpy(g.GetCellData().GetArray("material"))
    return pts, hexes, mat


def faces_of(hexes, mat):
    """All hex faces: sorted node keys, owning hex, material."""
    f = hexes[:, FACES].reshape(-1, 4)
    keys = np.sort(f, axis=1)
    owner = np.repeat(np.arange(len(hexes)), 6)
    return keys, owner, mat[owner]


def surface_faces(hexes, mat):
    """Faces on a surface: held by one hex, or by two hexes of different material.
    Returns (owner hex, surface id) per face side, surface = (material, other or -1)."""
    keys, owner, fm = faces_of(hexes, mat)
    order = np.lexsort(keys.T[::-1])
    k = keys[order]
    same_next = np.all(k[1:] == k[:-1], axis=1)
    start = np.concatenate([[True], ~same_next])
    group = np.cumsum(start) - 1
    counts = np.bincount(group)
    o, m = owner[order], fm[order]
    other = np.full(len(o), -1)
    pair = counts[group] == 2
    idx = np.nonzero(pair)[0]
    first = idx[start[idx]]
    other[first] = m[first + 1]
    other[first + 1] = m[first]
    on_surface = (counts[group] == 1) | (pair & (other != m))
    return o[on_surface], m[on_surface], other[on_surface], group[on_surface]


class RealScans(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.dir = workdir("real")
        cls.meshes = {}
        for name, file, opts in CASES:
            src = os.path.join(SHARED_DATA, file)
            plain = os.path.join(cls.dir, f"{name}_dc.vtu")
            pillowed = os.path.join(cls.dir, f"{name}_pillow.vtu")
            # a triangle surface is certified against 0.5 by default, a scan against 0
            target = 0.5 if file.endswith((".off", ".stl", ".obj", ".ply")) else 0.0
            # the tangled start: the valid start holds surface vertices back and
            # returns them only after the sheet, so the sheet's own property
            # (surface nodes kept bit for bit) is judged without it
            run_below_allowed(["mesh", src, *opts, "--no-optimize", "--tangled-start", "--no-pillow", "-o", plain,
                               "--report", plain + ".json", "-q"], plain, target)
            run_below_allowed(["mesh", src, *opts, "--no-optimize", "--tangled-start", "-o", pillowed, "--report",
                               pillowed + ".json", "-q"],
                              pillowed, target)
            with open(plain + ".json") as f:
                rp = json.load(f)
            with open(pillowed + ".json") as f:
                rq = json.load(f)
            cls.meshes[name] = (read(plain), read(pillowed), rp, rq)

    def test_dual_contouring_is_topologically_valid(self):
        for name, (_, _, rep, _) in self.meshes.items():
            defects = set(rep["validity"]["defects"]) - {"inverted_hex"}
            self.assertEqual(defects, set(), f"{name}: {rep['validity']}")

    def test_volume_within_two_percent_of_the_isosurface(self):
        for name in ("skull", "brain_2mm", "femur", "sphere966", "knot1", "fandisk"):
            rep = self.meshes[name][2]
            change = rep["fidelity"]["volume_change_percent"]
            print(f"{name}: volume change {change:+.3f}% ({rep['hexes']} hexes)")
            self.assertLess(abs(change), 2.0, name)

    def test_label_volume_lies_between_the_smooth_isosurface_and_the_voxels(self):
        # The 0.5-isosurface of a label's indicator rounds voxel corners off; dual
        # contouring follows the label boundaries, so the mesh volume must fall
        # between that smooth surface's volume and the label's voxel volume.
        f = self.meshes["jhu_labels"][2]["fidelity"]
        print(f"labels: sum of the labels' isosurfaces {f['volume_labels_isosurfaces']:.0f}, "
              f"mesh {f['volume_mesh']:.0f}, voxels {f['volume_voxels']:.0f} mm^3")
        self.assertGreater(f["volume_mesh"], f["volume_labels_isosurfaces"])
        self.assertLess(f["volume_mesh"], f["volume_voxels"])

    def test_label_total_volume_against_the_union_isosurface_measured_with_vtk(self):
        # Issue 4's volume criterion for a label map: the mesh partitions the
        # labelled region, whose surface is the 0.5-isosurface of the union of
        # the selected labels. Both that reference (VTK's flying edges on the
        # union's indicator) and the mesh's volume (VTK's cell sizes of the
        # written file) are measured here, not taken from isohex.
        _, _, rep, pillowed = self.meshes["jhu_labels"]
        f = rep["fidelity"]
        self.assertEqual(f["volume_isosurface_of"], "union of the selected labels")
        reader = vtk.vtkNIFTIImageReader()
        reader.SetFileName(os.path.join(SHARED_DATA, "JHU-WhiteMatter-labels-2mm.nii.gz"))
        reader.Update()
        img = reader.GetOutput()
        labels = ns.vtk_to_numpy(img.GetPointData().GetScalars())
        selected = [m["id"] for m in rep["selection"]["materials"]]
        self.assertGreater(len(selected), 1)
        union = vtk.vtkImageData()
        union.DeepCopy(img)
        union.GetPointData().SetScalars(ns.numpy_to_vtk(np.isin(labels, selected).astype(np.float32), deep=True))
        ext = union.GetExtent()
        pad = vtk.vtkImageConstantPad()
        pad.SetInputData(union)
        pad.SetConstant(0.0)
        pad.SetOutputWholeExtent(ext[0] - 1, ext[1] + 1, ext[2] - 1, ext[3] + 1, ext[4] - 1, ext[5] + 1)
        fe = vtk.vtkFlyingEdges3D()
        fe.SetInputConnection(pad.GetOutputPort())
        fe.SetValue(0, 0.5)
        fe.ComputeNormalsOff()
        mass = vtk.vtkMassProperties()
        mass.SetInputConnection(fe.GetOutputPort())
        mass.Update()
        vtk_union = mass.GetVolume()
        self.assertGreater(vtk_union, 0)
        # isohex's reference is OpenVDB's polygonisation of the same field.
        self.assertAlmostEqual(f["volume_isosurface"] / vtk_union, 1.0, delta=0.005)
        self.assertLess(f["volume_isosurface"], f["volume_voxels"])
        self.assertGreater(f["volume_isosurface"], 1.03 * f["volume_labels_isosurfaces"])
        for name, path in (("extracted", os.path.join(self.dir, "jhu_labels_dc.vtu")),
                           ("pillowed", os.path.join(self.dir, "jhu_labels_pillow.vtu"))):
            mesh_volume = vtk_volumes(read_vtu(path)).sum()
            change = 100 * (mesh_volume - vtk_union) / vtk_union
            print(f"jhu labels {name}: mesh {mesh_volume:.0f}, union isosurface (VTK) {vtk_union:.0f} mm^3, "
                  f"{change:+.2f}%")
            self.assertLess(abs(change), 2.0, name)

    def test_pillow_adds_one_hex_per_surface_quad_and_keeps_surface_nodes(self):
        for name, ((p0, h0, m0), (p1, h1, m1), _, _) in self.meshes.items():
            owner, mat, other, group = surface_faces(h0, m0)
            sides = len(owner)  # an interface quad counts once per side: it gets a sheet on each
            self.assertEqual(len(h1) - len(h0), sides, name)
            np.testing.assert_array_equal(p1[: len(p0)], p0, err_msg=name)  # bit-identical

    def test_after_pillowing_no_hex_has_two_faces_on_one_surface(self):
        for name, (_, (p1, h1, m1), _, rep) in self.meshes.items():
            defects = set(rep["validity"]["defects"]) - {"inverted_hex"}
            self.assertEqual(defects, set(), f"{name}: {rep['validity']}")
            owner, mat, other, _ = surface_faces(h1, m1)
            key = owner.astype(np.int64) * 1_000_000 + (other + 1)
            _, n = np.unique(key, return_counts=True)
            self.assertEqual(n.max(), 1, f"{name}: a hex has {n.max()} faces on one surface")

    def test_every_interface_carries_two_sheets(self):
        (_, h0, m0), (_, h1, m1), _, _ = self.meshes["jhu_labels"]
        owner, mat, other, _ = surface_faces(h1, m1)
        interface = other >= 0
        self.assertGreater(interface.sum(), 100)
        # both hexes at every interface quad are new sheet hexes
        self.assertTrue(np.all(owner[interface] >= len(h0)))




def boundary_quads(hexes, mat):
    """The quads of the mesh boundary against the outside (faces held by
    one hex), from the written file."""
    keys, owner, fm = faces_of(hexes, mat)
    order = np.lexsort(keys.T[::-1])
    k = keys[order]
    same_next = np.all(k[1:] == k[:-1], axis=1)
    start = np.concatenate([[True], ~same_next])
    counts = np.bincount(np.cumsum(start) - 1)
    single = np.nonzero(counts == 1)[0]
    firsts = np.nonzero(start)[0][single]
    return hexes[:, FACES].reshape(-1, 4)[order[firsts]]


def boundary_topology(hexes, mat):
    """Components and Euler characteristic of the mesh boundary."""
    return polygon_topology(boundary_quads(hexes, mat))


class IsosurfaceTopology(unittest.TestCase):
    """--isosurface-topology (issue 4): after the non-manifold repair, the
    repair's changes are re-chosen so the boundary keeps the components and
    Euler characteristic of volumeToMesh's surface on the element grid (the
    report's grid.repair.isosurface_topology.isosurface). On ch2bet at 1 mm
    (--keep-largest) the repair alone gives 483 components and chi 632
    against the isosurface's 491 and 674; with the option they are equal
    since the deep search (session 24), and at 2 mm since its annealing
    (session 25)."""

    def test_boundary_of_the_written_mesh_matches_the_isosurface_on_the_grid(self):
        d = workdir("isosurface_topology")
        src = os.path.join(SHARED_DATA, "ch2bet.nii.gz")
        got = {}
        for name, extra in (("plain", []), ("matched", ["--isosurface-topology"])):
            out = os.path.join(d, f"{name}.vtu")
            p = run_below_allowed(["mesh", src, "--size", "1", "--keep-largest", "--no-optimize", "--no-pillow",
                                   *extra, "-o", out, "--report", out + ".json", "--force"], out)
            with open(out + ".json") as f:
                rep = json.load(f)
            _, hexes, mat = read(out)
            os.remove(out)  # 190 MB each: one at a time on the disk
            got[name] = (boundary_topology(hexes, mat), rep, p.stderr)
        (c, e), rep, stderr = got["matched"]
        block = rep["grid"]["repair"]["isosurface_topology"]
        want = block["isosurface"][0]
        # the report's topology is the written mesh's
        self.assertEqual((c, e), (rep["grid"]["topology"][0]["components"], rep["grid"]["topology"][0]["euler"]))
        (c0, e0), rep0, _ = got["plain"]
        self.assertNotIn("isosurface_topology", rep0["grid"]["repair"])
        print(f"ch2bet 1 mm: isosurface on the grid {want['components']} components, chi {want['euler']}; "
              f"repair alone {c0}/{e0}; with --isosurface-topology {c}/{e} "
              f"({block['groups_mended']} of {block['groups_changing_it']} places mended)")
        self.assertEqual((c, e), (want["components"], want["euler"]))
        self.assertNotEqual((c0, e0), (want["components"], want["euler"]))
        self.assertEqual(block["groups_mended"], block["groups_changing_it"])
        self.assertEqual(block["unmended"], [])
        self.assertNotIn("--isosurface-topology: the mesh boundary has", stderr)

    def test_two_millimetres_matches_too(self):
        # ch2bet at 2 mm: the place the beam search leaves (grid 46..49,
        # 52..57, 13..19) is mended by the annealing; the written mesh's
        # boundary, counted here, equals the isosurface's
        d = workdir("isosurface_topology")
        out = os.path.join(d, "two.vtu")
        p = run_below_allowed(["mesh", os.path.join(SHARED_DATA, "ch2bet.nii.gz"), "--size", "2", "--keep-largest",
                               "--no-optimize", "--no-pillow", "--isosurface-topology", "-o", out, "--report",
                               out + ".json", "--force"], out)
        with open(out + ".json") as f:
            rep = json.load(f)
        _, hexes, mat = read(out)
        c, e = boundary_topology(hexes, mat)
        block = rep["grid"]["repair"]["isosurface_topology"]
        want = block["isosurface"][0]
        print(f"ch2bet 2 mm: isosurface on the grid {want['components']} components, chi {want['euler']}; "
              f"with --isosurface-topology {c}/{e} ({block['anneal_steps']} annealing steps)")
        self.assertEqual((c, e), (want["components"], want["euler"]))
        self.assertEqual(block["unmended"], [])
        self.assertGreater(block["anneal_steps"], 0)
        self.assertNotIn("--isosurface-topology: the mesh boundary has", p.stderr)

    def test_places_not_mended_are_named_where_the_boundary_is(self):
        # No real scan here is left with a place (since the annealing), so the
        # naming is checked on a synthetic one that is: random noise smoothed
        # twice over 3x3x3, cut at 0 (numpy's default_rng(95), 20^3 voxels of
        # 1 mm; of 115 such seeds it is the one the search leaves a place on:
        # 164 of 165 places mended). If a better search mends it, this test
        # says so and needs another input.
        d = workdir("isosurface_topology")
        a = np.random.default_rng(95).random((20, 20, 20)) - 0.5
        for _ in range(2):
            p = np.pad(a, 1, mode="edge")
            a = sum(p[i:i + 20, j:j + 20, k:k + 20] for i in range(3) for j in range(3) for k in range(3)) / 27.0
        a[:2] = a[-2:] = a[:, :2] = a[:, -2:] = a[:, :, :2] = a[:, :, -2:] = -0.2
        scan = os.path.join(d, "noise95.nii.gz")
        write_nifti(scan, (a * 1000).astype(np.float32))
        out = os.path.join(d, "noise95.vtu")
        p = run_below_allowed(["mesh", scan, "--iso", "0", "--size", "1", "--no-optimize", "--no-pillow",
                               "--isosurface-topology", "-o", out, "--report", out + ".json", "--force"], out)
        with open(out + ".json") as f:
            rep = json.load(f)
        pts, hexes, mat = read(out)
        c, e = boundary_topology(hexes, mat)
        block = rep["grid"]["repair"]["isosurface_topology"]
        want = block["isosurface"][0]
        places = block["unmended"]
        self.assertNotEqual(places, [], "the search now mends this input: pick one it leaves a place on")
        self.assertEqual(len(places), block["groups_changing_it"] - block["groups_mended"])
        # each accepted step keeps the surface exactly: what is off (counted
        # on the written mesh) is what the named places change
        self.assertEqual(sum(pl["euler_change"] for pl in places), e - want["euler"])
        self.assertEqual((c, e), (rep["grid"]["topology"][0]["components"], rep["grid"]["topology"][0]["euler"]))
        self.assertIn("--isosurface-topology: the mesh boundary has", p.stderr)
        self.assertIn("not mended near", p.stderr)
        size = rep["grid"]["element_size"]
        bnodes = pts[np.unique(boundary_quads(hexes, mat))]
        for pl in places:
            lo, hi = np.array(pl["world_min"]), np.array(pl["world_max"])
            self.assertTrue(np.all(lo <= hi))
            self.assertTrue(np.all(np.array(pl["grid_min"]) <= np.array(pl["grid_max"])))
            if pl is places[0]:
                self.assertIn(f"({lo[0]:g}, {lo[1]:g}, {lo[2]:g})", p.stderr)
            # the place is on the boundary: boundary nodes lie in its box (one element around)
            pad = np.array(size)
            near = np.all((bnodes >= lo - pad) & (bnodes <= hi + pad), axis=1)
            self.assertGreater(int(near.sum()), 0)

    def test_refused_with_the_sheet_method(self):
        p = run(["mesh", os.path.join(SHARED_DATA, "femur.off"), "--method", "sheets", "--isosurface-topology",
                 "-o", os.path.join(workdir("isosurface_topology"), "femur.vtu"), "--force"], check=False)
        self.assertNotEqual(p.returncode, 0)
        self.assertIn("--isosurface-topology", p.stderr)


if __name__ == "__main__":
    unittest.main(verbosity=2)
