"""Hostile inputs of the command line, the mesh readers, label maps and
surfaces: each is refused with one line naming the file (or option), the
problem and what to do, with nothing written, or (where the input is valid)
meshed correctly and checked against a control."""
import os
import re
import resource
import stat
import subprocess
import sys
import unittest

import numpy as np
from vtk.util.numpy_support import vtk_to_numpy

sys.path.insert(0, os.path.dirname(__file__))
sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "..", "samples"))
from common import ISOHEX, SHARED_DATA, SOURCE, run, workdir  # noqa: E402
from make_phantoms import ramp, write_nifti  # noqa: E402
from vtk_tools import read_vtu, vtk_sj, vtk_volumes  # noqa: E402

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "tools"))
from hostile_corpus import block_mesh, sphere_off, off_text  # noqa: E402


def material_of(vtu):
    return vtk_to_numpy(read_vtu(vtu).GetCellData().GetArray("material")).tolist()


def errors_of(p):
    return [line for line in p.stderr.splitlines()
            if line.strip() and not line.startswith(("isohex: warning", "isohex: info", "Run with --help"))]


class HostileInputs(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.dir = workdir("hostile_inputs")
        n = 16
        c = (n - 1) / 2
        x, y, z = np.meshgrid(*(np.arange(n) - c,) * 3, indexing="ij")
        cls.r = np.sqrt(x * x + y * y + z * z)
        cls.x = x
        cls.scan = os.path.join(cls.dir, "sphere.nii.gz")
        write_nifti(cls.scan, ramp(cls.r - 5))
        cls.sample_vtu = os.path.join(cls.dir, "sphere.vtu")
        run(["mesh", cls.scan, "-o", cls.sample_vtu, "-q"])

    def refused(self, args, must_name, *says, code=1, outputs=()):
        p = run(args, check=False)
        self.assertEqual(p.returncode, code, p.stdout + p.stderr)
        lines = errors_of(p)
        self.assertEqual(len(lines), 1, p.stderr)
        self.assertIn(must_name, lines[0])
        for s in says:
            self.assertIn(s, lines[0])
        for o in outputs:
            self.assertFalse(os.path.exists(o), o)
        return lines[0]

    # ------------------------------------------------------------ mesh files

    def test_a_vtu_declaring_a_billion_points_or_cells_is_refused_before_reading(self):
        # quality, smooth and convert said "out of memory; try a coarser
        # --size" after VTK had allocated 1.9 GB for the declared cells
        text = open(self.sample_vtu, encoding="latin-1").read()
        m = re.search(r'NumberOfPoints="(\d+)"\s*NumberOfCells="(\d+)"', text)
        self.assertIsNotNone(m)
        out = os.path.join(self.dir, "big_out.vtu")
        for what, lie in (("points", f'NumberOfPoints="1000000000" NumberOfCells="{m.group(2)}"'),
                          ("cells", f'NumberOfPoints="{m.group(1)}" NumberOfCells="2000000000"')):
            path = os.path.join(self.dir, f"declares_{what}.vtu")
            with open(path, "w", encoding="latin-1") as f:
                f.write(text[:m.start()] + lie + text[m.end():])
            for args in (["quality", path], ["convert", path, out], ["smooth", path, "-o", out, "-q"]):
                with self.subTest(what=what, command=args[0]):
                    line = self.refused(args, path, "declares", "the file has", outputs=[out])
                    self.assertNotIn("out of memory", line)

    def test_hexes_with_duplicated_unmerged_nodes_are_called_disconnected(self):
        # 27 cubes, each with its own 8 nodes: quality called the mesh valid
        import meshio
        pts, hexes = block_mesh(3)
        own = np.array([pts[i] for h in hexes for i in h], dtype=float)
        path = os.path.join(self.dir, "unmerged.vtu")
        meshio.write(path, meshio.Mesh(own, [("hexahedron", np.arange(8 * 27).reshape(27, 8))]))
        p = run(["quality", path], check=False)
        self.assertEqual(p.returncode, 0, p.stderr)
        self.assertNotIn("validity: ok", p.stdout)
        self.assertIn("coincident_node", p.stdout)
        self.assertIn("disconnected", p.stdout)
        self.assertEqual(run(["quality", path, "--strict"], check=False).returncode, 3)
        # the same cubes with shared nodes are valid
        shared = os.path.join(self.dir, "merged.vtu")
        meshio.write(shared, meshio.Mesh(np.array(pts, dtype=float), [("hexahedron", np.array(hexes))]))
        self.assertIn("validity: ok", run(["quality", shared]).stdout)

    def test_insert_sheet_refuses_a_mesh_whose_hexes_are_all_mirrored(self):
        import meshio
        block = os.path.join(SOURCE, "samples", "spherical_cuts_block.vtu")
        m = meshio.read(block)
        mirrored = os.path.join(self.dir, "mirrored_block.vtu")
        meshio.write(mirrored, meshio.Mesh(m.points, [("hexahedron", m.cells_dict["hexahedron"][:, [4, 5, 6, 7, 0, 1, 2, 3]])]))
        out = os.path.join(self.dir, "mirrored_cut.vtu")
        self.refused(["insert-sheet", "--mesh", mirrored, "--surface", os.path.join(SOURCE, "samples", "spherical_cut_1.off"),
                      "-o", out, "-q"], mirrored, "corner order is probably mirrored", outputs=[out])

    # ------------------------------------------------------------ labels

    def test_negative_labels_are_refused_and_never_written_as_material_ids(self):
        labels = np.zeros(self.r.shape, dtype=np.int16)
        labels[self.r < 5] = -1
        labels[(self.r < 5) & (self.x > 0)] = -5
        labels[self.r < 2] = 3
        path = os.path.join(self.dir, "negative_labels.nii.gz")
        write_nifti(path, labels)
        out = os.path.join(self.dir, "negative.vtu")
        self.refused(["mesh", path, "--labels", "-o", out, "-q"], path, "-5", "-1", "negative", "--label",
                     outputs=[out])
        self.refused(["mesh", path, "--label", "3,-1", "-o", out, "-q"], path, "-1", "negative", outputs=[out])
        # the positive label alone is meshed, with its own id only
        run(["mesh", path, "--label", "3", "-o", out, "-q"])
        g = read_vtu(out)
        from vtk.util import numpy_support as ns
        self.assertEqual(set(ns.vtk_to_numpy(g.GetCellData().GetArray("material")).tolist()), {3})

    # ------------------------------------------------------------ surfaces

    def write_off(self, name, v, f):
        path = os.path.join(self.dir, name)
        with open(path, "w") as fh:
            fh.write(off_text(v, f))
        return path

    def test_a_self_intersecting_surface_with_the_sheet_method_is_refused(self):
        # two overlapping spheres written as one closed surface: an inverted
        # hex and a generic warning, exit 0
        v, f = sphere_off()
        shifted = [(p[0] + 0.8, p[1], p[2]) for p in v]
        path = self.write_off("overlapping.off", v + shifted, f + [tuple(i + len(v) for i in t) for t in f])
        out = os.path.join(self.dir, "overlapping.vtu")
        self.refused(["mesh", path, "--method", "sheets", "-o", out, "-q"], path, "intersects itself",
                     outputs=[out])
        block = os.path.join(SOURCE, "samples", "spherical_cuts_block.vtu")
        self.refused(["insert-sheet", "--mesh", block, "--surface", path, "-o", out, "-q"], path, "intersects itself",
                     outputs=[out])

    def test_a_sphere_of_radius_1e_9_meshes_like_the_unit_sphere(self):
        # it was "not manifold": vertices closer than an absolute 1e-5 were welded
        v, f = sphere_off()
        unit = self.write_off("unit_sphere.off", v, f)
        tiny = self.write_off("tiny_sphere.off", [tuple(1e-9 * c for c in p) for p in v], f)
        out_unit = os.path.join(self.dir, "unit_sphere.vtu")
        out_tiny = os.path.join(self.dir, "tiny_sphere.vtu")
        run(["mesh", unit, "--method", "sheets", "-o", out_unit, "-q"])
        run(["mesh", tiny, "--method", "sheets", "-o", out_tiny, "-q"])
        gu, gt = read_vtu(out_unit), read_vtu(out_tiny)
        self.assertEqual(gu.GetNumberOfCells(), gt.GetNumberOfCells())
        self.assertGreater(min(vtk_sj(gt)), 0)
        vu, vt = sum(vtk_volumes(gu)), sum(vtk_volumes(gt))
        self.assertAlmostEqual(vt / (vu * 1e-27), 1.0, delta=1e-3)
        self.assertAlmostEqual(vu, 4 / 3 * np.pi, delta=0.25)

    # ------------------------------------------------------------ command line

    def test_an_unknown_command_is_named_with_the_list_of_commands(self):
        p = run(["frobnicate", self.scan], check=False)
        self.assertEqual(p.returncode, 2)
        line = errors_of(p)
        self.assertEqual(len(line), 1, p.stderr)
        self.assertIn("unknown command 'frobnicate'", line[0])
        for c in ("mesh", "quality", "smooth", "convert", "batch", "compare", "insert-sheet"):
            self.assertIn(c, line[0])

    def test_every_numeric_option_refuses_nan_inf_negative_and_huge_values_alike(self):
        out = os.path.join(self.dir, "opt.vtu")
        ranges = {"iso": None, "min-label-voxels": 0, "smooth": 0, "volume-index": 0, "max-memory": 0, "size": 0,
                  "level": 0, "boundary-layers": 1, "worst-hex-target": 0, "surface-tolerance": 0, "retries": 0,
                  "retry-below": 0, "threads": 1}
        for opt, lowest in ranges.items():
            bad = ["nan", "inf", "-inf"] + (["-1", "1e308", "99999999999999999999"] if lowest is not None else [])
            for v in bad:
                with self.subTest(option=opt, value=v):
                    line = self.refused(["mesh", self.scan, f"--{opt}", v, "-o", out, "-q"], f"--{opt}",
                                        f"(got '{v}')", code=2, outputs=[out])
                    self.assertRegex(line, r"must be")
            if opt in ("threads", "worst-hex-target"):  # no manifest column
                continue
            column = opt.replace("-", "_")
            for v in ("nan", "inf") + (("1e308",) if lowest is not None else ()):
                with self.subTest(column=column, value=v):
                    manifest = os.path.join(self.dir, f"opt_{column}.csv")
                    with open(manifest, "w") as f:
                        f.write(f"input,output,{column}\n{self.scan},{out},{v}\n")
                    p = run(["batch", manifest], check=False)
                    self.assertNotEqual(p.returncode, 0)
                    self.assertIn(f"opt_{column}.csv:2:", p.stderr)
                    self.assertIn(f"'{column}'", p.stderr)
                    self.assertFalse(os.path.exists(out))

    def test_an_unwritable_output_folder_is_found_before_meshing(self):
        # the folder's fault was found only when the mesh was written; the
        # crash injected at the first stage shows whether meshing began
        folder = os.path.join(self.dir, "read_only")
        os.makedirs(folder, exist_ok=True)
        os.chmod(folder, 0o555)
        os.chmod(self.dir, 0o755)
        os.chmod(self.scan, 0o644)
        os.chmod(self.sample_vtu, 0o644)
        out = os.path.join(folder, "x.vtu")
        as_user = []
        if os.geteuid() == 0:  # root writes anywhere: run as nobody
            as_user = ["setpriv", "--reuid=65534", "--regid=65534", "--clear-groups"]
        env = dict(os.environ, ISOHEX_TEST_CRASH="load")
        for args in (["mesh", self.scan, "-o", out, "-q"], ["quality", self.sample_vtu, "--report", out[:-4] + ".json"],
                     ["smooth", self.sample_vtu, "-o", out, "-q"], ["convert", self.sample_vtu, out]):
            with self.subTest(command=args[0]):
                p = subprocess.run(as_user + [ISOHEX] + args, capture_output=True, text=True, env=env, timeout=300)
                self.assertEqual(p.returncode, 1, p.stderr)
                lines = errors_of(p)
                self.assertEqual(len(lines), 1, p.stderr)
                self.assertIn(f"cannot write in the folder {folder}", lines[0])
                self.assertNotIn("crashed", lines[0])
        self.assertEqual(os.listdir(folder), [])


    # ------------------------------------------------------ label maps

    def test_a_label_map_meshed_as_a_scan_is_refused_not_split_at_otsus_threshold(self):
        # Without --labels a label map was meshed at Otsu's threshold between
        # label numbers: here labels 2 and 3 as one solid, label 1 left out,
        # with only an info line about the threshold.
        labels = np.zeros((24, 24, 24), np.uint8)
        labels[4:12, 4:20, 4:20] = 1
        labels[12:20, 4:20, 4:12] = 2
        labels[12:20, 4:20, 12:20] = 3
        path = os.path.join(self.dir, "three_labels.nii.gz")
        write_nifti(path, labels)
        out = os.path.join(self.dir, "three_labels.vtu")
        p = run(["mesh", path, "-o", out, "-q"], check=False)
        self.assertEqual(p.returncode, 1, p.stderr)
        lines = errors_of(p)
        self.assertEqual(len(lines), 1, p.stderr)
        self.assertIn(f"{path}: this looks like a label map, not a scan", lines[0])
        self.assertIn("4 of them fill regions", lines[0])
        self.assertIn("--labels", lines[0])
        self.assertIn("--iso", lines[0])
        self.assertFalse(os.path.exists(out))
        # A part of a split scan (uncompressed NIfTI streams its window) is checked alike.
        raw = os.path.join(self.dir, "three_labels.nii")
        write_nifti(raw, labels)
        p = run(["mesh", raw, "--part", "1/2", "--size", "2", "-o", out, "-q"], check=False)
        self.assertEqual(p.returncode, 1, p.stderr)
        self.assertIn(f"{raw}: this looks like a label map, not a scan", p.stderr)
        self.assertFalse(os.path.exists(out))
        # What the message offers works: every label as a material, or a threshold chosen on purpose.
        run(["mesh", path, "--labels", "-o", out, "-q"])
        self.assertEqual(sorted(set(material_of(out))), [1, 2, 3])
        run(["mesh", path, "--iso", "1.5", "-o", out, "-q", "--force"])  # labels 2 and 3: 8 x 16 x 16 voxels
        self.assertAlmostEqual(vtk_volumes(read_vtu(out)).sum() / 2048.0, 1.0, delta=0.1)

    def test_one_label_and_integer_ramps_are_still_meshed_at_otsus_threshold(self):
        # A mask (one label and the background) and a scan of whole numbers
        # whose edges are ramps (here the sphere, rounded: values 0-100) have
        # at most two values filling regions; Otsu's threshold is right for them.
        # A CT in whole Hounsfield units may have three (padding outside the
        # field of view, air clipped at -1024, metal clipped at 3071), but its
        # tissue is noise.
        mask = np.zeros((24, 24, 24), np.uint8)
        mask[4:20, 4:20, 4:20] = 7
        rounded = np.round(ramp(self.r - 5)).astype(np.int16)
        n = 32
        grid = np.indices((n, n, n)) - (n - 1) / 2
        radius = np.sqrt((grid ** 2).sum(axis=0))
        ct = np.full((n, n, n), -3024, np.int16)
        ct[radius < 15] = -1024
        body = radius < 11
        ct[body] = np.round(np.random.default_rng(7).normal(40, 20, body.sum()))
        ct[14:19, 14:19, 14:19] = 3071
        for name, image in (("mask", mask), ("rounded_ramp", rounded), ("ct_with_metal", ct)):
            path = os.path.join(self.dir, name + ".nii.gz")
            write_nifti(path, image)
            out = os.path.join(self.dir, name + ".vtu")
            with self.subTest(image=name):
                p = run(["mesh", path, "-o", out, "-q", "--force"], check=False)
                self.assertEqual(p.returncode, 0, p.stderr)
                self.assertGreater(read_vtu(out).GetNumberOfCells(), 0)

    # ------------------------------------------------------------ memory

    def test_a_limit_too_small_to_start_with_is_one_line_saying_so(self):
        # Under these limits isohex-run aborted before its main with
        # "terminate called after throwing an instance of 'std::system_error'":
        # log4cplus, loaded with OpenVDB, starts threads whose stacks (8 MB
        # each, ulimit -s, set here) no longer fit. Now the launcher finds that
        # out first and says so.
        out = os.path.join(self.dir, "too_small_to_start.vtu")

        def stack_8_mb():
            resource.setrlimit(resource.RLIMIT_STACK, (8 << 20, resource.getrlimit(resource.RLIMIT_STACK)[1]))

        for mb in (48, 80):
            p = subprocess.run(["prlimit", f"--as={mb << 20}", ISOHEX, "mesh", self.scan, "-o", out, "-q"],
                               capture_output=True, text=True, timeout=120, preexec_fn=stack_8_mb)
            with self.subTest(limit_mb=mb):
                self.assertEqual(p.returncode, 1, p.stderr)
                self.assertNotIn("terminate called", p.stderr)
                lines = errors_of(p)
                self.assertEqual(len(lines), 1, p.stderr)
                self.assertIn(f"cannot start under the address-space limit of {mb} MB (ulimit -v)", lines[0])
                self.assertIn("stack of ulimit -s, now 8 MB", lines[0])
                self.assertFalse(os.path.exists(out))

    def test_out_of_memory_under_ulimit_v_is_one_line_naming_the_stage(self):
        # under a 300 MB address-space limit an uncaught std::bad_alloc ended
        # isohex with SIGABRT and no message; then "out of memory" named no
        # stage. The limits tried start where isohex itself starts (its
        # libraries load) and rise in small steps until the skull meshes, at
        # --size 2 so that its stages need more than the first limit (read
        # without ITK's plugin, the skull meshed at its default size there).
        def under(mb, args):
            return subprocess.run(["prlimit", f"--as={mb << 20}", ISOHEX] + args, capture_output=True, text=True,
                                  timeout=600)
        start = next(mb for mb in range(160, 4096, 8) if under(mb, ["--version"]).returncode == 0)
        skull = os.path.join(SOURCE, "samples", "skull_ct.nii.gz")
        out = os.path.join(self.dir, "skull_limited.vtu")
        stages = set()
        for mb in range(start + 8, start + 400, 6):
            p = under(mb, ["mesh", skull, "--iso", "2.9", "--size", "2", "-o", out, "-q", "--force"])
            with self.subTest(limit_mb=mb):
                self.assertIn(p.returncode, (0, 1), p.stderr[-500:])
                self.assertNotIn("terminate called", p.stderr)
                if p.returncode == 0:
                    break
                lines = errors_of(p)
                self.assertEqual(len(lines), 1, p.stderr)
                self.assertRegex(lines[0], r"skull_ct.nii.gz: out of memory (in its \w+ stage|before its first stage)")
                self.assertIn(f"limit of {mb} MB", lines[0])
                self.assertFalse(os.path.exists(out))
                stages.add(re.search(r"out of memory (in its \w+ stage|before its first stage)", lines[0]).group(1))
        self.assertEqual(p.returncode, 0, "the skull never meshed under the limits tried")
        self.assertTrue(stages, "no limit ran out of memory")
        print("limits from", start, "MB: out of memory", sorted(stages), "then meshed at", mb, "MB")


if __name__ == "__main__":
    unittest.main(verbosity=2)
