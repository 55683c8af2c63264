#!/usr/bin/python3
"""Times one command line for several programs, interleaved (A, B, A, B, ...)
so that a change in the machine's load falls on all of them alike.

    bench/interleaved.py [--runs N] [--env NAME=VALUE ...] --args "ARGS" PROGRAM...

Per program: the median and least wall time (from Python, fork and exec
included) and the mean CPU time (user + system, from getrusage of the
children) of N runs; output is discarded. Used for the before/after start-up
figures in RESULTS.md, e.g.

    bench/interleaved.py --runs 40 --args "mesh /nonexist.nii.gz -o x.vtu" OLD/cli/isohex-run NEW/cli/isohex-run
    bench/interleaved.py --runs 9 --env LD_PRELOAD=/lib/x86_64-linux-gnu/libopenvdb.so.10.0 --args "" /bin/true
"""
import argparse
import os
import resource
import shlex
import statistics
import subprocess
import time


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=9)
    ap.add_argument("--env", action="append", default=[], help="NAME=VALUE set for every run")
    ap.add_argument("--args", default="", help="the command line after the program, as one string")
    ap.add_argument("programs", nargs="+")
    a = ap.parse_args()
    env = dict(os.environ)
    for item in a.env:
        name, _, value = item.partition("=")
        env[name] = value
    args = shlex.split(a.args)
    wall = {p: [] for p in a.programs}
    cpu = {p: 0.0 for p in a.programs}
    for _ in range(a.runs):
        for p in a.programs:
            before = resource.getrusage(resource.RUSAGE_CHILDREN)
            t = time.perf_counter()
            subprocess.run([p] + args, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            wall[p].append(time.perf_counter() - t)
            after = resource.getrusage(resource.RUSAGE_CHILDREN)
            cpu[p] += (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    print(f"load average {os.getloadavg()[0]:.2f}, {a.runs} runs each, interleaved")
    for p in a.programs:
        print(f"{p}: wall median {statistics.median(wall[p]) * 1e3:.1f} ms, least {min(wall[p]) * 1e3:.1f} ms, "
              f"CPU mean {cpu[p] / a.runs * 1e3:.1f} ms")


if __name__ == "__main__":
    main()
