"""bench/run writes its own sections of bench/RESULTS.md again; the sections
other bench scripts added below them (each with its command and figures) must
survive that (bench/results_sections.py), checked on the repository's own
RESULTS.md."""
import os
import sys
import unittest

sys.path.insert(0, os.path.dirname(__file__))
from common import SOURCE  # noqa: E402

sys.path.insert(0, os.path.join(SOURCE, "bench"))
sys.dont_write_bytecode = True
from results_sections import carry_sections, sections  # noqa: E402

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


if __name__ == "__main__":
    unittest.main()
