"""Plugins and the launcher (core/include/isohex/core/Plugin.hpp, cli/launcher/).

- `isohex --version`, answered by the launcher, is byte for byte what the
  program isohex-run prints for it;
- a mesh format's plugin is loaded only when that format is read or written:
  with a plugin folder (ISOHEX_PLUGIN_DIR) holding only the .vtu plugin,
  converting .vtu to Abaqus .inp works;
- a missing plugin is one error line naming the plugin file and what to do,
  exit status 1, and no output or temporary file is left behind;
- a damaged plugin file is one error line naming it, saying it could not be
  loaded.

Exits non-zero on any failure and prints what it checked.
"""
import os
import shutil
import subprocess
import sys
import tempfile

from common import ISOHEX

PASSED = []
FAILED = []


def check(cond, what):
    (PASSED if cond else FAILED).append(what)
    print(("ok    " if cond else "FAIL  ") + what, flush=True)
    return cond


def isohex(args, plugin_dir=None):
    env = dict(os.environ)
    if plugin_dir is not None:
        env["ISOHEX_PLUGIN_DIR"] = plugin_dir
    return subprocess.run([ISOHEX] + args, capture_output=True, text=True, env=env, timeout=300)


def block_vtu(folder):
    helper = os.environ.get("ISOHEX_TEST_MESHES", "")
    if not helper:
        sys.exit("make_test_meshes not found: set ISOHEX_TEST_MESHES (ctest does)")
    subprocess.run([helper, folder], check=True, capture_output=True)
    return os.path.join(folder, "block.vtu")


def test_version():
    launcher = isohex(["--version"])
    program = subprocess.run([os.path.join(os.path.dirname(ISOHEX), "isohex-run"), "--version"],
                             capture_output=True, text=True)
    check(launcher.returncode == 0 and launcher.stdout.startswith("isohex ") and "openvdb" in launcher.stdout,
          "isohex --version prints the version and the libraries")
    check(launcher.stdout == program.stdout and program.returncode == 0,
          "the launcher's --version equals isohex-run's")


def test_plugins(folder, build_plugins):
    vtu = block_vtu(folder)
    only_vtu = os.path.join(folder, "only_vtu")
    os.mkdir(only_vtu)
    os.symlink(os.path.join(build_plugins, "libisohex_vtu.so"), os.path.join(only_vtu, "libisohex_vtu.so"))

    out_dir = os.path.join(folder, "out")
    os.mkdir(out_dir)
    inp = os.path.join(out_dir, "block.inp")
    proc = isohex(["convert", vtu, inp], plugin_dir=only_vtu)
    check(proc.returncode == 0 and os.path.getsize(inp) > 0,
          ".vtu to .inp needs only the .vtu plugin " + proc.stderr.strip())

    msh = os.path.join(out_dir, "block.msh")
    proc = isohex(["convert", vtu, msh], plugin_dir=only_vtu)
    err = proc.stderr.strip()
    check(proc.returncode == 1 and err.count("\n") == 0 and "libisohex_msh.so" in err and "missing" in err
          and "ISOHEX_PLUGIN_DIR" in err and "isohex_plugins" in err,
          f"a missing plugin: one error line naming it and what to do ({err})")
    check(sorted(os.listdir(out_dir)) == ["block.inp"], "a missing plugin leaves no output or temporary file")

    empty = os.path.join(folder, "empty")
    os.mkdir(empty)
    proc = isohex(["quality", vtu], plugin_dir=empty)
    check(proc.returncode == 1 and "libisohex_vtu.so" in proc.stderr and "reads and writes .vtu" in proc.stderr,
          "reading .vtu without its plugin names the plugin and what it is for")

    damaged = os.path.join(folder, "damaged")
    os.mkdir(damaged)
    with open(os.path.join(damaged, "libisohex_vtu.so"), "wb") as f:
        f.write(b"not a shared object\n" * 10)
    proc = isohex(["quality", vtu], plugin_dir=damaged)
    err = proc.stderr.strip()
    check(proc.returncode == 1 and err.count("\n") == 0 and "libisohex_vtu.so" in err and "could not be loaded" in err,
          f"a damaged plugin: one error line naming it ({err})")


def main():
    # The build tree's plugins are in BUILD/lib/isohex, beside BUILD/cli/isohex.
    build_plugins = os.path.abspath(os.path.join(os.path.dirname(ISOHEX), "..", "lib", "isohex"))
    folder = tempfile.mkdtemp(prefix="isohex_plugins_")
    try:
        test_version()
        test_plugins(folder, build_plugins)
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    print(f"{len(PASSED)} passed, {len(FAILED)} failed")
    for f in FAILED:
        print("failed: " + f)
    return 1 if FAILED else 0


if __name__ == "__main__":
    sys.exit(main())
