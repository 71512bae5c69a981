"""Generated snippets in the guides: a result's table pulled into the prose, never typed by hand.

A guide (docs/*.md, README.md) marks a snippet with two comments::

    <!-- result:hand_campaign.md -->
    … (written by the generator: leave it alone) …
    <!-- /result -->

``render_all`` rewrites every such block from the file it names under docs/results/ (its body without the
provenance line and the title, relative links made relative to the guide), followed by one line naming the file
and the commit that wrote it.  ``python -m benchmarks.results`` calls it after each run; ``--render`` alone
re-renders.  ``stale`` lists the blocks whose text differs from what the files give (tests/test_docs.py fails on
them).
"""

from __future__ import annotations

import re
from pathlib import Path

if __package__ in (None, ""):
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks import provenance  # noqa: E402

ROOT = provenance.ROOT
RESULTS = ROOT / "docs" / "results"
BLOCK = re.compile(r"(<!-- result:(?P<name>[\w.\-]+) -->\n)(?P<body>.*?)(<!-- /result -->)", re.S)
LINK = re.compile(r"(\]\()(?P<target>[^)\s#]+)")


def guides(root: Path = ROOT) -> list[Path]:
    """The files that may carry snippets: README.md and docs/*.md."""
    return [root / "README.md", *sorted((root / "docs").glob("*.md"))]


def render(name: str, guide: Path, results: Path = RESULTS) -> str:
    """The snippet text of results file ``name`` as it appears in ``guide``."""
    path = results / name
    if not path.is_file():
        raise FileNotFoundError(f"docs/results/{name} does not exist")
    lines = provenance.body(path).strip("\n").splitlines()
    if lines and lines[0].startswith("# "):
        lines = lines[1:]
    text = "\n".join(lines).strip("\n")
    rel = Path(_relpath(path.parent, guide.parent))

    def fix(m: re.Match) -> str:
        target = m.group("target")
        if re.match(r"[a-z]+:", target) or target.startswith("/"):
            return m.group(0)
        return m.group(1) + _normalise(rel / target)

    text = LINK.sub(fix, text)
    prov = provenance.read(path)
    link = _normalise(rel / name)
    from benchmarks.results import BY_OUTPUT  # the result that writes this file

    how = f"`python -m benchmarks.results --only {BY_OUTPUT[name].name}`" if name in BY_OUTPUT else "its generator"
    state = (f"commit {prov['commit'][:7]}{' (dirty)' if prov.get('dirty') else ''}, {str(prov.get('date'))[:10]}"
             if prov and prov.get("commit") else "written before results were stamped")
    if prov and "before stamping" in (prov.get("inputs") or {}).values():
        state += ", from inputs written before results were stamped"
    return f"{text}\n\n<sub>Generated: [results/{name}]({link}) ({state}); regenerate with {how}.</sub>\n"


def _relpath(target: Path, start: Path) -> str:
    import os

    return os.path.relpath(target, start)


def _normalise(p: Path) -> str:
    import os

    return os.path.normpath(str(p)).replace(os.sep, "/")


def update(guide: Path, results: Path = RESULTS) -> str:
    """``guide``'s text with every snippet re-rendered (a snippet whose file does not exist yet is left as it is:
    :func:`stale` reports it)."""
    text = guide.read_text(encoding="utf-8")

    def one(m: re.Match) -> str:
        if not (results / m.group("name")).is_file():
            return m.group(0)
        return m.group(1) + render(m.group("name"), guide, results) + m.group(4)

    return BLOCK.sub(one, text)


def render_all(root: Path = ROOT, results: Path = RESULTS) -> list[Path]:
    """Re-render the snippets of every guide; returns the guides that changed."""
    changed = []
    for guide in guides(root):
        old = guide.read_text(encoding="utf-8")
        new = update(guide, results)
        if new != old:
            guide.write_text(new, encoding="utf-8")
            changed.append(guide)
    return changed


def stale(root: Path = ROOT, results: Path = RESULTS) -> list[str]:
    """``guide: name (reason)`` for every snippet that is not what its results file renders to."""
    out = []
    for guide in guides(root):
        text = guide.read_text(encoding="utf-8")
        for m in BLOCK.finditer(text):
            try:
                want = render(m.group("name"), guide, results)
            except FileNotFoundError as exc:
                out.append(f"{guide.relative_to(root)}: {m.group('name')} ({exc})")
                continue
            if m.group("body") != want:
                out.append(f"{guide.relative_to(root)}: {m.group('name')} (differs from the results file: "
                           "run python -m benchmarks.results --render)")
    return out
