#!/usr/bin/python3
"""The hostile corpus: inputs and command lines an adversarial user gives isohex.

Each case is a command line (with its input files written into a folder) and
what is acceptable:

  "refuse"  exit status non-zero, one error line on stderr naming the file
            (or, for a bad option, the option), nothing written;
  "either"  that, or exit 0 with a mesh VTK reads whose every hex has a
            positive scaled Jacobian (the input may still be a valid one).

Every case must also end without a signal and within the time limit. The
classes (see `classes()`):

  nifti-field     every field of the NIfTI-1 header given lies (0, -1, huge,
                  NaN for floats, the wrong magic)
  analyze-field   the same fields in an Analyze 7.5 .hdr/.img pair
  nrrd-field      every NRRD field given lies (a detached .nhdr for data file)
  mha-field       every MetaImage field given lies
  vtu-field       every attribute of a .vtu's header given lies (quality,
                  convert, smooth)
  msh-field       every count of a Gmsh file given lies
  off-field       OFF counts and indices (mesh --method sheets)
  truncation      each of those files cut at every structure boundary
                  (header fields, header end, data start, middle, last byte)
  option          every numeric option of mesh (and the batch columns) given
                  NaN, inf, -inf, 0, -1 and huge values

Usage: hostile_corpus.py OUT_DIR   writes the inputs and OUT_DIR/cases.json.
The test tests/py/test_hostile_corpus.py runs it.
"""
import gzip
import json
import os
import struct
import sys

import numpy as np

N = 10  # voxels per axis: small, so a case runs in a fraction of a second


def sphere_volume(n=N):
    c = (n - 1) / 2.0
    x, y, z = np.meshgrid(*(np.arange(n) - c,) * 3, indexing="ij")
    r = np.sqrt(x * x + y * y + z * z)
    return np.clip(50.0 - 50.0 * (r - n / 3.0), 0.0, 100.0).astype(np.float32)


# ---------------------------------------------------------------- NIfTI / Analyze

# (name, offset, struct format) of the NIfTI-1 header fields isohex's readers use
NIFTI_FIELDS = [
    ("sizeof_hdr", 0, "<i"), ("dim0", 40, "<h"), ("dim1", 42, "<h"), ("dim2", 44, "<h"), ("dim3", 46, "<h"),
    ("dim4", 48, "<h"), ("dim5", 50, "<h"), ("datatype", 70, "<h"), ("bitpix", 72, "<h"),
    ("pixdim0", 76, "<f"), ("pixdim1", 80, "<f"), ("pixdim2", 84, "<f"), ("pixdim3", 88, "<f"),
    ("vox_offset", 108, "<f"), ("scl_slope", 112, "<f"), ("scl_inter", 116, "<f"), ("xyzt_units", 123, "<b"),
    ("qform_code", 252, "<h"), ("sform_code", 254, "<h"), ("quatern_b", 256, "<f"), ("quatern_c", 260, "<f"),
    ("quatern_d", 264, "<f"), ("qoffset_x", 268, "<f"), ("srow_x0", 280, "<f"), ("srow_y1", 300, "<f"),
    ("srow_z2", 320, "<f"), ("magic", 344, "4s"),
]

INT_LIES = {"<i": [0, -1, 2**31 - 1], "<h": [0, -1, 32767], "<b": [-1, 127]}
FLOAT_LIES = [0.0, -1.0, 1e30, float("nan")]


def nifti_bytes(vol, magic=b"n+1\0", vox_offset=352.0):
    h = bytearray(348)
    struct.pack_into("<i", h, 0, 348)
    struct.pack_into("<8h", h, 40, 3, *vol.shape, 1, 1, 1, 1)
    struct.pack_into("<hh", h, 70, 16, 32)  # float32
    struct.pack_into("<8f", h, 76, 1.0, 1.0, 1.0, 1.0, 0, 0, 0, 0)
    struct.pack_into("<f", h, 108, vox_offset)
    struct.pack_into("<ff", h, 112, 1.0, 0.0)
    h[123] = 2  # mm
    struct.pack_into("<hh", h, 252, 1, 0)
    struct.pack_into("4s", h, 344, magic)
    data = vol.transpose(2, 1, 0).astype("<f4").tobytes()  # x fastest
    gap = b"\0" * (int(vox_offset) - 348) if vox_offset >= 348 else b""
    return bytes(h), gap, data


def lies_for(fmt):
    if fmt == "4s":  # the magic: NIfTI-2's, a .hdr/.img pair's inside a .nii, none, not NIfTI at all
        return [b"n+2\0", b"ni1\0", b"\0\0\0\0", b"XXXX"]
    return INT_LIES.get(fmt, FLOAT_LIES)


def lie_text(v):
    return v.decode("latin-1").strip("\0") or "empty" if isinstance(v, bytes) else repr(v)


def nifti_cases(out, vol):
    cases = []
    h, gap, data = nifti_bytes(vol)
    for name, off, fmt in NIFTI_FIELDS:
        for v in lies_for(fmt):
            hh = bytearray(h)
            struct.pack_into(fmt, hh, off, v)
            path = os.path.join(out, f"nifti_{name}_{lie_text(v)}.nii")
            with open(path, "wb") as f:
                f.write(bytes(hh) + gap + data)
            cases.append(mesh_case("nifti-field", path))
    # Analyze 7.5: the same header without the NIfTI magic, data in .img
    for name, off, fmt in NIFTI_FIELDS:
        if name in ("magic", "qform_code", "sform_code", "quatern_b", "quatern_c", "quatern_d", "qoffset_x",
                    "srow_x0", "srow_y1", "srow_z2", "vox_offset", "scl_slope", "scl_inter", "xyzt_units"):
            continue
        for v in lies_for(fmt):
            hh = bytearray(h)
            struct.pack_into("4s", hh, 344, b"\0\0\0\0")
            struct.pack_into("<f", hh, 108, 0.0)
            struct.pack_into(fmt, hh, off, v)
            stem = os.path.join(out, f"analyze_{name}_{lie_text(v)}")
            with open(stem + ".hdr", "wb") as f:
                f.write(bytes(hh))
            with open(stem + ".img", "wb") as f:
                f.write(data)
            cases.append(mesh_case("analyze-field", stem + ".hdr"))
    return cases


# ---------------------------------------------------------------- NRRD / MetaImage

def nrrd_header(vol, fields):
    lines = ["NRRD0004"] + [f"{k}: {v}" for k, v in fields.items() if v is not None]
    return ("\n".join(lines) + "\n\n").encode()


def nrrd_fields(vol, datafile=None):
    f = {"type": "float", "dimension": "3", "space": "left-posterior-superior",
         "sizes": " ".join(map(str, vol.shape)), "space directions": "(1,0,0) (0,1,0) (0,0,1)",
         "endian": "little", "encoding": "raw", "space origin": "(0,0,0)"}
    if datafile:
        f["data file"] = datafile
    return f


NRRD_LIES = {
    "type": ["int16", "double", "block", "nonsense"], "dimension": ["0", "2", "4", "-1", "99999"],
    "sizes": ["0 10 10", "10 10", "10 10 1000000", "-10 10 10", "1e9 1e9 1e9"],
    "space directions": ["(0,0,0) (0,1,0) (0,0,1)", "(nan,0,0) (0,1,0) (0,0,1)", "(1,1,0) (0,1,0) (0,0,1)",
                         "(1,0,0) (0,1,0)", "none (0,1,0) (0,0,1)"],
    "endian": ["big", "middle"], "encoding": ["gzip", "hex", "bzip2", "nonsense"],
    "byte skip": ["-2", "100000", "4"], "line skip": ["3", "-1"], "space origin": ["(nan,0,0)", "(1e300,0,0)"],
}


def nrrd_cases(out, vol):
    cases = []
    data = vol.transpose(2, 1, 0).astype("<f4").tobytes()
    for field, lies in NRRD_LIES.items():
        for v in lies:
            fields = nrrd_fields(vol)
            fields[field] = v
            path = os.path.join(out, f"nrrd_{field.replace(' ', '_')}_{safe(v)}.nrrd")
            with open(path, "wb") as f:
                f.write(nrrd_header(vol, fields) + data)
            cases.append(mesh_case("nrrd-field", path))
    # a detached header whose data file lies
    with open(os.path.join(out, "nrrd_data.raw"), "wb") as f:
        f.write(data)
    for v in ["missing.raw", "/etc/passwd", "../../../../etc/passwd", "/dev/zero", ".", "nrrd_datafile_self.nhdr"]:
        path = os.path.join(out, "nrrd_datafile_self.nhdr" if v == "nrrd_datafile_self.nhdr" else
                            f"nrrd_datafile_{safe(v)}.nhdr")
        with open(path, "wb") as f:
            f.write(nrrd_header(vol, nrrd_fields(vol, v)))
        cases.append(mesh_case("nrrd-field", path, expect="refuse"))
    return cases


def mha_fields(vol):
    return {"ObjectType": "Image", "NDims": "3", "BinaryData": "True", "BinaryDataByteOrderMSB": "False",
            "CompressedData": "False", "TransformMatrix": "1 0 0 0 1 0 0 0 1", "Offset": "0 0 0",
            "ElementSpacing": "1 1 1", "DimSize": " ".join(map(str, vol.shape)), "ElementType": "MET_FLOAT",
            "ElementDataFile": "LOCAL"}


MHA_LIES = {
    "NDims": ["0", "2", "4", "-1", "1000"], "DimSize": ["0 10 10", "10 10", "10 10 100000", "-1 10 10", "1e9 1 1"],
    "ElementType": ["MET_SHORT", "MET_DOUBLE", "MET_NONE", "nonsense"],
    "ElementSpacing": ["0 1 1", "nan 1 1", "-1 1 1", "1e300 1 1"],
    "TransformMatrix": ["0 0 0 0 0 0 0 0 0", "1 1 0 0 1 0 0 0 1", "nan 0 0 0 1 0 0 0 1"],
    "Offset": ["nan 0 0", "1e300 0 0"], "CompressedData": ["True"], "BinaryDataByteOrderMSB": ["True"],
    "HeaderSize": ["-2", "100000", "-1"], "ElementNumberOfChannels": ["0", "3", "-1"],
    "ElementDataFile": [None, "missing.raw", "/etc/passwd", "../../../../etc/passwd", "/dev/zero", "."],
}


def mha_cases(out, vol):
    cases = []
    data = vol.transpose(2, 1, 0).astype("<f4").tobytes()
    for field, lies in MHA_LIES.items():
        for v in lies:
            fields = mha_fields(vol)
            fields[field] = v
            if field == "HeaderSize":  # only for detached data
                fields["ElementDataFile"] = "mha_data.raw"
            detached = fields.get("ElementDataFile") != "LOCAL"
            path = os.path.join(out, f"mha_{field}_{safe(v)}" + (".mhd" if detached else ".mha"))
            # ElementDataFile ends the header
            keys = [k for k in fields if k != "ElementDataFile"] + ["ElementDataFile"]
            text = "".join(f"{k} = {fields[k]}\n" for k in keys if fields[k] is not None).encode()
            with open(path, "wb") as f:
                f.write(text + (b"" if detached else data))
            expect = "refuse" if field == "ElementDataFile" else "either"
            cases.append(mesh_case("mha-field", path, expect=expect))
    with open(os.path.join(out, "mha_data.raw"), "wb") as f:
        f.write(data)
    return cases


# ---------------------------------------------------------------- meshes and surfaces

def vtu_text(points, hexes, **override):
    """An ASCII .vtu of `hexes` (lists of 8 point ids); `override` replaces
    header attributes (NumberOfPoints, NumberOfCells, type of an array)."""
    npts = override.get("NumberOfPoints", len(points))
    ncells = override.get("NumberOfCells", len(hexes))
    ptype = override.get("points_type", "Float64")
    ctype = override.get("connectivity_type", "Int64")
    comps = override.get("NumberOfComponents", 3)
    cell_type = override.get("cell_type", 12)
    pts = " ".join("%g %g %g" % tuple(p) for p in points)
    conn = " ".join(str(i) for h in hexes for i in h)
    offs = " ".join(str(8 * (k + 1)) for k in range(len(hexes)))
    types = " ".join(str(cell_type) for _ in hexes)
    return f"""<?xml version="1.0"?>
<VTKFile type="UnstructuredGrid" version="1.0" byte_order="LittleEndian" header_type="UInt64">
  <UnstructuredGrid>
    <Piece NumberOfPoints="{npts}" NumberOfCells="{ncells}">
      <Points>
        <DataArray type="{ptype}" NumberOfComponents="{comps}" format="ascii">{pts}</DataArray>
      </Points>
      <Cells>
        <DataArray type="{ctype}" Name="connectivity" format="ascii">{conn}</DataArray>
        <DataArray type="Int64" Name="offsets" format="ascii">{offs}</DataArray>
        <DataArray type="UInt8" Name="types" format="ascii">{types}</DataArray>
      </Cells>
    </Piece>
  </UnstructuredGrid>
</VTKFile>
"""


def block_mesh(n=2):
    """n^3 unit cubes sharing their nodes, VTK corner order."""
    idx = lambda i, j, k: (k * (n + 1) + j) * (n + 1) + i  # noqa: E731
    points = [(i, j, k) for k in range(n + 1) for j in range(n + 1) for i in range(n + 1)]
    hexes = []
    for k in range(n):
        for j in range(n):
            for i in range(n):
                hexes.append([idx(i, j, k), idx(i + 1, j, k), idx(i + 1, j + 1, k), idx(i, j + 1, k),
                              idx(i, j, k + 1), idx(i + 1, j, k + 1), idx(i + 1, j + 1, k + 1), idx(i, j + 1, k + 1)])
    return points, hexes


VTU_LIES = {
    "NumberOfPoints": [0, -1, 10**9, 2 * 10**9, 10**18, "nan"], "NumberOfCells": [0, -1, 2 * 10**9, 10**18, "x"],
    "points_type": ["Int8", "String", "Float128"], "connectivity_type": ["Float32", "UInt8", "Bogus"],
    "NumberOfComponents": [0, 2, 100000], "cell_type": [10, 0, 255, 42],
}


def msh_text(points, hexes, nodes_header=None, elements_header=None):
    n, m = len(points), len(hexes)
    nh = nodes_header or f"1 {n} 1 {n}"
    eh = elements_header or f"1 {m} 1 {m}"
    lines = ["$MeshFormat", "4.1 0 8", "$EndMeshFormat", "$Nodes", nh, f"3 1 0 {n}"]
    lines += [str(i + 1) for i in range(n)] + ["%g %g %g" % tuple(p) for p in points]
    lines += ["$EndNodes", "$Elements", eh, f"3 1 5 {m}"]
    lines += [" ".join([str(k + 1)] + [str(i + 1) for i in h]) for k, h in enumerate(hexes)]
    lines += ["$EndElements"]
    return "\n".join(lines) + "\n"


MSH_LIES = {
    "nodes": ["1 27 1 1000000000000", "1 1000000000 1 1000000000", "0 27 1 27", "1 -1 1 27", "99999999 27 1 27"],
    "elements": ["1 8 1 999999999999", "1 2000000000 1 2000000000", "1 -8 1 8", "1 7 1 8"],
}


def mesh_cases(out):
    cases = []
    points, hexes = block_mesh()
    for attr, lies in VTU_LIES.items():
        for v in lies:
            path = os.path.join(out, f"vtu_{attr}_{safe(str(v))}.vtu")
            with open(path, "w") as f:
                f.write(vtu_text(points, hexes, **{attr: v}))
            commands = ("quality", "convert", "smooth") if attr.startswith("Number") else ("quality",)
            for cmd in commands:
                cases.append(mesh_file_case("vtu-field", cmd, path))
    for section, lies in MSH_LIES.items():
        for v in lies:
            path = os.path.join(out, f"msh_{section}_{safe(v)}.msh")
            with open(path, "w") as f:
                f.write(msh_text(points, hexes, **{f"{section}_header": v}))
            cases.append(mesh_file_case("msh-field", "quality", path))
    return cases


def sphere_off():
    """An icosphere (2 subdivisions) as OFF vertex and face lists."""
    t = (1 + 5 ** 0.5) / 2
    v = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t), (0, -1, -t), (0, 1, -t),
         (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    v = [tuple(c / np.linalg.norm(p) for c in p) for p in v]
    f = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4), (11, 10, 2), (10, 7, 6),
         (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10),
         (8, 6, 7), (9, 8, 1)]
    for _ in range(2):
        mid = {}

        def m(a, b):
            key = (min(a, b), max(a, b))
            if key not in mid:
                p = np.add(v[a], v[b]) / 2
                v.append(tuple(p / np.linalg.norm(p)))
                mid[key] = len(v) - 1
            return mid[key]
        f = [g for a, b, c in f for g in ((a, m(a, b), m(c, a)), (b, m(b, c), m(a, b)), (c, m(c, a), m(b, c)),
                                          (m(a, b), m(b, c), m(c, a)))]
    return v, f


def off_text(v, f, counts=None):
    head = counts or f"{len(v)} {len(f)} 0"
    return "OFF\n" + head + "\n" + "".join("%.17g %.17g %.17g\n" % p for p in v) + \
        "".join("3 %d %d %d\n" % t for t in f)


OFF_LIES = ["0 320 0", "162 0 0", "162 100000 0", "1000000000 320 0", "-1 320 0", "162 -5 0", "nan 320 0"]


def surface_cases(out):
    cases = []
    v, f = sphere_off()
    for counts in OFF_LIES:
        path = os.path.join(out, f"off_counts_{safe(counts)}.off")
        with open(path, "w") as fh:
            fh.write(off_text(v, f, counts))
        cases.append(mesh_case("off-field", path, "--method", "sheets", expect="refuse"))
    bad_index = [(0, 1, 100000)] + f[1:]
    path = os.path.join(out, "off_index_beyond.off")
    with open(path, "w") as fh:
        fh.write(off_text(v, bad_index))
    cases.append(mesh_case("off-field", path, "--method", "sheets", expect="refuse"))
    return cases


# ---------------------------------------------------------------- truncation

def truncation_cases(out, vol):
    cases = []
    h, gap, data = nifti_bytes(vol)
    whole = h + gap + data
    for cut in [0, 1, 4, 40, 42, 70, 72, 76, 108, 112, 252, 344, 347, 348, 350, 352, 353, 352 + len(data) // 2,
                len(whole) - 1]:
        path = os.path.join(out, f"cut_nifti_{cut}.nii")
        with open(path, "wb") as f:
            f.write(whole[:cut])
        cases.append(mesh_case("truncation", path, expect="refuse"))
        gz = gzip.compress(whole)
        path = os.path.join(out, f"cut_niftigz_{cut}.nii.gz")
        gz_cut = max(0, min(len(gz) - 1, cut * len(gz) // len(whole)))
        with open(path, "wb") as f:
            f.write(gz[:gz_cut])
        # cut inside the 8-byte trailer (CRC and size) the data is whole
        cases.append(mesh_case("truncation", path, expect="refuse" if gz_cut < len(gz) - 8 else "either"))
    raw = vol.transpose(2, 1, 0).astype("<f4").tobytes()
    nrrd = nrrd_header(vol, nrrd_fields(vol)) + raw
    hdr_len = len(nrrd) - len(raw)
    for cut in [0, 4, 9, hdr_len // 2, hdr_len - 1, hdr_len, hdr_len + 1, hdr_len + len(raw) // 2, len(nrrd) - 1]:
        path = os.path.join(out, f"cut_nrrd_{cut}.nrrd")
        with open(path, "wb") as f:
            f.write(nrrd[:cut])
        cases.append(mesh_case("truncation", path, expect="refuse"))
    mha_head = "".join(f"{k} = {v}\n" for k, v in mha_fields(vol).items()).encode()
    mha = mha_head + raw
    for cut in [0, 10, len(mha_head) // 2, len(mha_head) - 1, len(mha_head), len(mha_head) + 3,
                len(mha_head) + len(raw) // 2, len(mha) - 1]:
        path = os.path.join(out, f"cut_mha_{cut}.mha")
        with open(path, "wb") as f:
            f.write(mha[:cut])
        cases.append(mesh_case("truncation", path, expect="refuse"))
    points, hexes = block_mesh()
    vtu = vtu_text(points, hexes)
    marks = sorted({i for tag in ("<VTKFile", "<UnstructuredGrid", "<Piece", "<Points", "<DataArray", "</DataArray",
                                  "<Cells", "</Cells", "</Piece", "</VTKFile") for i in find_all(vtu, tag)})
    for cut in [0, 5] + marks + [len(vtu) - 2]:
        path = os.path.join(out, f"cut_vtu_{cut}.vtu")
        with open(path, "w") as f:
            f.write(vtu[:cut])
        cases.append(mesh_file_case("truncation", "quality", path, expect="refuse"))
    msh = msh_text(points, hexes)
    for cut in [0] + [i for tag in ("$MeshFormat", "$EndMeshFormat", "$Nodes", "$EndNodes", "$Elements",
                                     "$EndElements") for i in find_all(msh, tag)] + [len(msh) - 5]:
        path = os.path.join(out, f"cut_msh_{cut}.msh")
        with open(path, "w") as f:
            f.write(msh[:cut])
        cases.append(mesh_file_case("truncation", "quality", path, expect="refuse"))
    v, f = sphere_off()
    off = off_text(v, f)
    lines = off.splitlines(keepends=True)
    offsets = np.cumsum([0] + [len(line) for line in lines])
    for k in [0, 1, 2, 3, len(v) // 2, len(v) + 1, len(v) + 2, len(v) + 2 + len(f) // 2, len(lines) - 1]:
        cut = int(offsets[k])
        path = os.path.join(out, f"cut_off_{cut}.off")
        with open(path, "w") as fh:
            fh.write(off[:cut])
        cases.append(mesh_case("truncation", path, "--method", "sheets", expect="refuse"))
    return cases


def find_all(text, tag):
    i = text.find(tag)
    while i >= 0:
        yield i
        i = text.find(tag, i + 1)


# ---------------------------------------------------------------- options

NUMERIC_OPTIONS = ["iso", "min-label-voxels", "smooth", "volume-index", "max-memory", "size", "level",
                   "boundary-layers", "worst-hex-target", "surface-tolerance", "retries", "retry-below", "threads"]
BAD_VALUES = ["nan", "inf", "-1", "1e308", "1,5", ""]


def option_cases(out, vol):
    cases = []
    scan = os.path.join(out, "option_scan.nii")
    h, gap, data = nifti_bytes(vol)
    with open(scan, "wb") as f:
        f.write(h + gap + data)
    for opt in NUMERIC_OPTIONS:
        for v in BAD_VALUES + ["0"]:
            expect = "either" if v == "0" else "refuse"
            # a value the option's range allows may still be refused for
            # this scan (an iso outside its data): then the scan is named
            cases.append({"class": "option", "name": f"--{opt} {v}", "args": ["mesh", scan, f"--{opt}", v],
                          "input": f"--{opt}", "or_names": os.path.basename(scan), "expect": expect})
    for opt in NUMERIC_OPTIONS:
        if opt == "threads":
            continue
        column = opt.replace("-", "_")
        for v in ["nan", "1e308"]:
            manifest = os.path.join(out, f"batch_{column}_{safe(v)}.csv")
            output = os.path.join(out, f"batch_{column}_{safe(v)}.vtu")
            with open(manifest, "w") as f:
                f.write(f"input,output,{column}\n{scan},{output},{v}\n")
            cases.append({"class": "option", "name": f"batch {column}={v}", "args": ["batch", manifest],
                          "input": os.path.basename(manifest), "or_names": os.path.basename(scan), "expect": "refuse",
                          "outputs": [output]})
    return cases


# ---------------------------------------------------------------- cases

def safe(v):
    s = "".join(c if c.isalnum() or c in "-+." else "_" for c in str(v))
    return s[:40] or "empty"


def mesh_case(cls, path, *extra, expect="either"):
    return {"class": cls, "name": os.path.basename(path), "args": ["mesh", path, *extra], "input": path,
            "expect": expect}


def mesh_file_case(cls, cmd, path, expect="either"):
    args = {"quality": ["quality", path, "--report", "OUT.json"], "convert": ["convert", path, "OUT"],
            "smooth": ["smooth", path, "-o", "OUT"]}[cmd]
    return {"class": cls, "name": f"{cmd} {os.path.basename(path)}", "args": args, "input": path, "expect": expect,
            "command": cmd}


def classes(cases):
    counts = {}
    for c in cases:
        counts[c["class"]] = counts.get(c["class"], 0) + 1
    return counts


def main():
    out = sys.argv[1]
    os.makedirs(out, exist_ok=True)
    vol = sphere_volume()
    cases = (nifti_cases(out, vol) + nrrd_cases(out, vol) + mha_cases(out, vol) + mesh_cases(out) +
             surface_cases(out) + truncation_cases(out, vol) + option_cases(out, vol))
    with open(os.path.join(out, "cases.json"), "w") as f:
        json.dump(cases, f, indent=1)
    print(len(cases), "cases:", classes(cases))


if __name__ == "__main__":
    main()
