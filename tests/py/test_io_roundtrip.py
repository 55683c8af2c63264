"""Mesh files written by isohex, read back by independent tools.

The test-mesh helper (tests/tools/make_test_meshes.cpp, env ISOHEX_TEST_MESHES)
writes a two-material block whose hexes are renumbered by the 24 cube
rotations, so every local face of a hex meets every side of the block, in all
formats plus the exact mesh as JSON. Then:

- meshio reads .vtu, .msh, .inp and .mesh (and .exo when netCDF4 is present):
  same nodes in the same order, same hexes in VTK order, same materials;
- VTK's Exodus reader reads .exo: blocks per material, element id map, side
  sets turned into quads by VTK's own Exodus side table, node sets;
- every named surface (Gmsh physical surface, MEDIT referenced quads, Abaqus
  *SURFACE decoded with the C3D8 face table of the Abaqus/CalculiX manuals,
  Exodus side set) holds exactly the expected boundary/interface faces, seen
  from the `inside` material and, where quads carry an orientation, pointing
  out of it;
- Debian's gmsh checks the .msh (`gmsh -check`) and, through its Python API,
  finds the physical groups and only positive hexes;
- CalculiX solves the .inp of a 4x4x4 block of 1 mm hexes twice: a uniaxial
  compression (reaction = E * strain * area, negative) and a uniform pressure
  on the written *SURFACEs (uniform contraction, which only happens when every
  face number S1..S6 is right);
- `isohex convert` (when the CLI has it) turns .msh into .vtu losslessly.

Exits non-zero on any failure and prints what it checked.
"""
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile

import numpy as np

import meshio

PASSED = []
FAILED = []


def check(cond, what):
    (PASSED if cond else FAILED).append(what)
    print(("ok    " if cond else "FAIL  ") + what, flush=True)
    return cond


def find_helper():
    helper = os.environ.get("ISOHEX_TEST_MESHES", "")
    if helper and os.path.exists(helper):
        return helper
    isohex = os.environ.get("ISOHEX", "")
    if isohex:
        guess = os.path.join(os.path.dirname(os.path.dirname(isohex)), "tests", "make_test_meshes")
        if os.path.exists(guess):
            return guess
    sys.exit("make_test_meshes not found: set ISOHEX_TEST_MESHES (ctest does)")


HELPER = find_helper()

# VTK_HEXAHEDRON faces as node sets (orientation is checked separately).
VTK_FACES = [(0, 4, 7, 3), (1, 2, 6, 5), (0, 1, 5, 4), (3, 7, 6, 2), (0, 3, 2, 1), (4, 5, 6, 7)]
# Abaqus / CalculiX C3D8 faces, 1-based corners as in the manuals.
ABAQUS_FACES = {1: (1, 2, 3, 4), 2: (5, 8, 7, 6), 3: (1, 5, 6, 2), 4: (2, 6, 7, 3), 5: (3, 7, 8, 4), 6: (4, 8, 5, 1)}
SURFACE_NAMES = {(1, -1): "boundary_m1", (2, -1): "outer_skin_of_material_two", (1, 2): "interface_m1_m2"}


def make_meshes(folder, size=None):
    args = [HELPER, folder] + ([str(s) for s in size] if size else [])
    proc = subprocess.run(args, capture_output=True, text=True)
    if proc.returncode != 0:
        sys.exit(f"{' '.join(args)} failed: {proc.stdout}{proc.stderr}")
    with open(os.path.join(folder, "block.truth.json")) as f:
        t = json.load(f)
    return {
        "nodes": np.array(t["nodes"], dtype=float),
        "hexes": np.array(t["hexes"], dtype=np.int64),
        "material": np.array(t["material"], dtype=np.int64),
        "node_class": np.array(t["node_class"]),
        "node_surface": np.array(t["node_surface"]),
        "size": t["size"],
        "h": t["h"],
    }


def expected_surfaces(truth):
    """{surface name: {frozenset(face nodes): (inside hex, VTK local face)}} from the hexes alone."""
    owners = {}
    for h, hexa in enumerate(truth["hexes"]):
        for f, face in enumerate(VTK_FACES):
            owners.setdefault(frozenset(int(hexa[i]) for i in face), []).append((h, f))
    out = {name: {} for name in SURFACE_NAMES.values()}
    mat = truth["material"]
    for key, hs in owners.items():
        if len(hs) == 1:
            out[SURFACE_NAMES[(int(mat[hs[0][0]]), -1)]][key] = hs[0]
        elif mat[hs[0][0]] != mat[hs[1][0]]:
            inside = min(hs, key=lambda hf: mat[hf[0]])
            out[SURFACE_NAMES[(1, 2)]][key] = inside
    return out


def hex_cells(mesh):
    blocks = [c.data for c in mesh.cells if c.type == "hexahedron"]
    return np.concatenate(blocks) if blocks else np.zeros((0, 8), dtype=np.int64)


def check_nodes_and_hexes(fmt, points, hexes, truth, same_hex_order):
    check(points.shape == truth["nodes"].shape, f"{fmt}: {len(points)} nodes as written")
    if points.shape == truth["nodes"].shape:
        err = np.abs(points - truth["nodes"]).max()
        check(err <= 1e-12, f"{fmt}: node coordinates identical, in index order (max diff {err:.1e})")
    check(hexes.shape == truth["hexes"].shape, f"{fmt}: {len(hexes)} hexahedra as written")
    if hexes.shape != truth["hexes"].shape:
        return None
    if same_hex_order:
        check(np.array_equal(hexes, truth["hexes"]), f"{fmt}: hex connectivity identical (VTK order, same hex order)")
        return np.arange(len(hexes))
    # Formats grouped by material: match each hex by its exact corner list.
    index = {tuple(map(int, h)): i for i, h in enumerate(truth["hexes"])}
    order = [index.get(tuple(map(int, h)), -1) for h in hexes]
    check(sorted(order) == list(range(len(hexes))), f"{fmt}: hex connectivity identical (VTK order), grouped by material")
    return np.array(order)


def quad_orientation_ok(points, quad, hex_nodes):
    p = points[list(quad)]
    normal = np.cross(p[2] - p[0], p[3] - p[1])
    outward = p.mean(axis=0) - points[list(hex_nodes)].mean(axis=0)
    return float(np.dot(normal, outward)) > 0


def check_quads(fmt, name, quads, expected, truth, oriented=True):
    got = {}
    for q in quads:
        got.setdefault(frozenset(int(v) for v in q), []).append(q)
    check(len(quads) == len(expected) and set(got) == set(expected),
          f"{fmt}: surface {name} holds exactly its {len(expected)} faces")
    if oriented and set(got) == set(expected):
        bad = sum(1 for key, qs in got.items() for q in qs
                  if not quad_orientation_ok(truth["nodes"], q, truth["hexes"][expected[key][0]]))
        check(bad == 0, f"{fmt}: surface {name} quads point out of the inside material ({bad} wrong)")


def test_meshio_formats(folder, truth, surfaces):
    # VTU
    m = meshio.read(os.path.join(folder, "block.vtu"))
    order = check_nodes_and_hexes("vtu", m.points, hex_cells(m), truth, True)
    if order is not None:
        mat = m.cell_data.get("material", [None])[0]
        check(mat is not None and np.array_equal(mat, truth["material"]), "vtu: cell data 'material' matches")
        sj = m.cell_data.get("scaled_jacobian", [None])[0]
        check(sj is not None and np.allclose(sj, 1.0), "vtu: cell data 'scaled_jacobian' present, 1 for the cubes")
    for name in ("node_class", "node_surface"):
        arr = m.point_data.get(name)
        check(arr is not None and np.array_equal(arr, truth[name]), f"vtu: point data '{name}' matches")

    # MSH 4.1
    path = os.path.join(folder, "block.msh")
    with open(path) as f:
        check(f.read(20).startswith("$MeshFormat\n4.1 0 8"), "msh: ASCII MSH 4.1 header")
    m = meshio.read(path)
    order = check_nodes_and_hexes("msh", m.points, hex_cells(m), truth, False)
    phys = {n: int(v[0]) for n, v in m.field_data.items() if len(v) == 2}
    dims = {n: int(v[1]) for n, v in m.field_data.items() if len(v) == 2}
    check(dims.get("material_1") == 3 and dims.get("material_2") == 3, "msh: volume physical groups material_1, material_2")
    check(all(dims.get(n) == 2 for n in SURFACE_NAMES.values()), "msh: a physical surface per boundary/interface surface")
    if order is not None:
        mats = np.concatenate([d for c, d in zip(m.cells, m.cell_data["gmsh:physical"]) if c.type == "hexahedron"])
        want = np.array([phys[f"material_{truth['material'][i]}"] for i in order])
        check(np.array_equal(mats, want), "msh: each hex in its material's physical group")
    for name, expected in surfaces.items():
        quads = [q for c, d in zip(m.cells, m.cell_data["gmsh:physical"]) if c.type == "quad"
                 for q, tag in zip(c.data, d) if tag == phys.get(name)]
        check_quads("msh", name, quads, expected, truth)

    # Abaqus
    m = meshio.read(os.path.join(folder, "block.inp"))
    order = check_nodes_and_hexes("inp", m.points, hex_cells(m), truth, False)
    check_abaqus_surfaces(os.path.join(folder, "block.inp"), truth, surfaces)

    # MEDIT
    m = meshio.read(os.path.join(folder, "block.mesh"))
    order = check_nodes_and_hexes("medit", m.points, hex_cells(m), truth, True)
    refs = dict(zip([c.type for c in m.cells], m.cell_data["medit:ref"]))
    if order is not None:
        check(np.array_equal(refs["hexahedron"], truth["material"]), "medit: hexahedron reference = material")
    want_ref = np.where(truth["node_class"] == 1, truth["node_surface"] + 1, 0)
    check(np.array_equal(m.point_data["medit:ref"], want_ref), "medit: vertex reference = surface id + 1 or 0")
    quads = [c.data for c in m.cells if c.type == "quad"][0]
    names = list(SURFACE_NAMES.values())
    # Surfaces are numbered in (inside, outside) order: boundary_m1, interface_m1_m2, outer skin.
    numbering = {"boundary_m1": 1, "interface_m1_m2": 2, "outer_skin_of_material_two": 3}
    for name in names:
        sel = [q for q, r in zip(quads, refs["quad"]) if r == numbering[name]]
        check_quads("medit", name, sel, surfaces[name], truth)


def parse_abaqus(path):
    """Element materials, ELSETs and SURFACEs of the mesh .inp, read independently of isohex."""
    elsets, surfaces, elem_mat, elems = {}, {}, {}, {}
    section, name = None, None
    with open(path) as f:
        for raw in f:
            line = raw.strip()
            if not line or line.startswith("**"):
                continue
            if line.startswith("*"):
                opts = dict((kv.split("=", 1) + [""])[:2] for kv in (s.strip() for s in line.split(",")[1:]))
                opts = {k.upper(): v for k, v in opts.items()}
                key = line.split(",")[0].upper()
                section = key
                if key == "*ELEMENT":
                    check(opts.get("TYPE") == "C3D8", f"inp: *ELEMENT type C3D8 ({line})")
                    name = opts["ELSET"]
                elif key == "*ELSET":
                    name = opts["ELSET"]
                    elsets[name] = []
                elif key == "*SURFACE":
                    check(opts.get("TYPE") == "ELEMENT", f"inp: *SURFACE is element-based ({opts.get('NAME')})")
                    name = opts["NAME"]
                    surfaces[name] = []
                continue
            values = [v.strip() for v in line.split(",") if v.strip()]
            if section == "*ELEMENT":
                elems[int(values[0])] = [int(v) - 1 for v in values[1:]]
                elem_mat[int(values[0])] = name
            elif section == "*ELSET":
                elsets[name] += [int(v) for v in values]
            elif section == "*SURFACE":
                surfaces[name].append((values[0], values[1]))
    return elems, elem_mat, elsets, surfaces


def check_abaqus_surfaces(path, truth, surfaces):
    elems, elem_mat, elsets, surfs = parse_abaqus(path)
    check(all(elem_mat[h + 1] == f"MAT_{truth['material'][h]}" for h in range(len(truth["hexes"]))),
          "inp: every element in ELSET MAT_<material>")
    check(all(elems[h + 1] == list(truth["hexes"][h]) for h in range(len(truth["hexes"]))),
          "inp: element h+1 has the corners of hex h (C3D8 order = VTK order)")
    for name, expected in surfaces.items():
        got = {}
        wrong_side = 0
        for elset, side in surfs.get(name, []):
            face = ABAQUS_FACES[int(side.upper().lstrip("S"))]
            for e in elsets[elset]:
                key = frozenset(elems[e][i - 1] for i in face)
                got[key] = got.get(key, 0) + 1
                if key in expected and expected[key][0] != e - 1:
                    wrong_side += 1
        check(sorted(got.values()) == [1] * len(expected) and set(got) == set(expected),
              f"inp: *SURFACE {name} (decoded with the manual's S1..S6) holds exactly its {len(expected)} faces")
        check(wrong_side == 0, f"inp: *SURFACE {name} faces belong to the inside material's elements")


def test_exodus(folder, truth, surfaces):
    path = os.path.join(folder, "block.exo")
    try:
        import netCDF4  # noqa: F401  (meshio's Exodus reader needs it)
        m = meshio.read(path)
        check_nodes_and_hexes("exodus/meshio", m.points, hex_cells(m), truth, False)
    except ImportError:
        print("note  exodus: python3-netcdf4 not installed, meshio cannot read Exodus; using VTK's reader")

    from vtkmodules.vtkIOExodus import vtkExodusIIReader
    from vtkmodules.vtkCommonDataModel import vtkCompositeDataSet
    from vtkmodules.util.numpy_support import vtk_to_numpy

    r = vtkExodusIIReader()
    r.SetFileName(path)
    r.UpdateInformation()
    blocks = {r.GetObjectName(r.ELEM_BLOCK, i): r.GetObjectId(r.ELEM_BLOCK, i)
              for i in range(r.GetNumberOfObjects(r.ELEM_BLOCK))}
    check(blocks == {"material_1": 1, "material_2": 2}, f"exodus: one element block per material, id = material ({blocks})")
    for kind, label in ((r.SIDE_SET, "side sets"), (r.NODE_SET, "node sets")):
        names = sorted(r.GetObjectName(kind, i) for i in range(r.GetNumberOfObjects(kind)))
        check(names == sorted(SURFACE_NAMES.values()), f"exodus: {label} named after the surfaces")
        for i in range(r.GetNumberOfObjects(kind)):
            r.SetObjectStatus(kind, i, 1)
    r.GenerateGlobalElementIdArrayOn()
    r.GenerateGlobalNodeIdArrayOn()
    r.Update()
    out = r.GetOutput()

    def children(block_index):
        b = out.GetBlock(block_index)
        return {b.GetMetaData(j).Get(vtkCompositeDataSet.NAME()): b.GetBlock(j) for j in range(b.GetNumberOfBlocks())}

    def cells_of(grid):
        gid = vtk_to_numpy(grid.GetPointData().GetArray("GlobalNodeId")) - 1
        cells = []
        for c in range(grid.GetNumberOfCells()):
            ids = grid.GetCell(c).GetPointIds()
            cells.append([int(gid[ids.GetId(k)]) for k in range(ids.GetNumberOfIds())])
        return cells

    nodes_ok, hexes_ok, n_hex = True, True, 0
    for name, grid in children(0).items():
        gid = vtk_to_numpy(grid.GetPointData().GetArray("GlobalNodeId")) - 1
        pts = vtk_to_numpy(grid.GetPoints().GetData())
        nodes_ok &= bool(np.abs(pts - truth["nodes"][gid]).max() <= 1e-12)
        eid = vtk_to_numpy(grid.GetCellData().GetArray("GlobalElementId")) - 1
        for c, cell in zip(eid, cells_of(grid)):
            hexes_ok &= cell == list(truth["hexes"][c]) and name == f"material_{truth['material'][c]}"
            n_hex += 1
    check(nodes_ok, "exodus: node coordinates identical (by global node id)")
    check(hexes_ok and n_hex == len(truth["hexes"]),
          "exodus: element id map = hex index + 1, HEX8 corners in VTK order, block = material")

    for name, grid in children(4).items():
        quads = cells_of(grid)
        check_quads("exodus", name, quads, surfaces[name], truth)
        # VTK reports the side's element by its global id - 1, i.e. (through the
        # element id map isohex writes) by its hex index.
        src = vtk_to_numpy(grid.GetCellData().GetArray("SourceElementId"))
        inside = all(int(e) == surfaces[name][frozenset(q)][0]
                     for e, q in zip(src, quads) if frozenset(q) in surfaces[name])
        check(inside, f"exodus: side set {name} sides belong to the inside material's elements")
    for name, grid in children(7).items():
        gid = set(int(g) - 1 for g in vtk_to_numpy(grid.GetPointData().GetArray("GlobalNodeId")))
        want = set().union(*surfaces[name].keys())
        check(gid == want, f"exodus: node set {name} = the nodes of its faces ({len(want)})")


def test_gmsh(folder, truth):
    path = os.path.join(folder, "block.msh")
    gmsh_exe = shutil.which("gmsh")
    if check(gmsh_exe is not None, "gmsh: Debian's gmsh executable found"):
        proc = subprocess.run([gmsh_exe, path, "-check"], capture_output=True, text=True, timeout=120)
        log = proc.stdout + proc.stderr
        check(proc.returncode == 0, "gmsh -check: exit status 0")
        check(not re.search(r"^(Error|Warning)", log, re.M), "gmsh -check: no errors or warnings")
        n = len(truth["hexes"]) + sum(len(s) for s in expected_surfaces(truth).values())
        check(f"{len(truth['nodes'])} nodes" in log and f"{n} elements" in log,
              f"gmsh -check: reads {len(truth['nodes'])} nodes and {n} elements")
    try:
        import gmsh
    except ImportError:
        print("note  python3-gmsh not importable; skipped the Gmsh API checks")
        return
    gmsh.initialize(readConfigFiles=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.open(path)
        groups = {gmsh.model.getPhysicalName(d, t): (d, t) for d, t in gmsh.model.getPhysicalGroups()}
        check({"material_1", "material_2"} <= set(groups) and set(SURFACE_NAMES.values()) <= set(groups),
              "gmsh API: physical groups for both materials and all three surfaces")
        types, tags, _ = gmsh.model.mesh.getElements(3)
        hex_tags = [t for ty, ts in zip(types, tags) if ty == 5 for t in ts]
        check(list(types) == [5] * len(types) and len(hex_tags) == len(truth["hexes"]),
              "gmsh API: volumes hold only 8-node hexahedra (type 5), all of them")
        # Jacobian determinants at the 8 corners of Gmsh's reference hex [-1,1]^3.
        corners = [c for z in (-1, 1) for y in (-1, 1) for x in (-1, 1) for c in (x, y, z)]
        _, dets, _ = gmsh.model.mesh.getJacobians(5, corners)
        check(len(dets) == 8 * len(hex_tags) and min(dets) > 0,
              f"gmsh API: every hex corner has a positive Jacobian in Gmsh's own evaluation (min {min(dets):.3g})")
    finally:
        gmsh.finalize()


def write_nset(name, ids):
    lines = [f"*NSET, NSET={name}"]
    for k in range(0, len(ids), 8):
        lines.append(", ".join(str(i + 1) for i in ids[k:k + 8]))
    return "\n".join(lines) + "\n"


def run_ccx(folder, job):
    ccx = shutil.which("ccx")
    if not check(ccx is not None, "calculix: ccx found"):
        return None
    proc = subprocess.run([ccx, "-i", job], cwd=folder, capture_output=True, text=True, timeout=600)
    log = proc.stdout + proc.stderr
    ok = check(proc.returncode == 0 and "*ERROR" not in log and "Job finished" in log,
               f"calculix: job {job} ran to the end without *ERROR")
    if not ok:
        print(log[-3000:])
        return None
    with open(os.path.join(folder, job + ".dat")) as f:
        return f.read()


def compression_deck(include, pos, o, side, strain, materials, stresses):
    """A CalculiX deck that includes the mesh `include` (node positions `pos`,
    the block's corner at (o, o, o)) and compresses it by `strain` in z:
    bottom fixed in z, two corner nodes holding it in x and y."""
    def where(sel):
        return [int(i) for i in np.where(sel)[0]]
    # No *HEADING here: the included mesh has one and CalculiX allows only one per deck.
    return ("** isohex io test: uniaxial compression of " + include + "\n*INCLUDE, INPUT=" + include + "\n" +
            materials + write_nset("BOTTOM", where(np.abs(pos[:, 2] - o) < 1e-9)) +
            write_nset("TOP", where(np.abs(pos[:, 2] - side - o) < 1e-9)) +
            write_nset("PA", where(np.all(np.abs(pos - [o, o, o]) < 1e-9, axis=1))) +
            write_nset("PB", where(np.all(np.abs(pos - [side + o, o, o]) < 1e-9, axis=1))) +
            "*BOUNDARY\nBOTTOM, 3, 3, 0.\nPA, 1, 2, 0.\nPB, 2, 2, 0.\n"
            "*STEP\n*STATIC\n*BOUNDARY\nTOP, 3, 3, %g\n" % (strain * side) +
            "*NODE PRINT, NSET=TOP, TOTALS=ONLY\nRF\n" + ("*EL PRINT, ELSET=MAT_1\nS\n" if stresses else "") +
            "*END STEP\n")


def top_reaction(dat):
    """The z reaction force summed over the TOP node set in a CalculiX .dat, or None."""
    m = re.search(r"total force \(fx,fy,fz\) for set TOP.*?\n\s*\n\s*(\S+)\s+(\S+)\s+(\S+)", dat, re.S)
    return float(m.group(3)) if m else None


def test_calculix():
    folder = tempfile.mkdtemp(prefix="isohex_ccx_")
    truth = make_meshes(folder, [4, 4, 4, 1.0])
    x = truth["nodes"]
    side = 4.0
    E, nu = 1000.0, 0.3

    def at(px, py, pz):
        return [int(i) for i in np.where(np.all(np.abs(x - [px, py, pz]) < 1e-9, axis=1))[0]]

    materials = ("*MATERIAL, NAME=SOFT\n*ELASTIC\n%g, %g\n" % (E, nu) +
                 "*SOLID SECTION, ELSET=MAT_1, MATERIAL=SOFT\n*SOLID SECTION, ELSET=MAT_2, MATERIAL=SOFT\n")

    # 1) Uniaxial compression: bottom fixed in z, top pushed down by 0.25% strain.
    strain = -0.0025
    with open(os.path.join(folder, "compress.inp"), "w") as f:
        f.write(compression_deck("block.inp", x, 0.0, side, strain, materials, stresses=True))
    dat = run_ccx(folder, "compress")
    if dat is not None:
        fz = top_reaction(dat)
        expected = E * strain * side * side  # -40 N
        if check(fz is not None, "calculix compression: total reaction force at the top face printed"):
            check(fz < 0, f"calculix compression: reaction force is compressive (Fz = {fz:.4g} N)")
            check(abs(fz - expected) <= 0.01 * abs(expected),
                  f"calculix compression: |Fz| = E*strain*area = {abs(expected):.4g} N within 1% (got {fz:.6g})")
        stresses = [float(v.split()[4]) for v in re.findall(r"^\s+\d+\s+\d+(?:\s+\S+){6}\s*$", dat, re.M)]
        check(len(stresses) > 0 and all(abs(s - E * strain) < 1e-6 * E for s in stresses),
              f"calculix compression: sigma_zz = E*strain = {E * strain:g} MPa at every integration point")

    # 2) Pressure p on the written exterior *SURFACEs: exact answer is uniform contraction.
    p = 1.0
    eps = -p * (1 - 2 * nu) / E
    deck = ("** isohex io test: pressure on the written surfaces\n*INCLUDE, INPUT=block.inp\n" + materials +
            write_nset("PA", at(0, 0, 0)) + write_nset("PB", at(side, 0, 0)) + write_nset("PC", at(0, side, 0)) +
            write_nset("EVERY", list(range(len(x)))) +
            "*BOUNDARY\nPA, 1, 3, 0.\nPB, 2, 3, 0.\nPC, 3, 3, 0.\n"
            "*STEP\n*STATIC\n*DSLOAD\nboundary_m1, P, %g\nouter_skin_of_material_two, P, %g\n" % (p, p) +
            "*NODE PRINT, NSET=EVERY\nU\n*END STEP\n")
    with open(os.path.join(folder, "pressure.inp"), "w") as f:
        f.write(deck)
    dat = run_ccx(folder, "pressure")
    if dat is not None:
        rows = re.findall(r"^\s+(\d+)\s+(\S+)\s+(\S+)\s+(\S+)\s*$", dat, re.M)
        u = {int(n) - 1: np.array([float(a), float(b), float(c)]) for n, a, b, c in rows}
        check(len(u) == len(x), f"calculix pressure: displacements of all {len(x)} nodes printed")
        err = max((np.abs(u[i] - eps * x[i]).max() for i in u), default=1.0)
        check(err < 1e-6 * side,
              f"calculix pressure: u = {eps:g} * x at every node (max error {err:.2e} mm): "
              "every S1..S6 face of the *SURFACEs is the right one")

    # 3) Coordinates near zero. The shortest exact text of -1.813617615035761e-05
    #    is 22 characters and CalculiX stops on a field longer than 20
    #    ("*ERROR reading *NODE"): the block shifted by that much, through
    #    `isohex convert`, must read and give the same reaction force.
    isohex = os.environ.get("ISOHEX", "")
    if check(bool(isohex) and os.path.exists(isohex), "calculix near-zero coordinates: ISOHEX set"):
        shift = -1.813617615035761e-05
        m = meshio.read(os.path.join(folder, "block.vtu"))
        m.points = m.points + shift
        meshio.write(os.path.join(folder, "shifted.vtu"), m)
        proc = subprocess.run([isohex, "convert", os.path.join(folder, "shifted.vtu"),
                               os.path.join(folder, "shifted.inp")], capture_output=True, text=True)
        check(proc.returncode == 0, f"calculix near-zero coordinates: isohex convert to .inp ({proc.stderr.strip()})")
        with open(os.path.join(folder, "shifted.inp")) as f:
            text = f.read()
        node_lines = text.split("*NODE\n")[1].split("*")[0].strip().splitlines()
        longest = max(len(field.strip()) for line in node_lines for field in line.split(","))
        check(longest <= 20, f"calculix near-zero coordinates: every *NODE field at most 20 characters ({longest})")
        with open(os.path.join(folder, "shifted_run.inp"), "w") as f:
            f.write(compression_deck("shifted.inp", x + shift, shift, side, strain, materials, stresses=False))
        dat = run_ccx(folder, "shifted_run")
        if dat is not None:
            fz = top_reaction(dat)
            expected = E * strain * side * side
            check(fz is not None and abs(fz - expected) <= 0.01 * abs(expected),
                  f"calculix near-zero coordinates: reaction force {expected:.4g} N within 1%")
    shutil.rmtree(folder, ignore_errors=True)


def test_convert_cli(folder, truth):
    isohex = os.environ.get("ISOHEX", "")
    if not isohex or not os.path.exists(isohex):
        print("note  ISOHEX not set; skipped isohex convert")
        return
    help_ = subprocess.run([isohex, "convert", "--help"], capture_output=True, text=True)
    if help_.returncode != 0:
        print("note  this isohex has no convert command; skipped")
        return
    src, dst = os.path.join(folder, "block.msh"), os.path.join(folder, "converted.vtu")
    proc = subprocess.run([isohex, "convert", src, dst], capture_output=True, text=True)
    check(proc.returncode == 0, "isohex convert .msh -> .vtu: exit status 0")
    if proc.returncode == 0:
        m = meshio.read(dst)
        check_nodes_and_hexes("convert msh->vtu", m.points, hex_cells(m), truth, True)
        check(np.array_equal(m.cell_data["material"][0], truth["material"]), "convert msh->vtu: materials kept")
    again = subprocess.run([isohex, "convert", src, dst], capture_output=True, text=True)
    check(again.returncode != 0 and "exists" in again.stderr and again.stderr.count("\n") == 1,
          "isohex convert refuses to overwrite without --force, with one error line")
    bad = os.path.join(folder, "garbage.vtu")
    with open(bad, "wb") as f:
        f.write(os.urandom(2000))
    proc = subprocess.run([isohex, "convert", bad, os.path.join(folder, "x.msh")], capture_output=True, text=True)
    check(proc.returncode != 0 and bad in proc.stderr and proc.stderr.count("\n") == 1,
          f"isohex convert on a garbage .vtu: one error line naming the file ({proc.stderr.strip()})")


def main():
    folder = tempfile.mkdtemp(prefix="isohex_io_")
    try:
        truth = make_meshes(folder)
        surfaces = expected_surfaces(truth)
        test_meshio_formats(folder, truth, surfaces)
        test_exodus(folder, truth, surfaces)
        test_gmsh(folder, truth)
        test_convert_cli(folder, truth)
        test_calculix()
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    print(f"{len(PASSED)} passed, {len(FAILED)} failed")
    for f in FAILED:
        print("failed: " + f)
    return 1 if FAILED else 0


if __name__ == "__main__":
    sys.exit(main())
