#!/usr/bin/python3
"""Independent measurements for the benchmark, with VTK only (Debian's python3-vtk9).

Nothing here uses isohex's own quality or fidelity code:

* quality(path): hexahedra of a .vtu (isohex) or legacy .vtk (gmsh) file,
  scaled Jacobian and volume from vtkMeshQuality.
* isosurface(...): the scan's isosurface by VTK's flying edges, in the world
  coordinates isohex uses (ITK physical space: origin + direction * spacing * index),
  optionally resampled to a coarser spacing (for the gmsh baseline) and reduced
  to its largest connected piece (for --keep-largest inputs).
* boundary_distance(grid, surface): distance of the mesh's boundary nodes to a
  closed surface (vtkImplicitPolyDataDistance).
* four_hex_nodes(grid): interior nodes in only four hexes (with four edges: a
  tetrahedral star, what pillowing makes of a boundary node that was the
  corner of a single hex) and the scaled Jacobian of the hexes at them
  against the rest.

Command line (for a quick look at one file):
  measure.py quality MESH.vtu|MESH.vtk
  measure.py four-hex-nodes MESH.vtu|MESH.vtk
"""
import json
import sys

import numpy as np
import vtk
from vtk.util import numpy_support as ns


def read_hex_grid(path):
    """The hexahedra of a mesh file as a vtkUnstructuredGrid (other cells dropped)."""
    if path.endswith(".vtu"):
        r = vtk.vtkXMLUnstructuredGridReader()
    elif path.endswith(".vtk"):
        r = vtk.vtkUnstructuredGridReader()
    else:
        raise ValueError(f"{path}: expected .vtu or .vtk")
    r.SetFileName(path)
    r.Update()
    g = r.GetOutput()
    types = ns.vtk_to_numpy(g.GetCellTypesArray())
    if np.all(types == vtk.VTK_HEXAHEDRON):
        return g
    ids = vtk.vtkIdTypeArray()
    ids.SetNumberOfComponents(1)
    for i in np.nonzero(types == vtk.VTK_HEXAHEDRON)[0]:
        ids.InsertNextValue(int(i))
    sel_node = vtk.vtkSelectionNode()
    sel_node.SetFieldType(vtk.vtkSelectionNode.CELL)
    sel_node.SetContentType(vtk.vtkSelectionNode.INDICES)
    sel_node.SetSelectionList(ids)
    sel = vtk.vtkSelection()
    sel.AddNode(sel_node)
    ex = vtk.vtkExtractSelection()
    ex.SetInputData(0, g)
    ex.SetInputData(1, sel)
    ex.Update()
    out = vtk.vtkUnstructuredGrid()
    out.ShallowCopy(ex.GetOutput())
    return out


def _measure(grid, setter):
    q = vtk.vtkMeshQuality()
    q.SetInputData(grid)
    setter(q)
    q.Update()
    return ns.vtk_to_numpy(q.GetOutput().GetCellData().GetArray("Quality")).astype(float)


def hex_volumes(grid):
    """Exact volume of every trilinear hex: 2x2x2 Gauss quadrature of det(J), exact
    because det(J) has degree 2 in each reference coordinate. (vtkMeshQuality's hex
    volume is an approximation that is 5% low on tetrahedra split into hexes.)"""
    pts = ns.vtk_to_numpy(grid.GetPoints().GetData()).astype(float)
    conn = ns.vtk_to_numpy(grid.GetCells().GetConnectivityArray()).reshape(-1, 8)
    ref = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], float)
    gauss = (0.5 - 0.5 / np.sqrt(3.0), 0.5 + 0.5 / np.sqrt(3.0))
    vol = np.zeros(len(conn))
    for start in range(0, len(conn), 500_000):
        x = pts[conn[start:start + 500_000]]  # (n, 8, 3)
        acc = np.zeros(len(x))
        for u in gauss:
            for v in gauss:
                for w in gauss:
                    dn = np.empty((8, 3))
                    for k, (a, b, c) in enumerate(ref):
                        fu, fv, fw = (u if a else 1 - u), (v if b else 1 - v), (w if c else 1 - w)
                        su, sv, sw = (1 if a else -1), (1 if b else -1), (1 if c else -1)
                        dn[k] = (su * fv * fw, fu * sv * fw, fu * fv * sw)
                    acc += np.linalg.det(np.einsum("nki,kj->nij", x, dn)) / 8.0
        vol[start:start + len(x)] = acc
    return vol


def quality(path_or_grid):
    g = read_hex_grid(path_or_grid) if isinstance(path_or_grid, str) else path_or_grid
    sj = _measure(g, lambda q: q.SetHexQualityMeasureToScaledJacobian())
    conn = ns.vtk_to_numpy(g.GetCells().GetConnectivityArray())
    used_nodes = int(np.unique(conn).size)
    return {
        "hexes": int(g.GetNumberOfCells()),
        "nodes": used_nodes,
        "sj_min": float(sj.min()) if sj.size else None,
        "sj_mean": float(sj.mean()) if sj.size else None,
        "below_0_2": int(np.count_nonzero(sj < 0.2)),
        "inverted": int(np.count_nonzero(sj < 0)),
        "volume": float(hex_volumes(g).sum()),
    }


def world_matrix(origin, spacing, direction):
    """4x4 index -> world matrix: origin + direction * diag(spacing) * index."""
    d = np.array(direction, dtype=float).reshape(3, 3)
    m = d @ np.diag(np.array(spacing, dtype=float))
    out = np.eye(4)
    out[:3, :3] = m
    out[:3, 3] = origin
    return out


def isosurface(nifti, iso, origin, spacing, direction, inside_below=False, resample_to=None, labels=None):
    """Closed isosurface (every piece) of a NIfTI scan in isohex's world coordinates.

    resample_to: world spacing (same on every axis) to resample the scan to
    before contouring (a coarser surface); None keeps the voxels.
    labels: for a label map, the selected label ids; the surface is then the
    0.5-isosurface of the indicator of their union (pass iso 0.5)."""
    r = vtk.vtkNIFTIImageReader()
    r.SetFileName(nifti)
    r.Update()
    img = vtk.vtkImageData()
    img.DeepCopy(r.GetOutput())
    arr = ns.vtk_to_numpy(img.GetPointData().GetScalars())
    if r.GetQFac() < 0:
        # With qfac -1 VTK's reader stores the slices in reverse order; put
        # them back in the file's index order, which origin/direction refer to.
        nx, ny, nz = img.GetDimensions()
        arr = arr.reshape(nz, ny, nx)[::-1].reshape(-1)
    arr = np.isin(arr, labels).astype(np.float32) if labels is not None else arr.astype(np.float32)
    if inside_below:
        arr = -arr
        iso = -iso
    # Index space with the true spacing (world = D * that + origin, applied after).
    img.SetSpacing(*spacing)
    img.SetOrigin(0, 0, 0)
    img.GetPointData().SetScalars(ns.numpy_to_vtk(arr, deep=True))
    src = img
    if resample_to:
        rs = vtk.vtkImageResample()
        rs.SetInputData(src)
        for a in range(3):
            rs.SetAxisOutputSpacing(a, float(resample_to))
        rs.SetInterpolationModeToLinear()
        rs.Update()
        src = rs.GetOutput()
    # Pad with the background so the surface is closed where the solid touches the box.
    ext = src.GetExtent()
    pad = vtk.vtkImageConstantPad()
    pad.SetInputData(src)
    pad.SetConstant(float(arr.min()) - 1.0)
    pad.SetOutputWholeExtent(ext[0] - 1, ext[1] + 1, ext[2] - 1, ext[3] + 1, ext[4] - 1, ext[5] + 1)
    fe = vtk.vtkFlyingEdges3D()
    fe.SetInputConnection(pad.GetOutputPort())
    fe.SetValue(0, float(iso))
    fe.ComputeNormalsOff()
    fe.ComputeGradientsOff()
    fe.ComputeScalarsOff()
    fe.Update()
    return transformed(fe.GetOutput(), world_matrix(origin, [1, 1, 1], direction))


def transformed(poly, m):
    t = vtk.vtkTransform()
    t.SetMatrix(np.asarray(m, float).ravel().tolist())
    tf = vtk.vtkTransformPolyDataFilter()
    tf.SetInputData(poly)
    tf.SetTransform(t)
    tf.Update()
    out = vtk.vtkPolyData()
    out.DeepCopy(tf.GetOutput())
    return out


def read_off(path):
    """A triangle surface in OFF format (vertices, then faces 'n i j k ...', fanned into triangles)."""
    with open(path) as fh:
        tokens = []
        for line in fh:
            line = line.split("#", 1)[0].strip()
            if line:
                tokens.extend(line.split())
    if not tokens[0].upper().endswith("OFF"):
        raise ValueError(f"{path}: not an OFF file")
    nv, nf = int(tokens[1]), int(tokens[2])
    pos = 4
    verts = np.array(tokens[pos:pos + 3 * nv], float).reshape(nv, 3)
    pos += 3 * nv
    tris = []
    for _ in range(nf):
        k = int(tokens[pos])
        idx = [int(t) for t in tokens[pos + 1:pos + 1 + k]]
        pos += 1 + k
        tris += [(idx[0], idx[i], idx[i + 1]) for i in range(1, k - 1)]
    pts = vtk.vtkPoints()
    pts.SetData(ns.numpy_to_vtk(verts, deep=True))
    cells = vtk.vtkCellArray()
    flat = np.hstack([np.full((len(tris), 1), 3), np.array(tris)]).astype(np.int64).ravel()
    ids = vtk.vtkIdTypeArray()
    ids.DeepCopy(ns.numpy_to_vtk(flat, deep=True, array_type=vtk.VTK_ID_TYPE))
    cells.SetCells(len(tris), ids)
    poly = vtk.vtkPolyData()
    poly.SetPoints(pts)
    poly.SetPolys(cells)
    return poly


def shells(poly):
    """The connected closed pieces of a surface, with their nesting: list of dicts
    with poly, volume, depth (how many pieces enclose it) and parent (index of the
    innermost enclosing piece or -1). Even depth: outer boundary of a solid region;
    odd depth: a cavity of its parent."""
    cf = vtk.vtkPolyDataConnectivityFilter()
    cf.SetInputData(poly)
    cf.SetExtractionModeToAllRegions()
    cf.ColorRegionsOn()
    cf.Update()
    out = cf.GetOutput()
    n = cf.GetNumberOfExtractedRegions()
    region = ns.vtk_to_numpy(out.GetPointData().GetArray("RegionId"))
    pts = ns.vtk_to_numpy(out.GetPoints().GetData()).astype(float)
    tris = ns.vtk_to_numpy(out.GetPolys().GetConnectivityArray()).reshape(-1, 3)
    tri_region = region[tris[:, 0]]
    pieces = []
    for r in range(n):
        t = tris[tri_region == r]
        if len(t) == 0:
            continue
        used, inv = np.unique(t, return_inverse=True)
        p = vtk.vtkPoints()
        p.SetData(ns.numpy_to_vtk(np.ascontiguousarray(pts[used]), deep=True))
        flat = np.hstack([np.full((len(t), 1), 3), inv.reshape(-1, 3)]).astype(np.int64).ravel()
        ids = vtk.vtkIdTypeArray()
        ids.DeepCopy(ns.numpy_to_vtk(flat, deep=True, array_type=vtk.VTK_ID_TYPE))
        cells = vtk.vtkCellArray()
        cells.SetCells(len(t), ids)
        pd = vtk.vtkPolyData()
        pd.SetPoints(p)
        pd.SetPolys(cells)
        pieces.append({"poly": pd, "volume": enclosed_volume(pd), "probe": pts[used[0]],
                       "bounds": (pts[used].min(0), pts[used].max(0))})
    order = sorted(range(len(pieces)), key=lambda i: -pieces[i]["volume"])
    pieces = [pieces[i] for i in order]
    testers = {}
    for i, pc in enumerate(pieces):
        pc["parent"], pc["depth"] = -1, 0
        best = None
        for j in range(i):  # only larger pieces can enclose it
            lo, hi = pieces[j]["bounds"]
            if np.any(pc["probe"] < lo) or np.any(pc["probe"] > hi):
                continue
            if j not in testers:
                se = vtk.vtkSelectEnclosedPoints()
                se.Initialize(pieces[j]["poly"])
                testers[j] = se
            if testers[j].IsInsideSurface(*pc["probe"]):
                pc["depth"] += 1
                if best is None or pieces[j]["volume"] < pieces[best]["volume"]:
                    best = j
        pc["parent"] = -1 if best is None else best
    for se in testers.values():
        se.Complete()
    return pieces


def solid_regions(pieces):
    """Solid regions as (outer piece index, [cavity piece indices]), largest first."""
    regions = []
    for i, pc in enumerate(pieces):
        if pc["depth"] % 2 == 0:
            cav = [k for k, q in enumerate(pieces) if q["parent"] == i and q["depth"] == pc["depth"] + 1]
            regions.append((i, cav))
    regions.sort(key=lambda r: -(pieces[r[0]]["volume"] - sum(pieces[k]["volume"] for k in r[1])))
    return regions


def merge(polys):
    ap = vtk.vtkAppendPolyData()
    for p in polys:
        ap.AddInputData(p)
    ap.Update()
    out = vtk.vtkPolyData()
    out.DeepCopy(ap.GetOutput())
    return out


def largest_region_surface(poly):
    """The boundary of the largest solid region: its outer piece and its cavities."""
    pieces = shells(poly)
    outer, cav = solid_regions(pieces)[0]
    return merge([pieces[outer]["poly"]] + [pieces[k]["poly"] for k in cav])


def enclosed_volume(poly):
    tri = vtk.vtkTriangleFilter()
    tri.SetInputData(poly)
    mp = vtk.vtkMassProperties()
    mp.SetInputConnection(tri.GetOutputPort())
    mp.Update()
    return float(mp.GetVolume())


def boundary_points(grid):
    """Nodes on the outer boundary of a hex mesh (faces held by one hex)."""
    s = vtk.vtkDataSetSurfaceFilter()
    s.SetInputData(grid)
    s.Update()
    return ns.vtk_to_numpy(s.GetOutput().GetPoints().GetData()).astype(float)


def boundary_distance(grid, surface):
    pts = boundary_points(grid)
    d = vtk.vtkImplicitPolyDataDistance()
    d.SetInput(surface)
    inp = ns.numpy_to_vtk(np.ascontiguousarray(pts), deep=True)
    out = vtk.vtkDoubleArray()
    d.FunctionValue(inp, out)
    dist = np.abs(ns.vtk_to_numpy(out))
    return {"boundary_nodes": int(len(pts)), "mean": float(dist.mean()), "max": float(dist.max())}


def write_stl(poly, path):
    w = vtk.vtkSTLWriter()
    w.SetFileName(path)
    w.SetInputData(poly)
    w.SetFileTypeToBinary()
    w.Write()


def four_hex_nodes(path_or_grid):
    """Interior nodes (on no boundary face) that only four hexes share, and the
    VTK scaled Jacobian of the hexes at such a node against the other hexes.
    A corner of four hexes has four edges; the hexes can all be valid only with
    the node inside the tetrahedron of its four neighbours, and with its four
    edges in the regular tetrahedral directions each of its corners has a
    scaled Jacobian of 4 / (3 sqrt 3) = 0.77."""
    g = read_hex_grid(path_or_grid) if isinstance(path_or_grid, str) else path_or_grid
    sj = _measure(g, lambda q: q.SetHexQualityMeasureToScaledJacobian())
    hexes = ns.vtk_to_numpy(g.GetCells().GetConnectivityArray()).reshape(-1, 8).astype(np.int64)
    n = int(g.GetNumberOfPoints())
    in_hexes = np.bincount(hexes.ravel(), minlength=n)
    faces = np.sort(np.concatenate([hexes[:, list(f)] for f in
                                    ((0, 1, 2, 3), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7))]),
                    axis=1)
    key = ((faces[:, 0] * n + faces[:, 1]) * n + faces[:, 2]) * n + faces[:, 3] if n < 45000 else None
    if key is not None:
        _, inv, count = np.unique(key, return_inverse=True, return_counts=True)
        once = count[inv] == 1
    else:
        _, inv, count = np.unique(faces, axis=0, return_inverse=True, return_counts=True)
        once = count[inv.ravel()] == 1
    on_boundary = np.zeros(n, bool)
    on_boundary[faces[once].ravel()] = True
    star = (in_hexes == 4) & ~on_boundary
    at = star[hexes].any(axis=1)
    return {
        "hexes": int(len(hexes)),
        "four_hex_nodes": int(star.sum()),
        "hexes_at_them": int(at.sum()),
        "sj_mean_at_them": float(sj[at].mean()) if at.any() else None,
        "sj_mean_elsewhere": float(sj[~at].mean()) if (~at).any() else None,
        "sj_mean": float(sj.mean()) if sj.size else None,
    }


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] == "quality":
        print(json.dumps(quality(sys.argv[2]), indent=2))
    elif len(sys.argv) == 3 and sys.argv[1] == "four-hex-nodes":
        print(json.dumps(four_hex_nodes(sys.argv[2]), indent=2))
    else:
        print(__doc__)
        sys.exit(2)
