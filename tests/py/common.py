"""Shared helpers for the Python end-to-end tests (run by ctest with Debian's /usr/bin/python3)."""
import atexit
import os
import shutil
import subprocess
import sys
import tempfile

ISOHEX = os.environ.get("ISOHEX", "isohex")
SHARED_DATA = os.environ.get("ISOHEX_SHARED_DATA", "")
SOURCE = os.environ.get("ISOHEX_SOURCE", os.path.dirname(os.path.dirname(os.path.dirname(__file__))))


def run(args, check=True, timeout=600, **kw):
    """Runs the isohex binary; returns the CompletedProcess (text mode). A hang
    fails the test (subprocess.TimeoutExpired) instead of stalling the suite."""
    proc = subprocess.run([ISOHEX] + [str(a) for a in args], capture_output=True, text=True, timeout=timeout, **kw)
    if check and proc.returncode != 0:
        sys.stderr.write(proc.stdout + proc.stderr)
        raise AssertionError(f"isohex {' '.join(map(str, args))} exited {proc.returncode}")
    return proc


def workdir(name):
    """A new temporary folder, removed when the test process exits (unless
    ISOHEX_KEEP_TEST_FILES is set, to look at a failure's meshes): the suite writes
    gigabytes of meshes in all, more than a CI machine's disk may have free."""
    d = tempfile.mkdtemp(prefix=f"isohex_{name}_")
    if not os.environ.get("ISOHEX_KEEP_TEST_FILES"):
        atexit.register(shutil.rmtree, d, True)
    return d


def phantoms(name):
    """A new work folder with samples/make_phantoms.py's phantoms written into it."""
    d = workdir(name)
    subprocess.run(["/usr/bin/python3", os.path.join(SOURCE, "samples", "make_phantoms.py"), d], check=True,
                   capture_output=True)
    return d


def polygon_topology(polys):
    """Components and Euler characteristic V - E + F of a polygon surface given
    as a numpy array of vertex ids (one row per polygon, all the same size)."""
    import numpy as np
    polys = np.asarray(polys)
    used = np.unique(polys)
    edges = np.unique(np.sort(np.stack([polys, np.roll(polys, -1, axis=1)], axis=2).reshape(-1, 2), axis=1), axis=0)
    parent = {int(v): int(v) for v in used}

    def find(v):
        while parent[v] != v:
            parent[v] = parent[parent[v]]
            v = parent[v]
        return v

    for a, b in edges:
        ra, rb = find(int(a)), find(int(b))
        if ra != rb:
            parent[max(ra, rb)] = min(ra, rb)
    components = len({find(int(v)) for v in used})
    return components, len(used) - len(edges) + len(polys)


EXIT_BELOW_QUALITY = 4  # isohex's exit status when a mesh stays below --min-quality


def run_below_allowed(args, mesh, target=0.0, **kw):
    """Runs a command meant to leave poor hexes (--no-optimize, --fix-boundary)
    with --allow-below: the mesh is written, and the exit status is 4 exactly
    when VTK's scaled Jacobian on the written `mesh` (a .vtu) has a hex below
    `target`, at or below 0, or degenerate (VTK's 1e30), else 0."""
    from vtk_tools import vtk_sj
    p = run(list(args) + ["--allow-below"], check=False, **kw)
    sj = vtk_sj(mesh)
    below = bool(((sj < target) | (sj <= 0) | (sj > 1 + 1e-9)).any())
    expected = EXIT_BELOW_QUALITY if below else 0
    if p.returncode != expected:
        sys.stderr.write(p.stdout + p.stderr)
        raise AssertionError(f"isohex {' '.join(map(str, args))} exited {p.returncode}, expected {expected} "
                             f"(VTK: min scaled Jacobian {sj.min():.3f})")
    return p
