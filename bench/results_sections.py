"""Keeping the sections other scripts added to a results file when bench/run writes it again.

bench/run writes its own sections of bench/RESULTS.md; other scripts in bench/
(split_parts_table.py, adaptive_vs_uniform.py, optimiser_start.py ...) add
sections of their own below them, each naming its command. Writing the file
again must not lose those: every `## ` section of the old file whose heading
bench/run does not write is carried over, in its old order, after the new text.

The file is read and written as UTF-8 whatever the process's locale: the Gmsh
baseline's library sets the C locale when it starts, after which Python's
default text encoding is ASCII, and RESULTS.md has non-ASCII characters.
"""
import os


def sections(text):
    """The text before the first `## ` heading, then (heading line, section text) pairs in order."""
    head, parts, current = [], [], None
    for line in text.splitlines(keepends=True):
        if line.startswith("## "):
            current = [line.rstrip("\n"), [line]]
            parts.append(current)
        elif current is None:
            head.append(line)
        else:
            current[1].append(line)
    return "".join(head), [(h, "".join(body)) for h, body in parts]


def carry_sections(old, new):
    """`new`, then every section of `old` whose `## ` heading `new` does not have."""
    _, new_parts = sections(new)
    written = {h for h, _ in new_parts}
    _, old_parts = sections(old)
    kept = [body for h, body in old_parts if h not in written]
    if not kept:
        return new
    out = new if new.endswith("\n") else new + "\n"
    for body in kept:
        out += ("\n" if not out.endswith("\n\n") else "") + body
    return out


def write_results_file(path, new):
    """Writes `new` to `path`, carrying the sections of the file there (carry_sections), as UTF-8."""
    if os.path.exists(path):
        with open(path, encoding="utf-8") as fh:
            new = carry_sections(fh.read(), new)
    with open(path, "w", encoding="utf-8") as fh:
        fh.write(new)
