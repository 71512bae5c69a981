"""Copy a campaign's summary files into docs/results, and render a campaign summary as a Markdown table.

    python benchmarks/collect.py CAMPAIGN_DIR summary.csv:campaign_summary.csv error_vs_severity.png --to docs/results
    python benchmarks/collect.py --campaign-table docs/results/campaign_summary.csv
    python benchmarks/collect.py --section out/report.md "Attitude validation"   # one section of a report

``SRC[:DST]``: the file SRC of the campaign folder, written as DST (default: the same name).  The runner
(``python -m benchmarks.results``) stamps what lands in docs/results; this script only copies and renders.
"""

from __future__ import annotations

import argparse
import csv
import io
import shutil
import sys
from pathlib import Path

HANDS = ("ideal", "steady", "typical", "shaky")


def campaign_table(path: str | Path) -> str:
    """``gyrosim campaign``'s summary.csv as the table of docs/campaigns.md: per hand and estimator the RMS errors
    (S and G in % of the nominal sensitivity, bias in °/s) with their 95 % intervals and the failures (Wilson 95 %)."""
    text = "".join(line for line in Path(path).read_text(encoding="utf-8").splitlines(keepends=True)
                   if not line.startswith("#"))
    rows = list(csv.DictReader(io.StringIO(text)))
    lines = ["| hand (ext. acc. RMS) | estimator | S error RMS % [95 %] | G error RMS % [95 %] | bias error RMS °/s | "
             "failed or diverged [95 %] |", "|" + "---|" * 6]
    order = {h: i for i, h in enumerate(HANDS)}
    for r in sorted(rows, key=lambda r: (order.get(r["hand"], 9), float(r["severity"]))):
        g = lambda k: float(r[k])  # noqa: E731
        acc = f" ({g('ext_acc_rms_m_s2'):.3f} m/s²)" if r.get("ext_acc_rms_m_s2") else ""
        sev = f", severity {g('severity'):g}" if g("severity") != 1.0 else ""
        cells = [f"{r['hand']}{sev}{acc}", f"`{r['estimator']}`"]
        for k in ("S_pct", "G_pct"):
            cells.append(f"{g('rms_' + k):.3g} [{g('rms_' + k + '_lo'):.3g}, {g('rms_' + k + '_hi'):.3g}]"
                         if r.get("rms_" + k) else "—")
        cells.append(f"{g('rms_bias_deg_s'):.4f}" if r.get("rms_bias_deg_s") else "—")
        cells.append(f"{r['failed']}/{r['n']} [{100 * g('failure_rate_lo'):.1f}, {100 * g('failure_rate_hi'):.1f} %]")
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def section(path: str | Path, heading: str) -> str:
    """The section of a Markdown file whose heading starts with ``heading`` (without the heading line)."""
    lines = Path(path).read_text(encoding="utf-8").splitlines()
    for i, line in enumerate(lines):
        if line.startswith("#") and line.lstrip("#").strip().startswith(heading):
            level = len(line) - len(line.lstrip("#"))
            end = next((j for j in range(i + 1, len(lines))
                        if lines[j].startswith("#") and len(lines[j]) - len(lines[j].lstrip("#")) <= level), len(lines))
            return "\n".join(lines[i + 1:end]).strip()
    raise SystemExit(f"{Path(path).name}: no section '{heading}'")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folder", nargs="?", help="the campaign's output folder")
    ap.add_argument("files", nargs="*", help="SRC[:DST] names inside the folder")
    ap.add_argument("--to", help="destination folder (docs/results)")
    ap.add_argument("--campaign-table", help="print this summary.csv as a Markdown table instead")
    ap.add_argument("--section", nargs=2, metavar=("FILE", "HEADING"), help="print one section of a Markdown file")
    a = ap.parse_args(argv)
    if a.section:
        print(section(*a.section))
        return 0
    if a.campaign_table:
        print(campaign_table(a.campaign_table))
        return 0
    if not (a.folder and a.files and a.to):
        ap.error("give the campaign folder, the files and --to")
    for item in a.files:
        src, _, dst = item.partition(":")
        source = Path(a.folder) / src
        if not source.is_file():
            there = ", ".join(sorted(p.name for p in Path(a.folder).iterdir()))
            print(f"{source.name}: not in the campaign folder ({there})", file=sys.stderr)
            return 2
        shutil.copyfile(source, Path(a.to) / (dst or src))
    return 0


if __name__ == "__main__":
    sys.exit(main())
