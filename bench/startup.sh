#!/usr/bin/env bash
# Start-up cost of isohex (issue 39, part 3): prints a Markdown table of
#   - `isohex --version`: wall time (median of --runs) and peak resident memory;
#   - shared libraries the launcher and the program load at start (ldd);
#   - the dynamic loader's start-up relocations of the program (LD_DEBUG=statistics);
#   - a tiny label map (432 hexes) meshed --runs times: wall, CPU, peak memory,
#     and wall minus the report's pipeline total; the same map 20 times in one
#     `isohex batch`: wall and CPU per job;
#   - a ~20k-hex mesh end to end (phantom sphere --iso 50 --size 1.25,
#     21,999 hexes): wall, CPU and the report's stage times.
#
#   bench/startup.sh [--isohex BIN] [--runs N] [--work DIR]
#
# BIN defaults to $ISOHEX, else build/cli/isohex. Several BINs can be
# compared by running the script once per build. Wall times on a shared
# machine vary with its load: the table records the load average; CPU
# times (user + system, from GNU time) vary less.
set -euo pipefail
top=$(cd "$(dirname "$0")/.." && pwd)
bin=${ISOHEX:-$top/build/cli/isohex}
runs=11
work=/tmp/isohex-startup-$(id -u)
while [ $# -gt 0 ]; do
    case $1 in
        --isohex) bin=$2; shift 2 ;;
        --runs) runs=$2; shift 2 ;;
        --work) work=$2; shift 2 ;;
        *) echo "usage: bench/startup.sh [--isohex BIN] [--runs N] [--work DIR]" >&2; exit 2 ;;
    esac
done
py=/usr/bin/python3
mkdir -p "$work"
cd "$work"

median() { sort -n | awk '{a[NR]=$1} END {print (NR % 2) ? a[(NR+1)/2] : (a[NR/2] + a[NR/2+1]) / 2}'; }

# wall milliseconds of one run of the command, output discarded
wall_ms() {
    local s e
    s=$(date +%s%N)
    "$@" > /dev/null 2>&1
    e=$(date +%s%N)
    echo $(( (e - s) / 1000000 ))
}

# "wall_s cpu_s maxrss_kb" of one run (GNU time; CPU includes waited-for children)
gnu_time() { /usr/bin/time -f "%e %U %S %M" "$@" 2>&1 > /dev/null | tail -1 | awk '{print $1, $2 + $3, $4}'; }

# Inputs: a 12^3 label map with a 6^3 cube, and the phantoms.
[ -f tiny.nii.gz ] || $py - <<'EOF'
import numpy as np, vtk
from vtk.util import numpy_support as ns
n = 12
a = np.zeros((n, n, n), np.uint8)
a[3:9, 3:9, 3:9] = 1
img = vtk.vtkImageData()
img.SetDimensions(n, n, n)
img.GetPointData().SetScalars(ns.numpy_to_vtk(a.ravel(order="F"), deep=True, array_type=vtk.VTK_UNSIGNED_CHAR))
w = vtk.vtkNIFTIImageWriter()
w.SetInputData(img)
w.SetFileName("tiny.nii.gz")
w.Write()
EOF
[ -f phantoms/sphere.nii.gz ] || $py "$top/samples/make_phantoms.py" phantoms > /dev/null

echo "isohex start-up: \`$bin\`, $(date -u '+%Y-%m-%d %H:%M UTC'), $(nproc) cores, load average $(cut -d' ' -f1-3 /proc/loadavg)"
echo
echo "| measure | value | command |"
echo "|---|---|---|"

v=$(for _ in $(seq "$runs"); do wall_ms "$bin" --version; done | median)
rss=$(gnu_time "$bin" --version | awk '{print $3}')
echo "| \`--version\` wall, median of $runs | $v ms | \`$bin --version\` |"
echo "| \`--version\` peak resident | $((rss / 1024)) MB | \`/usr/bin/time -f %M $bin --version\` |"

# Since the launcher, the program is isohex-run beside it; before, isohex itself.
program=$(dirname "$bin")/isohex-run
[ -x "$program" ] || program=$bin
echo "| libraries at start, \`isohex\` | $(ldd "$bin" | wc -l) | \`ldd $bin \| wc -l\` |"
echo "| libraries at start, the program | $(ldd "$program" | wc -l) | \`ldd $program \| wc -l\` |"
relocs=$(ISOHEX_HUGEPAGES=0 LD_DEBUG=statistics "$program" --help 2>&1 > /dev/null |
    awk '/number of relocations:/ {n = $NF} END {print n}')
echo "| start-up symbol relocations, the program | $relocs | \`ISOHEX_HUGEPAGES=0 LD_DEBUG=statistics $program --help\` |"

tiny=(mesh tiny.nii.gz --labels -o tiny.vtu --force -q --threads 1)
"$bin" "${tiny[@]}" --report tiny.json > /dev/null 2>&1
pipeline=$($py -c "import json; print(json.load(open('tiny.json'))['timings_s']['total'])")
hexes=$($py -c "import json; print(json.load(open('tiny.json'))['hexes'])")
for _ in $(seq "$runs"); do gnu_time "$bin" "${tiny[@]}"; done > tiny.times
w=$(awk '{print $1}' tiny.times | median)
c=$(awk '{print $2}' tiny.times | median)
m=$(awk '{print $3}' tiny.times | median)
echo "| tiny mesh ($hexes hexes) wall, median of $runs | ${w} s | \`$bin ${tiny[*]}\` |"
echo "| tiny mesh CPU (user + system) | ${c} s | same, GNU time |"
echo "| tiny mesh peak resident | $((m / 1024)) MB | same, GNU time |"
echo "| tiny mesh pipeline (report timings_s.total; includes loading the reader's plugin) | ${pipeline} s | same, \`--report\` |"
echo "| tiny mesh wall - pipeline | $(awk -v a="$w" -v b="$pipeline" 'BEGIN {printf "%.3f", a - b}') s | |"

# The same input 20 times in one batch: each job runs in a forked child.
{ echo "input,output"; for i in $(seq 20); do echo "tiny.nii.gz,batch/tiny$i.vtu"; done; } > batch.csv
read -r w c m < <(gnu_time "$bin" batch batch.csv --labels -q --threads 1 --force)
echo "| batch of 20 tiny jobs wall, per job | $(awk -v a="$w" 'BEGIN {printf "%.3f", a / 20}') s | \`$bin batch batch.csv --labels -q --threads 1 --force\` |"
echo "| batch of 20 tiny jobs CPU, per job | $(awk -v a="$c" 'BEGIN {printf "%.3f", a / 20}') s | same, GNU time |"

mid=(mesh phantoms/sphere.nii.gz --iso 50 --size 1.25 -o sphere.vtu --force -q --threads 2)
read -r w c m < <(gnu_time "$bin" "${mid[@]}" --report sphere.json)
$py - "$w" "$c" "$bin ${mid[*]}" <<'EOF'
import json, sys
r = json.load(open("sphere.json"))
t = r["timings_s"]
stages = ", ".join(f"{k} {v:.3f}" for k, v in t.items() if k != "total")
print(f"| {r['hexes']}-hex mesh wall | {float(sys.argv[1]):.2f} s | `{sys.argv[3]}` |")
print(f"| {r['hexes']}-hex mesh CPU | {float(sys.argv[2]):.2f} s | same, GNU time |")
print(f"| {r['hexes']}-hex mesh stages (s) | {stages} | same, `--report` |")
EOF
