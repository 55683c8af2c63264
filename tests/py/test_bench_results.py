"""bench/run writes its own sections of bench/RESULTS.md again; the sections
other bench scripts added below them (each with its command and figures) must
survive that (bench/results_sections.py), checked on the repository's own
RESULTS.md."""
import locale
import os
import subprocess
import sys
import tempfile
import unittest

sys.path.insert(0, os.path.dirname(__file__))
from common import SOURCE  # noqa: E402

sys.path.insert(0, os.path.join(SOURCE, "bench"))
sys.dont_write_bytecode = True
from results_sections import carry_sections, sections, write_results_file  # noqa: E402

NEW = """# isohex benchmark results

Written by `bench/run`.

## Quality and fidelity per input

new figures

## Figures the other issues ask for

new issue figures
"""


class CarrySections(unittest.TestCase):
    def test_other_scripts_sections_survive_and_bench_runs_are_replaced(self):
        with open(os.path.join(SOURCE, "bench", "RESULTS.md")) as f:
            old = f.read()
        _, old_parts = sections(old)
        headings = [h for h, _ in old_parts]
        self.assertIn("## Quality and fidelity per input", headings)
        out = carry_sections(old, NEW)
        self.assertTrue(out.startswith(NEW))
        _, out_parts = sections(out)
        out_headings = [h for h, _ in out_parts]
        # bench/run's own sections once each, with the new text
        self.assertEqual(out_headings.count("## Quality and fidelity per input"), 1)
        self.assertIn("new figures", dict(out_parts)["## Quality and fidelity per input"])
        # every other section of the old file, whole and in its old order
        others = [(h, body) for h, body in old_parts if h not in ("## Quality and fidelity per input",
                                                                   "## Figures the other issues ask for")]
        self.assertGreater(len(others), 5)
        self.assertEqual(out_parts[2:], others)

    def test_a_file_without_other_sections_is_the_new_text(self):
        self.assertEqual(carry_sections(NEW.replace("new", "old"), NEW), NEW)
        self.assertEqual(carry_sections("", NEW), NEW)


    def test_written_as_utf8_after_a_library_set_the_c_locale(self):
        # The Gmsh baseline's library sets the C locale; Python's default text
        # encoding is ASCII from then on, and RESULTS.md has non-ASCII text.
        # Run in a child so the locale change does not leak into other tests.
        with tempfile.TemporaryDirectory() as d:
            path = os.path.join(d, "RESULTS.md")
            with open(path, "w", encoding="utf-8") as f:
                f.write("# old\n\n## Other script \u2264 0.5 \u00d7 Gmsh\n\nkept \u2013 figures\n")
            code = ("import locale, sys; sys.path.insert(0, sys.argv[1]); "
                    "locale.setlocale(locale.LC_ALL, 'C'); "
                    "assert locale.getpreferredencoding(False).lower() not in ('utf-8', 'utf8'), 'C locale is UTF-8'; "
                    "from results_sections import write_results_file; "
                    "write_results_file(sys.argv[2], '# new\\n\\n## Quality \\u2265 0.3\\n')")
            env = dict(os.environ, PYTHONUTF8="0", LC_ALL="C.UTF-8")
            p = subprocess.run([sys.executable, "-c", code, os.path.join(SOURCE, "bench"), path],
                               capture_output=True, text=True, env=env)
            self.assertEqual(p.returncode, 0, p.stderr)
            with open(path, encoding="utf-8") as f:
                out = f.read()
        self.assertTrue(out.startswith("# new\n\n## Quality \u2265 0.3\n"))
        self.assertIn("## Other script \u2264 0.5 \u00d7 Gmsh\n\nkept \u2013 figures\n", out)


if __name__ == "__main__":
    unittest.main()
