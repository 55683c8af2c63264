"""The cohort summary of workflow/Snakefile: one row per scan from the files the
workflow leaves (OUT/NAME.report.json, OUT/estimates/NAME.json, OUT/logs/), written
as OUT/cohort.csv, OUT/cohort.html (a table and an SVG of the scaled Jacobian per
scan) and OUT/failures.txt (each failed scan with its error lines). A scan in
parts (OUT/parts/NAME/K.vtu, merged into OUT/NAME.vtu) has the merge's report, its
parts' SLURM jobs, and fails at the part (or the merge) whose log has the error. Standard
library only: Snakemake runs it in its own interpreter at the end of every run
(onsuccess and onerror), so a failed scan never keeps the others out of it.

    python3 workflow/scripts/cohort.py OUT NAME[:PARTS]...   writes the same files by hand
"""
import csv
import html
import io
import json
import os
import sys

COLUMNS = ["name", "status", "stage", "hexes", "sj_min", "sj_mean", "sj_below_0_2", "inverted",
           "volume_change_percent", "boundary_distance_mean", "seconds", "peak_memory_mb",
           "estimated_hexes", "estimated_peak_memory_mb", "estimated_wall_seconds", "threads",
           "slurm_job", "host", "error", "parts", "part_jobs"]
SUFFIXES = (".nii.gz", ".nii", ".nrrd", ".nhdr", ".mha", ".mhd", ".tif", ".tiff", ".vdb")


def stem(path):
    """A scan's name: its file name without the image extension."""
    base = os.path.basename(os.path.normpath(path))
    for s in SUFFIXES:
        if base.lower().endswith(s):
            return base[: -len(s)]
    return base


def _json(path):
    try:
        with open(path) as f:
            return json.load(f)
    except (OSError, ValueError):
        return None


def _error_lines(path):
    """The lines of a log that say what went wrong: isohex's 'error' lines, a
    JSON log's error events, or else the log's last three lines."""
    try:
        with open(path, errors="replace") as f:
            lines = [line.rstrip("\n") for line in f if line.strip()]
    except OSError:
        return []
    errors = []
    for line in lines:
        try:
            event = json.loads(line)
        except ValueError:
            event = None
        if isinstance(event, dict):
            if event.get("event") == "error" or event.get("level") == "error":
                errors.append(str(event.get("message") or event.get("text") or line))
        elif "error" in line.lower() or "killed" in line.lower():
            errors.append(line)
    return errors or lines[-3:]


def _job(path):
    """The SLURM job id and host a job wrote to its .job file ("local" off SLURM)."""
    try:
        with open(path) as f:
            return (f.read().split() + ["", ""])[:2]
    except OSError:
        return ["", ""]


def _merged(out, name, parts, row):
    """The figures of a scan meshed in parts: the merge's report (quality, validity),
    the parts' seconds added to the merge's, the largest peak of the parts and the
    merge. Volume change and boundary distance are the merge report's fidelity
    (merge --scan measures the merged mesh against the scan); a merge report
    without it gives the volume against the scan's isosurface the parts measured
    (the same in every part only where each read the whole scan; else empty)."""
    reps = [_json(os.path.join(out, "parts", name, f"{k}.report.json")) or {} for k in range(1, parts + 1)]
    merge = _json(os.path.join(out, name + ".report.json")) or {}
    isos = {r.get("fidelity", {}).get("volume_isosurface") for r in reps}
    iso = isos.pop() if len(isos) == 1 else None  # the same whole-scan volume in every part, else unknown
    volume = merge.get("volume", {}).get("total")
    if iso and volume is not None and "fidelity" not in merge:
        row["volume_change_percent"] = 100.0 * (volume - iso) / iso
    seconds = sum(r.get("timings_s", {}).get("total", 0) for r in reps) + merge.get("merge", {}).get("seconds", 0)
    peaks = [r.get("peak_memory_mb", 0) for r in reps] + [merge.get("peak_memory_mb", 0)]
    row.update(seconds=round(seconds, 3), peak_memory_mb=max(peaks))


def _part_failure(out, name, parts):
    """(stage, error) of the parts that failed (their estimate or their mesh job), or
    None: the stages as "part K/N" (or "estimate part K/N"), comma-separated, and
    each one's error lines, each after its part's stage."""
    stages, errors = [], []
    logs = os.path.join(out, "logs", "parts", name)
    for k in range(1, parts + 1):
        if os.path.exists(os.path.join(out, "parts", name, f"{k}.vtu")):
            continue
        log = os.path.join(logs, f"{k}.estimate.log")
        stage = f"estimate part {k}/{parts}"
        if os.path.exists(os.path.join(out, "estimates", "parts", name, f"{k}.json")) or not os.path.exists(log):
            log, stage = os.path.join(logs, f"{k}.log.jsonl"), f"part {k}/{parts}"
        if os.path.exists(log):
            stages.append(stage)
            errors += [f"{stage}: {e}" for e in _error_lines(log)]
    return (", ".join(stages), " | ".join(errors)) if stages else None


def scan_row(out, name, parts=1):
    """One scan's row: done (with its report's figures), failed (with the stage
    and error lines) or not run. A scan in `parts` parts: see _merged and _part_failure."""
    row = dict.fromkeys(COLUMNS, "")
    row["name"] = name
    if parts > 1:  # the parts' SLURM jobs ("-" for a part not run), done or not
        row["parts"] = parts
        row["part_jobs"] = " ".join(_job(os.path.join(out, "logs", "parts", name, f"{k}.job"))[0] or "-"
                                    for k in range(1, parts + 1))
    est = _json(os.path.join(out, "estimates", name + ".json"))
    if est:
        row.update(estimated_hexes=est.get("hexes", ""), estimated_peak_memory_mb=est.get("peak_memory_mb", ""),
                   estimated_wall_seconds=est.get("wall_seconds", ""), threads=est.get("threads", ""))
    row["slurm_job"], row["host"] = _job(os.path.join(out, "logs", name + ".job"))
    rep = _json(os.path.join(out, name + ".report.json"))
    if rep and os.path.exists(os.path.join(out, name + ".vtu")):
        sj = rep.get("scaled_jacobian", {})
        fid = rep.get("fidelity", {})
        row.update(status="done", hexes=rep.get("hexes", ""), sj_min=sj.get("min", ""), sj_mean=sj.get("mean", ""),
                   sj_below_0_2=sj.get("below_0_2", ""), inverted=sj.get("inverted", ""),
                   volume_change_percent=fid.get("volume_change_percent", ""),
                   boundary_distance_mean=fid.get("boundary_distance_mean", ""),
                   seconds=rep.get("timings_s", {}).get("total", ""), peak_memory_mb=rep.get("peak_memory_mb", ""))
        if parts > 1:
            _merged(out, name, parts, row)
        return row
    mesh_log = os.path.join(out, "logs", name + ".log.jsonl")
    estimate_log = os.path.join(out, "logs", name + ".estimate.log")
    part_failure = _part_failure(out, name, parts) if parts > 1 else None
    if not est and os.path.exists(estimate_log):
        row.update(status="failed", stage="estimate", error=" | ".join(_error_lines(estimate_log)))
    elif part_failure:
        row.update(status="failed", stage=part_failure[0], error=part_failure[1])
    elif parts > 1 and os.path.exists(os.path.join(out, "logs", name + ".merge.log")):
        row.update(status="failed", stage="merge",
                   error=" | ".join(_error_lines(os.path.join(out, "logs", name + ".merge.log"))))
    elif os.path.exists(mesh_log):
        row.update(status="failed", stage="mesh", error=" | ".join(_error_lines(mesh_log)))
    else:
        row.update(status="not run")
    return row


def _svg(rows):
    """Bars of the scaled Jacobian per meshed scan (min dark, mean light); failed scans marked."""
    bar_h, gap, left, width = 14, 6, 160, 400
    height = len(rows) * (bar_h + gap) + 30
    parts = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{left + width + 80}" height="{height}" '
             'font-family="sans-serif" font-size="11">']
    for tick in (0, 0.2, 0.5, 1.0):
        x = left + tick * width
        parts.append(f'<line x1="{x}" y1="0" x2="{x}" y2="{height - 20}" stroke="#ccc"/>'
                     f'<text x="{x}" y="{height - 6}" text-anchor="middle">{tick}</text>')
    for i, r in enumerate(rows):
        y = i * (bar_h + gap) + 4
        label = r["name"] + (f" ({r['parts']} parts)" if r["parts"] else "")
        parts.append(f'<text x="{left - 6}" y="{y + bar_h - 3}" text-anchor="end">{html.escape(label)}</text>')
        if r["status"] == "done":
            mean, low = float(r["sj_mean"]), max(float(r["sj_min"]), 0.0)
            parts.append(f'<rect x="{left}" y="{y}" width="{mean * width:.1f}" height="{bar_h}" fill="#9ecae1"/>'
                         f'<rect x="{left}" y="{y}" width="{low * width:.1f}" height="{bar_h}" fill="#3182bd"/>'
                         f'<text x="{left + mean * width + 4:.1f}" y="{y + bar_h - 3}">{mean:.2f}</text>')
        else:
            parts.append(f'<text x="{left + 4}" y="{y + bar_h - 3}" fill="#c00">{html.escape(r["status"])}'
                         f'{" at " + html.escape(r["stage"]) if r["stage"] else ""}</text>')
    parts.append("</svg>")
    return "".join(parts)


def _html(rows):
    done = sum(r["status"] == "done" for r in rows)
    head = "".join(f"<th>{c}</th>" for c in COLUMNS)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(str(r[c]))}</td>" for c in COLUMNS) + "</tr>" for r in rows)
    return ("<!DOCTYPE html><html><head><meta charset=\"utf-8\"><title>isohex cohort</title>"
            "<style>body{font-family:sans-serif}table{border-collapse:collapse;font-size:12px}"
            "td,th{border:1px solid #ccc;padding:2px 6px}</style></head><body>"
            f"<h1>isohex cohort: {done} of {len(rows)} scans meshed</h1>"
            "<p>Scaled Jacobian per scan: minimum (dark) and mean (light, with its value).</p>"
            f"{_svg(rows)}<table><tr>{head}</tr>{body}</table></body></html>\n")


def _write(path, text):
    """Whole or not at all: a temporary beside the file, renamed over it."""
    tmp = path + ".tmp"
    with open(tmp, "w", newline="") as f:
        f.write(text)
    os.replace(tmp, path)


def summarize(out, names, parts=None):
    """Writes OUT/cohort.csv, OUT/cohort.html and OUT/failures.txt; returns the rows.
    `parts`: name -> the number of parts a scan is meshed in (absent: 1, whole)."""
    parts = parts or {}
    rows = [scan_row(out, n, parts.get(n, 1)) for n in sorted(names)]
    os.makedirs(out, exist_ok=True)
    table = io.StringIO()
    writer = csv.DictWriter(table, fieldnames=COLUMNS, lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    _write(os.path.join(out, "cohort.csv"), table.getvalue())
    _write(os.path.join(out, "cohort.html"), _html(rows))
    failed = [r for r in rows if r["status"] != "done"]
    _write(os.path.join(out, "failures.txt"),
           "".join(f"{r['name']}: {r['status']}{' at ' + r['stage'] if r['stage'] else ''}: {r['error']}\n"
                   for r in failed))
    print(f"cohort: {len(rows) - len(failed)} of {len(rows)} scans meshed; {os.path.join(out, 'cohort.html')}"
          + (f"; failures in {os.path.join(out, 'failures.txt')}" if failed else ""), file=sys.stderr)
    return rows


if __name__ == "__main__":
    if len(sys.argv) < 3:
        sys.exit("usage: cohort.py OUT NAME[:PARTS]...")
    scans = dict((a.rsplit(":", 1) + ["1"])[:2] if ":" in a else (a, "1") for a in sys.argv[2:])
    summarize(sys.argv[1], scans, {n: int(k) for n, k in scans.items()})
