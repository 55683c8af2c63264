#!/usr/bin/python3
"""Writes the small synthetic meshes bundled in samples/ (run with Debian's
/usr/bin/python3, which has python3-vtk9 and numpy):

  twisted_bar.vtu  a 24 x 4 x 4 hex bar, 48 x 8 x 8 mm, twisted by 90 degrees
                   about its axis and bent in an arc; two materials (the two
                   halves along the bar), so every element is valid but not a
                   cube, and the report has an interface to show.
"""
import os

import numpy as np
import vtk
from vtk.util import numpy_support as ns

HERE = os.path.dirname(os.path.abspath(__file__))


def twisted_bar(nx=24, ny=4, nz=4, length=48.0, width=8.0):
    i, j, k = np.meshgrid(np.arange(nx + 1), np.arange(ny + 1), np.arange(nz + 1), indexing="ij")
    x = i / nx * length
    y = (j / ny - 0.5) * width
    z = (k / nz - 0.5) * width
    angle = 0.5 * np.pi * x / length          # twist
    yr = y * np.cos(angle) - z * np.sin(angle)
    zr = y * np.sin(angle) + z * np.cos(angle)
    radius = 60.0                              # bend in the x-z plane
    theta = x / radius
    px = (radius + zr) * np.sin(theta)
    pz = (radius + zr) * np.cos(theta) - radius
    pts = np.stack([px, yr, pz], axis=-1)

    def nid(a, b, c):
        return (a * (ny + 1) + b) * (nz + 1) + c

    cells, mats = [], []
    for a in range(nx):
        for b in range(ny):
            for c in range(nz):
                cells.append([nid(a, b, c), nid(a + 1, b, c), nid(a + 1, b + 1, c), nid(a, b + 1, c),
                              nid(a, b, c + 1), nid(a + 1, b, c + 1), nid(a + 1, b + 1, c + 1), nid(a, b + 1, c + 1)])
                mats.append(1 if a < nx // 2 else 2)
    return pts.reshape(-1, 3), np.array(cells), np.array(mats, dtype=np.int32)


def write_vtu(path, pts, cells, mats):
    points = vtk.vtkPoints()
    points.SetDataTypeToDouble()
    points.SetData(ns.numpy_to_vtk(pts.copy(), deep=True))
    grid = vtk.vtkUnstructuredGrid()
    grid.SetPoints(points)
    for c in cells:
        ids = vtk.vtkIdList()
        for v in c:
            ids.InsertNextId(int(v))
        grid.InsertNextCell(vtk.VTK_HEXAHEDRON, ids)
    m = ns.numpy_to_vtk(mats, deep=True)
    m.SetName("material")
    grid.GetCellData().AddArray(m)
    w = vtk.vtkXMLUnstructuredGridWriter()
    w.SetFileName(path)
    w.SetInputData(grid)
    w.SetDataModeToBinary()
    if w.Write() != 1:
        raise SystemExit(f"could not write {path}")


if __name__ == "__main__":
    out = os.path.join(HERE, "twisted_bar.vtu")
    write_vtu(out, *twisted_bar())
    print("wrote", out)
