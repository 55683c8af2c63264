#!/usr/bin/python3
"""The table of bench/RESULTS.md's "Split scans" from the JSON files
bench/split_parts.py writes (one per input):

  bench/split_parts_table.py DIR/skull.json DIR/ch2bet.json

Per input: the single run, then each split merged: VTK's scaled Jacobian
(min / mean), the exact hex volume, the boundary nodes' distance to the
scan's isosurface (mean / max), peak memory (single run; every part, the
largest first named), and the largest part's excess over single / N."""
import json
import sys


def row(name, run, sj_min, sj_mean, volume, dist, peak, excess, hexes):
    return (f"| {name} | {run} | {hexes} | {sj_min:.3f} / {sj_mean:.3f} | {volume:,.0f} | "
            f"{dist['mean']:.3f} / {dist['max']:.2f} | {peak} | {excess} |")


def main():
    print("| input | run | hexes per part | SJ min / mean | volume | distance mean / max | peak MB | "
          "largest part - single / N (MB) |")
    print("|---|---|--:|--:|--:|--:|--:|--:|")
    for path in sys.argv[1:]:
        d = json.load(open(path))
        s = d["single"]
        print(row(d["name"], "single", s["sj_min"], s["sj_mean"], s["volume"], s["distance"],
                  f"{d['single_peak_mb']:.0f}", "", f"{s['hexes']:,}"))
        for sp in d["splits"]:
            m, n = sp["merged"], sp["parts"]
            peaks = sp["part_peak_mb"]
            inverted = f" ({m['inverted']} inverted)" if m["inverted"] else ""
            print(row(d["name"], f"{n} parts + merge{inverted}", m["sj_min"], m["sj_mean"], m["volume"],
                      m["distance"], " / ".join(f"{p:.0f}" for p in peaks) + f"; merge {sp['merge_peak_mb']:.0f}",
                      f"{max(peaks) - d['single_peak_mb'] / n:.0f}",
                      " / ".join(f"{h:,}" for h in sp["merge_report"]["hexes_per_part"])))


if __name__ == "__main__":
    main()
