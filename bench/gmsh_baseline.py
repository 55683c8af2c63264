#!/usr/bin/python3
"""The Gmsh baseline: all-hex by subdividing a tetrahedral mesh of the same
closed surface (the seed's "THex", chapter 3.2.2.1).

1. The closed surface, in isohex's world coordinates:
   * scans: VTK's flying edges on the scan at the iso isohex used. The full-
     resolution surface is simplified with vtkQuadricDecimation (volume
     preserving) to triangles about h wide; if Gmsh rejects that surface
     (decimation can make it self-intersect, as on the folded brain) the scan is
     instead resampled to spacing h and contoured again, which cannot
     self-intersect but loses more of the shape. The table says which was used.
   * triangle surfaces (.off): the input surface, decimated the same way, or
     as it is if Gmsh rejects the decimated one.
   An attempt also fails when the hexes' volume differs by more than 2% from the
   volume the surface encloses (Gmsh then filled a cavity: it misread a surface
   that touches itself).
   The surface is split into its closed pieces and their nesting (measure.shells):
   each solid region is a Gmsh volume bounded by its outer piece with its
   cavities as holes; with --keep-largest only the largest region is kept. Pieces
   smaller than h^3 / 10 cannot be meshed at this size and are dropped (counted).
2. gmsh (Debian's CLI) on a .geo script: every piece merged from its own STL
   file, `Surface Loop` per piece, `Volume` per region, then
       Mesh.MeshSizeMax = h; Mesh.SubdivisionAlgorithm = 2 (all hexahedra);
       Mesh.SecondOrderLinear = 1;
   SecondOrderLinear places the nodes the subdivision creates by linear
   interpolation. Without it Gmsh 4.8 tries to put new surface nodes on the
   STL's (non-existent) parametrisation and leaves some at (0,0,0), which
   inverts about 20% of the hexes (checked on the sphere phantom).
3. h is chosen so the hex count is comparable to isohex's: a subdivided
   Delaunay mesh has about K*V/h^3 hexes (K ~ 20, measured on the sphere
   phantom); if the count is off by more than a factor 1.6 it is re-run once
   with h corrected.

Timing: gmsh's wall time, CPU time and peak memory under /usr/bin/time -v (STL
read, tetrahedralisation, subdivision, writing the .vtk). Preparing the surface
with VTK is timed separately and reported beside it.
"""
import os
import subprocess
import time

import vtk

import measure

K_HEX_PER_H3 = 20.4  # hexes per (volume / h^3): sphere phantom, h = 3 mm -> 24,908 hexes for 33,031 mm^3


def gmsh_version():
    try:
        out = subprocess.run(["gmsh", "--version"], capture_output=True, text=True, timeout=30)
        return "gmsh " + (out.stdout + out.stderr).strip().splitlines()[-1]
    except (OSError, subprocess.SubprocessError, IndexError):
        return None


def decimated(poly, h):
    mp = vtk.vtkMassProperties()
    tri = vtk.vtkTriangleFilter()
    tri.SetInputData(poly)
    mp.SetInputConnection(tri.GetOutputPort())
    mp.Update()
    target = max(20.0, 2.31 * mp.GetSurfaceArea() / (h * h))  # equilateral triangles of edge h
    n = poly.GetNumberOfPolys()
    if target >= n:
        return poly
    d = vtk.vtkQuadricDecimation()
    d.SetInputData(poly)
    d.SetTargetReduction(1.0 - target / n)
    d.VolumePreservationOn()
    d.Update()
    out = vtk.vtkPolyData()
    out.DeepCopy(d.GetOutput())
    return out


def regions_of(surface, largest, h, decimate):
    """[(outer poly, [cavity polys])] and the number of pieces dropped as too small."""
    pieces = measure.shells(surface)
    regions = measure.solid_regions(pieces)
    if largest:
        regions = regions[:1]
    tiny = h ** 3 / 10.0
    out, dropped = [], 0
    for outer, cav in regions:
        if pieces[outer]["volume"] < tiny:
            dropped += 1 + len(cav)
            continue
        keep = [k for k in cav if pieces[k]["volume"] >= tiny]
        dropped += len(cav) - len(keep)
        polys = [pieces[outer]["poly"]] + [pieces[k]["poly"] for k in keep]
        if decimate:
            polys = [decimated(p, h) for p in polys]
        out.append((polys[0], polys[1:]))
    return out, dropped


def write_geo(regions, workdir, name, h):
    lines, tag = [], 0
    loops = []
    for r, (outer, cavities) in enumerate(regions):
        tags = []
        for p in [outer] + cavities:
            tag += 1
            stl = f"{name}_piece{tag}.stl"
            measure.write_stl(p, os.path.join(workdir, stl))
            lines.append(f'Merge "{stl}";')
            tags.append(tag)
        loops.append(tags)
    for r, tags in enumerate(loops):
        for t in tags:
            lines.append(f"Surface Loop({t}) = {{{t}}};")
        lines.append(f"Volume({r + 1}) = {{{', '.join(str(t) for t in tags)}}};")
    lines += [f"Mesh.MeshSizeMax = {h:.6g};", "Mesh.SubdivisionAlgorithm = 2;", "Mesh.SecondOrderLinear = 1;"]
    geo = os.path.join(workdir, f"{name}.geo")
    with open(geo, "w") as f:
        f.write("\n".join(lines) + "\n")
    return geo


def _one(source, largest, h, workdir, name, timed_run, threads):
    """source: ('scan', nifti, iso, geom) or ('surface', poly)."""
    attempts = ["decimated", "resampled"] if source[0] == "scan" else ["decimated", "input surface"]
    res = None
    for mode in attempts:
        t = time.perf_counter()
        if source[0] == "surface":
            regions, dropped = regions_of(source[1], largest, h, decimate=(mode == "decimated"))
        else:
            _, nifti, iso, geom = source
            surf = measure.isosurface(nifti, iso, geom["origin"], geom["spacing"], geom["direction"],
                                      inside_below=geom.get("inside_below", False),
                                      resample_to=h if mode == "resampled" else None)
            regions, dropped = regions_of(surf, largest, h, decimate=(mode == "decimated"))
        geo = write_geo(regions, workdir, name, h)
        surface_s = time.perf_counter() - t
        out = os.path.join(workdir, f"{name}.vtk")
        if os.path.exists(out):
            os.remove(out)
        run = timed_run(["gmsh", os.path.basename(geo), "-3", "-nt", str(threads), "-format", "vtk",
                         "-o", os.path.basename(out)], cwd=workdir, log=os.path.join(workdir, f"{name}.gmsh.log"))
        tris = sum(p.GetNumberOfPolys() for o, c in regions for p in [o] + c)
        res = {"h": h, "surface": mode, "surface_triangles": tris, "pieces_dropped": dropped,
               "surface_s": surface_s, "run": run, "mesh": out, "failed_attempts": (res or {}).get("failed_attempts", [])}
        expected = sum(measure.enclosed_volume(o) - sum(measure.enclosed_volume(c) for c in cav) for o, cav in regions)
        if run["rc"] == 0 and os.path.exists(out):
            q = measure.quality(out)
            if abs(q["volume"] - expected) <= 0.02 * expected:
                res["quality"] = q
                return res
            # Gmsh meshed a different region than the surface bounds (a decimated
            # surface that touches itself lets the inside leak into a cavity).
            err = (f"the mesh fills {q['volume']:.6g} but its surface encloses {expected:.6g}; "
                   "Gmsh misread the surface")
        else:
            err = gmsh_error(run["log"])
        res["failed_attempts"] = res["failed_attempts"] + [f"{mode} surface: {err}"]
        res["error"] = "; ".join(res["failed_attempts"])
    return res


def gmsh_error(log):
    try:
        with open(log) as f:
            errs = [ln.strip() for ln in f if ln.startswith("Error")]
        return errs[0] if errs else "gmsh failed"
    except OSError:
        return "gmsh failed"


def run(source, largest, target_hexes, volume, workdir, name, timed_run, threads=2):
    h = (K_HEX_PER_H3 * volume / max(target_hexes, 1)) ** (1.0 / 3.0)
    res = _one(source, largest, h, workdir, name, timed_run, threads)
    if "quality" in res:
        ratio = res["quality"]["hexes"] / target_hexes
        if ratio > 1.6 or ratio < 1 / 1.6:
            h2 = h * ratio ** (1.0 / 3.0)
            res2 = _one(source, largest, h2, workdir, name, timed_run, threads)
            res2["first_try"] = {"h": h, "hexes": res["quality"]["hexes"]}
            if "quality" in res2:
                res = res2
    return res
