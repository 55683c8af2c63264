#!/usr/bin/python3
"""What the heap holds at isohex's peak, by the isohex function that allocated it.

  bench/memory_peak.py [--isohex-run PATH] [--work DIR] -- MESH ARGUMENTS
  bench/memory_peak.py --analyse FILE.zst

Runs `isohex-run mesh MESH ARGUMENTS` in one process (ISOHEX_ISOLATE=0) under heaptrack
(Debian's `heaptrack`), or reads a heaptrack file it wrote, and prints the heap at its
highest total (heaptrack_print's "peak" flame graph cost) grouped by the innermost two
isohex functions on each allocation's stack: which stage holds which arrays at the peak.
Heaptrack sees malloc and new; memory mapped directly (huge-page buffers) and the
libraries' code are not in it, so the total is below the peak resident set size.
A run under heaptrack takes several times as long as without it.
"""
import argparse
import collections
import os
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)


def peak_by_function(zst, depth=2):
    """(total bytes at peak, Counter of 'inner < outer' isohex frames -> bytes)."""
    stacks = zst + ".peak.txt"
    subprocess.run(["heaptrack_print", "-f", zst, "-p", "0", "-a", "0", "-T", "0",
                    "--flamegraph-cost-type", "peak", "-F", stacks],
                   check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    total, by = 0, collections.Counter()
    with open(stacks) as f:
        for line in f:
            stack, _, n = line.rstrip().rpartition(" ")
            n = int(n)
            total += n
            frames = [fr.split("(")[0] for fr in stack.split(";") if "isohex" in fr]
            by[" < ".join(reversed(frames[-depth:])) if frames else "(outside isohex)"] += n
    return total, by


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--isohex-run", default=os.path.join(ROOT, "build/cli/isohex-run"))
    ap.add_argument("--work", default=f"/tmp/isohex-memory-peak-{os.getuid()}")
    ap.add_argument("--analyse", help="a heaptrack .zst file to read instead of running")
    ap.add_argument("--top", type=int, default=15)
    ap.add_argument("mesh_args", nargs="*")
    a = ap.parse_args()
    zst = a.analyse
    if not zst:
        if not a.mesh_args:
            sys.exit("memory_peak: give the mesh arguments after --, or --analyse FILE.zst")
        os.makedirs(a.work, exist_ok=True)
        base = os.path.join(a.work, "heaptrack")
        env = dict(os.environ, ISOHEX_ISOLATE="0")
        subprocess.run(["heaptrack", "-o", base, a.isohex_run, "mesh", *a.mesh_args], env=env, check=True,
                       stdout=subprocess.DEVNULL)
        zst = base + ".zst"
    total, by = peak_by_function(zst)
    print(f"heap at peak: {total / 1048576:,.0f} MB ({zst})\n")
    print("| MB at peak | allocated in (innermost isohex function < its caller) |")
    print("|--:|---|")
    for key, n in by.most_common(a.top):
        if n >= 1048576:
            print(f"| {n / 1048576:,.1f} | `{key}` |")


if __name__ == "__main__":
    main()
