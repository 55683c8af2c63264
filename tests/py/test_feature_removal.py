"""End-to-end tests of feature removal, the certified minimum's last means: a
label map with a one-voxel speck or a one-voxel pocket misses --min-quality 0.6
with --keep-features; by default the
feature is removed, listed in the report (position, volume) and the minimum is
reached, judged by VTK's vtkMeshQuality on the written file; the same volumes
without the feature (a ball, a plate) remove nothing. The meshing without the
feature optimises only a neighbourhood of it: every node farther away keeps
the position it had in the mesh with the feature. (A tunnel one voxel wide
through a plate four voxels thick reaches 0.6 without removal; the tunnel
search is tested on label grids in tests/pipeline/test_local_features.cpp.)"""
import json
import os
import sys
import unittest

import numpy as np
from vtk.util import numpy_support as ns

sys.path.insert(0, os.path.dirname(__file__))
sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "..", "samples"))
from common import EXIT_BELOW_QUALITY, run, workdir  # noqa: E402
from make_phantoms import write_nifti  # noqa: E402
from vtk_tools import read_vtu, vtk_sj  # noqa: E402

Q = 0.6


class FeatureRemoval(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.dir = workdir("feature_removal")
        n = 32
        x, y, z = np.meshgrid(*(np.arange(n),) * 3, indexing="ij")
        ball = (((x - 15.5) ** 2 + (y - 15.5) ** 2 + (z - 15.5) ** 2) < 10.5 ** 2).astype(np.uint8)
        speck, pocket = ball.copy(), ball.copy()
        speck[15, 15, 29] = 1   # two voxels off the ball
        pocket[15, 15, 15] = 0  # at its centre
        halves = np.where(ball & (x >= 16), 2, ball).astype(np.uint8)  # two materials: a curve where both meet the outside
        halves[15, 15, 29] = 1
        plate = np.zeros((n, n, n), np.uint8)
        plate[4:28, 4:28, 14:18] = 1
        for name, a in (("ball", ball), ("speck", speck), ("pocket", pocket), ("plate", plate), ("halves", halves)):
            write_nifti(os.path.join(cls.dir, name + ".nii.gz"), a)

    def out(self, name, *extra):
        return os.path.join(self.dir, name + "".join(extra).replace("-", "_") + ".vtu")

    def mesh(self, name, *extra):
        out = self.out(name, *extra)
        report = out[:-4] + ".json"
        p = run(["mesh", os.path.join(self.dir, name + ".nii.gz"), "--labels", "--size", "1", "--min-quality",
                 str(Q), "--threads", "1", "-o", out, "--report", report, "-q", "--force", *extra], check=False)
        with open(report) as f:
            q = json.load(f)["quality"]
        return p, vtk_sj(out), q

    def removal(self, q):
        return [m for m in q["means"] if m["mean"] == "feature_removal"]

    def check_removed(self, name, shape, at, material, replaced_by):
        kept, sj_kept, q_kept = self.mesh(name, "--allow-below", "--keep-features")
        self.assertEqual(kept.returncode, EXIT_BELOW_QUALITY, kept.stderr)
        self.assertLess(sj_kept.min(), Q)
        self.assertEqual(self.removal(q_kept), [])
        self.assertGreater(q_kept["below_target_by_shape"][shape], 0)
        p, sj, q = self.mesh(name)
        self.assertEqual(p.returncode, 0, p.stderr)
        self.assertIs(q["min_quality_certified"], True)
        self.assertGreaterEqual(sj.min(), Q)
        (r,) = self.removal(q)
        self.assertIs(r["kept"], True)
        self.assertEqual(len(r["features"]), 1)
        f = r["features"][0]
        self.assertEqual(f["shape"], shape)
        np.testing.assert_allclose(f["at"], at, atol=1e-9)
        self.assertEqual(f["volume"], float(f["grid_points"]))  # 1 mm voxels, --size 1
        self.assertEqual((f["material"], f["replaced_by"]), (material, replaced_by))
        self.check_far_nodes_kept(self.out(name, "--allow-below", "--keep-features"), self.out(name), r, at)
        return f

    def check_far_nodes_kept(self, with_feature, without, removal, at):
        # Only the hexes near the feature were optimised again; every node
        # outside the neighbourhood (a box of region["cells"] grid cells
        # around each changed grid point, plus the node's half cell and one
        # more for the repair) is where the mesh with the feature had it, to
        # the bit.
        region = removal["region"]
        self.assertLess(region["hexes"], 0.5 * region["mesh_hexes"])
        a = ns.vtk_to_numpy(read_vtu(with_feature).GetPoints().GetData())
        b = ns.vtk_to_numpy(read_vtu(without).GetPoints().GetData())
        far = np.abs(a - np.asarray(at)).max(axis=1) > region["cells"] + 1.5
        self.assertGreater(far.sum(), 0.5 * len(a))
        kept = {tuple(x) for x in b}
        moved = sum(1 for x in a[far] if tuple(x) not in kept)
        self.assertEqual(moved, 0, f"{moved} of {far.sum()} far nodes moved")

    def test_one_voxel_speck_is_removed_and_listed(self):
        f = self.check_removed("speck", "speck", [15, 15, 29], 1, 0)
        self.assertEqual(f["volume"], 1.0)

    def test_one_voxel_pocket_is_filled_and_listed(self):
        f = self.check_removed("pocket", "pocket", [15, 15, 15], 0, 1)
        self.assertEqual(f["volume"], 1.0)

    def test_far_nodes_keep_their_optimised_positions_next_to_a_curve(self):
        # Two materials meet the outside along a curve, whose nodes the
        # optimiser demotes to surface nodes where the curve runs through a
        # quad with two more of its nodes. The meshing without the speck
        # takes those nodes with the rest; freeing them as "changed" (the
        # fresh contouring makes them curve nodes again) optimised them alone
        # (JHU at 1 mm: 66 hexes left below 0.005).
        kept, _, q_kept = self.mesh("halves", "--allow-below", "--keep-features")
        p, _, q = self.mesh("halves", "--allow-below")
        (r,) = self.removal(q)
        self.assertIs(r["kept"], True)
        self.assertEqual([f["shape"] for f in r["features"]], ["speck"])
        self.assertGreaterEqual(q["min"], q_kept["min"])
        self.assertIn("region", r, "the whole volume was optimised again, not the speck's neighbourhood")
        self.check_far_nodes_kept(self.out("halves", "--allow-below", "--keep-features"),
                                  self.out("halves", "--allow-below"), r, [15, 15, 29])

    def test_controls_without_features_remove_nothing(self):
        for name in ("ball", "plate"):
            p, sj, q = self.mesh(name)
            self.assertEqual(p.returncode, 0, p.stderr)
            self.assertGreaterEqual(sj.min(), Q)
            self.assertEqual(self.removal(q), [])
            self.assertEqual(sum(q["below_target_by_shape"].values()), 0)


if __name__ == "__main__":
    unittest.main()
