"""VTK helpers shared by the end-to-end tests: read a .vtu and judge it with
VTK's own filters (independent of isohex's quality code)."""
import vtk
from vtk.util import numpy_support as ns


def read_vtu(path):
    r = vtk.vtkXMLUnstructuredGridReader()
    r.SetFileName(str(path))
    r.Update()
    return r.GetOutput()


def vtk_hex_quality(grid_or_path, measure):
    """Per-cell hex quality `measure` (ScaledJacobian, Condition, Volume, ...)
    from vtkMeshQuality, for a grid or a .vtu path."""
    grid = read_vtu(grid_or_path) if isinstance(grid_or_path, (str, bytes)) or hasattr(grid_or_path, "__fspath__") \
        else grid_or_path
    q = vtk.vtkMeshQuality()
    q.SetInputData(grid)
    getattr(q, "SetHexQualityMeasureTo" + measure)()
    q.Update()
    return ns.vtk_to_numpy(q.GetOutput().GetCellData().GetArray("Quality")).astype(float)


def vtk_sj(grid_or_path):
    """Per-cell scaled Jacobian from vtkMeshQuality (a grid, or a .vtu path)."""
    return vtk_hex_quality(grid_or_path, "ScaledJacobian")


def vtk_volumes(grid):
    """Per-cell volume from vtkCellSizeFilter."""
    f = vtk.vtkCellSizeFilter()
    f.SetInputData(grid)
    f.ComputeVolumeOn()
    f.Update()
    return ns.vtk_to_numpy(f.GetOutput().GetCellData().GetArray("Volume")).astype(float)
