#!/usr/bin/env bash
# Checks that a change leaves isohex's output unchanged: meshes a fixed set of
# inputs (phantoms, the skull CT, the JHU label atlas, femur and a sphere
# surface, --method sheets, compare, batch, insert-sheet, smooth, convert) with
# two builds and compares what they write.
#
#   tools/same-output.sh BASE_REV [BIN]
#       builds BASE_REV in build-base/ (a git worktree, built in build-base/build),
#       runs the set with its isohex and with BIN (default ./build/cli/isohex) into
#       build-same-output/{before,after},
#       and compares: every mesh file byte for byte, every JSON report with its
#       timings, versions and memory figures left out (keys may be added, never
#       removed or changed). Exit 0 when all match, 1 otherwise.
#   tools/same-output.sh --record BIN DIR
#       only runs the set with BIN into DIR.
#   tools/same-output.sh --compare DIR_A DIR_B
#       only compares two recorded sets (A before, B after).
#
# Needs ./setup.sh's packages and ../shared/data beside the checkout.
set -euo pipefail
top=$(cd "$(dirname "$0")/.." && pwd)
data=${ISOHEX_SHARED_DATA:-$top/../shared/data}
py=/usr/bin/python3

noise_volume() {  # PATH: smoothed noise whose isosurface the topology search
    # mends in several places with its beam and annealing searches, and leaves one
    $py - "$1" <<'EOF'
import sys, numpy as np, vtk
from vtk.util import numpy_support as ns
n = 20
a = np.random.default_rng(95).random((n, n, n)) - 0.5
for _ in range(2):
    p = np.pad(a, 1, mode="edge")
    a = sum(p[i:i + n, j:j + n, k:k + n] for i in range(3) for j in range(3) for k in range(3)) / 27.0
a[:2] = a[-2:] = a[:, :2] = a[:, -2:] = a[:, :, :2] = a[:, :, -2:] = -0.2
a = (a * 1000).astype(np.float32)
img = vtk.vtkImageData()
img.SetDimensions(*a.shape)
img.GetPointData().SetScalars(ns.numpy_to_vtk(a.ravel(order="F"), deep=True))
w = vtk.vtkNIFTIImageWriter()
w.SetFileName(sys.argv[1])
w.SetInputData(img)
w.Write()
EOF
}

record() {  # BIN DIR: runs in DIR with relative paths, so the outputs name no folder
    local bin=$1 out=$2
    rm -rf "$out" && mkdir -p "$out/in"
    $py "$top/samples/make_phantoms.py" "$out/in" --size 48 > /dev/null
    noise_volume "$out/in/noise95.nii.gz"
    cp "$top/samples/skull_ct.nii.gz" "$top/samples/JHU-WhiteMatter-labels-2mm.nii.gz" "$top/samples/twisted_bar.vtu" \
        "$top/samples/spherical_cuts_block.vtu" "$top/samples/spherical_cut_1.off" "$top/samples/spherical_cut_2.off" \
        "$data/femur.off" "$data/sphere966.off" "$out/in/"
    local m=("$bin" mesh -q --force --threads 2)
    (
        cd "$out"
        set -x
        for p in sphere torus thin_plate two_spheres; do
            "${m[@]}" "in/$p.nii.gz" --iso 50 -o "$p.vtu" --report "$p.json"
        done
        "${m[@]}" in/two_materials.nii.gz --labels -o two_materials.vtu -o two_materials.exo \
            -o two_materials.msh -o two_materials.inp -o two_materials.mesh --report two_materials.json
        "${m[@]}" in/torus.nii.gz --iso 50 --size 3 --boundary-layers 2 --mesh-exterior \
            -o torus_exterior.vtu --report torus_exterior.json
        "${m[@]}" in/sphere.nii.gz --iso 50 --method voxel --level 1 -o sphere_voxel.vtu
        "${m[@]}" in/skull_ct.nii.gz --iso 2.9 -o skull.vtu -o skull.exo -o skull.msh -o skull.inp --report skull.json
        "${m[@]}" in/JHU-WhiteMatter-labels-2mm.nii.gz --labels --size 4 -o jhu.vtu -o jhu.exo --report jhu.json
        "${m[@]}" in/JHU-WhiteMatter-labels-2mm.nii.gz --labels --label 3,7 --size 2 --isosurface-topology \
            -o jhu_topology.vtu --report jhu_topology.json
        "${m[@]}" in/noise95.nii.gz --iso 0 --size 1 --isosurface-topology -o noise95.vtu --report noise95.json
        "${m[@]}" in/femur.off -o femur.vtu --report femur.json
        "${m[@]}" in/sphere966.off --method sheets -o sphere_sheets.vtu --report sphere_sheets.json
        "$bin" compare -q --threads 2 in/torus.nii.gz --iso 50 --size 3 --json compare.json --mesh-dir compare
        printf 'input,output,report,size,no_pillow,labels\n%s\n%s\n' \
            "in/sphere.nii.gz,batch/sphere.vtu;batch/sphere.inp,batch/sphere.json,,," \
            "in/two_materials.nii.gz,batch/labels.vtu,batch/labels.json,3,true,yes" > jobs.csv
        "$bin" batch jobs.csv --iso 50 --size 4 -q --threads 2
        "$bin" insert-sheet -q --force --threads 2 --mesh in/spherical_cuts_block.vtu \
            --surface in/spherical_cut_1.off --surface in/spherical_cut_2.off --keep outside -o cut.vtu
        "$bin" smooth -q --force --threads 2 in/twisted_bar.vtu -o twisted_bar.vtu
        "$bin" convert --force skull.vtu skull_converted.msh
        "$bin" quality --json skull.vtu > skull_quality.json
    ) 2> "$out/commands.log"
    rm -rf "$out/in"
}

compare() {  # DIR_A DIR_B
    $py - "$1" "$2" <<'EOF'
import json, os, re, sys
a, b = sys.argv[1:3]
# figures that differ from run to run, not outputs of the method
volatile = re.compile(r"(seconds|_s$|^time|elapsed|version|memory|rss|peak|threads|^date|^host|git|command_line|eta)", re.I)
def strip(x, base):
    """x without volatile figures, with the recorded folder's path as <out>."""
    if isinstance(x, dict):
        return {k: strip(v, base) for k, v in x.items() if not volatile.search(k)}
    if isinstance(x, list):
        return [strip(v, base) for v in x]
    if isinstance(x, str):
        return x.replace(base, "<out>")
    return x
def missing(x, y, path=""):
    """What x has that y lacks or holds differently (y may add keys)."""
    if isinstance(x, dict) and isinstance(y, dict):
        for k, v in x.items():
            if k not in y:
                yield f"{path}/{k}: removed"
            else:
                yield from missing(v, y[k], f"{path}/{k}")
    elif isinstance(x, list) and isinstance(y, list) and len(x) == len(y):
        for i, (u, v) in enumerate(zip(x, y)):
            yield from missing(u, v, f"{path}[{i}]")
    elif x != y:
        yield f"{path}: {json.dumps(x)[:80]} -> {json.dumps(y)[:80]}"
bad = 0
files = sorted(os.path.relpath(os.path.join(r, f), a) for r, _, fs in os.walk(a) for f in fs if f != "commands.log")
for rel in files:
    pa, pb = os.path.join(a, rel), os.path.join(b, rel)
    if not os.path.exists(pb):
        print(f"MISSING  {rel}"); bad += 1; continue
    if rel.endswith(".json"):
        diffs = list(missing(strip(json.load(open(pa)), os.path.abspath(a)),
                             strip(json.load(open(pb)), os.path.abspath(b))))
        if diffs:
            bad += 1
            print(f"DIFFERS  {rel}"); [print("         " + d) for d in diffs[:10]]
        else:
            print(f"same     {rel}")
    elif open(pa, "rb").read() != open(pb, "rb").read():
        print(f"DIFFERS  {rel} (bytes)"); bad += 1
    else:
        print(f"same     {rel}")
print(f"{len(files) - bad} same, {bad} differ")
sys.exit(1 if bad else 0)
EOF
}

case "${1:-}" in
    --record) record "$(realpath "$2")" "$3"; exit 0 ;;
    --compare) compare "$2" "$3"; exit $? ;;
esac
base=${1:?usage: tools/same-output.sh BASE_REV [BIN] | --record BIN DIR}
bin=$(realpath "${2:-$top/build/cli/isohex}")
# The base is a worktree with its build folder inside it (build-base/build),
# laid out like the checkout so a compiler cache shares their objects.
wt=$top/build-base
if [ ! -d "$wt" ]; then
    git -C "$top" worktree add --detach "$wt" "$base" > /dev/null
else
    git -C "$wt" checkout -q --detach "$base"
fi
launcher=()
command -v ccache > /dev/null && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache -DCMAKE_C_COMPILER_LAUNCHER=ccache)
cmake -S "$wt" -B "$wt/build" "${launcher[@]}" -G Ninja -DCMAKE_BUILD_TYPE=Release -DBUILD_TESTING=OFF \
    -DISOHEX_SHARED_DATA="$data" > /dev/null
cmake --build "$wt/build" -j"$(nproc)" --target isohex
record "$wt/build/cli/isohex" "$top/build-same-output/before"
record "$bin" "$top/build-same-output/after"
compare "$top/build-same-output/before" "$top/build-same-output/after"
