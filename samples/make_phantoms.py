#!/usr/bin/python3
"""Synthetic phantoms for tests and benchmarks, written as NIfTI with VTK.

  sphere.nii.gz      a ball of radius 20 mm, 1 mm voxels, smooth intensity
                     (100 inside, 0 outside, a linear ramp 2 mm wide): iso 50
  torus.nii.gz       a torus, radii 18 and 7 mm (genus 1): iso 50
  thin_plate.nii.gz  a plate 2.5 mm thick, 40 x 40 mm: iso 50
  two_spheres.nii.gz two balls 1.2 mm apart (almost touching): iso 50
  two_materials.nii.gz  a label map: a ball split into label 1 and label 2,
                     inside a cube of label 3 (three materials, interfaces)

Usage: make_phantoms.py OUT_DIR [--size N] (N voxels per axis, default 64)
"""
import argparse
import os

import numpy as np
import vtk
from vtk.util import numpy_support as ns


def ramp(signed_distance, width=2.0):
    """100 deep inside, 0 outside, linear across the surface: iso 50 is the surface."""
    return np.clip(50.0 - 50.0 * signed_distance / (width / 2), 0.0, 100.0).astype(np.float32)


def write_nifti(path, array, spacing=(1.0, 1.0, 1.0), origin=(0.0, 0.0, 0.0)):
    """array is indexed [x, y, z]."""
    img = vtk.vtkImageData()
    img.SetDimensions(*array.shape)
    img.SetSpacing(*spacing)
    img.SetOrigin(*origin)
    flat = np.ascontiguousarray(array.transpose(2, 1, 0)).ravel()  # VTK wants x fastest
    arr = ns.numpy_to_vtk(flat, deep=True)
    img.GetPointData().SetScalars(arr)
    w = vtk.vtkNIFTIImageWriter()
    w.SetFileName(path)
    w.SetInputData(img)
    w.Write()
    if w.GetErrorCode() != 0:
        raise SystemExit(f"could not write {path}")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("out_dir")
    ap.add_argument("--size", type=int, default=64)
    a = ap.parse_args()
    os.makedirs(a.out_dir, exist_ok=True)
    n = a.size
    c = (n - 1) / 2.0
    x, y, z = np.meshgrid(np.arange(n) - c, np.arange(n) - c, np.arange(n) - c, indexing="ij")
    r = np.sqrt(x * x + y * y + z * z)
    s = n / 64.0  # shapes scale with the grid
    write_nifti(os.path.join(a.out_dir, "sphere.nii.gz"), ramp(r - 20 * s))
    q = np.sqrt(x * x + y * y) - 18 * s
    write_nifti(os.path.join(a.out_dir, "torus.nii.gz"), ramp(np.sqrt(q * q + z * z) - 7 * s))
    plate = np.maximum(np.maximum(np.abs(x) - 20 * s, np.abs(y) - 20 * s), np.abs(z) - 1.25)
    write_nifti(os.path.join(a.out_dir, "thin_plate.nii.gz"), ramp(plate))
    d1 = np.sqrt((x + 10.6 * s) ** 2 + y * y + z * z) - 10 * s
    d2 = np.sqrt((x - 10.6 * s) ** 2 + y * y + z * z) - 10 * s
    write_nifti(os.path.join(a.out_dir, "two_spheres.nii.gz"), ramp(np.minimum(d1, d2)))
    labels = np.zeros((n, n, n), dtype=np.uint8)
    cube = np.maximum(np.maximum(np.abs(x), np.abs(y)), np.abs(z)) <= 26 * s
    labels[cube] = 3
    ball = r <= 16 * s
    labels[ball & (x < 0)] = 1
    labels[ball & (x >= 0)] = 2
    write_nifti(os.path.join(a.out_dir, "two_materials.nii.gz"), labels)
    print("wrote phantoms to", a.out_dir)


if __name__ == "__main__":
    main()
