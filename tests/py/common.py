"""Shared helpers for the Python end-to-end tests (run by ctest with Debian's /usr/bin/python3)."""
import os
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
    d = tempfile.mkdtemp(prefix=f"isohex_{name}_")
    return d
