"""The docs' own rules, checked on every file they govern.

* No words that only made sense to the people writing at the time — a work session ("this round"), a ticket number
  ("issue 12"), a source document's folder number ("seed 001": sources are cited by title) — and no absolute path
  of somebody's machine, in the code, the docs, the benchmarks, the examples or the tests.
* Every file under docs/results/ carries a provenance stamp (benchmarks.provenance): the commit and command line
  that wrote it, or — for a file written before results were stamped — ``"commit": null`` with a note saying how
  to regenerate it; every file the results registry (benchmarks.results) names exists, and every generated block
  of a guide is what its file renders to.
* Every ``calib.…`` / ``gyrosim.…`` dotted name a guide or the README writes in backticks resolves: the module
  imports and the attribute exists, so a rename in the code that leaves a guide stale fails here.
"""

from __future__ import annotations

import importlib
import re
import sys
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:   # benchmarks/ is a package of the checkout, not of the installed distribution
    sys.path.insert(0, str(ROOT))

from benchmarks import provenance  # noqa: E402

SCANNED = ("calib", "gyrosim", "docs", "benchmarks", "examples", "tests")
TEXT_SUFFIXES = {".py", ".md", ".json", ".csv", ".toml", ".yaml", ".yml", ".txt", ".sh", ".cfg", ".ini", ".xml"}

# (what is forbidden, the pattern); this file, which spells them out, is the one file not scanned
_ROUND = r"\bthis\s+round\b"
_ISSUE = r"\bissues?\s+#?\d+"
_SEED = r"\bseeds?[ /]00\d"
_PATHS = r"/work/|/tmp/|/home/|/root/|\b[A-Z]:\\"
FORBIDDEN = (
    ("a work session's name", re.compile(_ROUND, re.IGNORECASE)),
    ("a ticket number", re.compile(_ISSUE, re.IGNORECASE)),
    ("a source document's folder number (cite it by title)", re.compile(_SEED, re.IGNORECASE)),
    ("an absolute path of a machine", re.compile(_PATHS)),
)


def _governed_files() -> list[Path]:
    files = [ROOT / "README.md"]
    for top in SCANNED:
        files += [p for p in (ROOT / top).rglob("*")
                  if p.is_file() and p.suffix in TEXT_SUFFIXES and "__pycache__" not in p.parts
                  and not any(part.startswith(".") for part in p.relative_to(ROOT).parts)]
    return sorted(f for f in files if f.resolve() != Path(__file__).resolve())


def test_no_session_names_ticket_numbers_seed_folders_or_machine_paths():
    found = []
    for path in _governed_files():
        text = path.read_text(encoding="utf-8", errors="replace")
        for what, pattern in FORBIDDEN:
            for m in pattern.finditer(text):
                line = text.count("\n", 0, m.start()) + 1
                found.append(f"{path.relative_to(ROOT)}:{line}: {what}: {m.group(0)!r}")
    assert not found, "\n".join(found[:50])


def test_the_forbidden_patterns_catch_what_they_name():
    # each pattern fails on the words it is for (so the scan above cannot pass by matching nothing)
    samples = ("since this round", "see issue 12", "seed 001's test", "/work/shared/data", "C:\\Users\\x")
    for sample in samples:
        assert any(p.search(sample) for _, p in FORBIDDEN), sample
    assert not any(p.search("a seeded generator, seeds 0..49, the issue of σ, this rounding") for _, p in FORBIDDEN)


def _results_files() -> list[Path]:
    return sorted(p for p in (ROOT / "docs" / "results").rglob("*") if p.is_file())


def test_every_results_file_carries_a_provenance_stamp():
    unstamped, incomplete = [], []
    for path in _results_files():
        prov = provenance.read(path)
        name = str(path.relative_to(ROOT))
        if prov is None:
            unstamped.append(name)
        elif not prov.get("command") or not (prov.get("commit") or prov.get("note")):
            incomplete.append(name)   # a stamp says which command wrote it, and the commit or why there is none
    assert not unstamped, "results without a provenance stamp (python -m benchmarks.results writes them): " + \
        ", ".join(unstamped)
    assert not incomplete, "stamps without a command, or without a commit or a note: " + ", ".join(incomplete)


def test_every_result_the_registry_names_exists_and_each_guide_snippet_names_a_result():
    from benchmarks import results, snippets

    missing = [f"{r.name}: {o}" for r in results.REGISTRY for o in r.outputs
               if not (results.RESULTS / o).exists()]
    assert not missing, "results the registry lists but docs/results lacks: " + ", ".join(missing)
    unknown = []
    for guide in sorted((ROOT / "docs").glob("*.md")):
        for name in re.findall(r"<!-- result:([^ >]+) -->", guide.read_text(encoding="utf-8")):
            if name not in results.BY_OUTPUT:
                unknown.append(f"{guide.name}: {name}")
    assert not unknown, "result blocks naming no registered result: " + ", ".join(unknown)
    # a block is what its file renders to: a table edited by hand in a guide, or a result regenerated without
    # re-rendering, fails here (python -m benchmarks.results --render fixes the latter)
    stale = snippets.stale()
    assert not stale, "\n".join(stale)


# ------------------------------------------------------------------------------------------ dotted names
_CODE = re.compile(r"```.*?```|`[^`\n]+`", re.DOTALL)
_DOTTED = re.compile(r"(?<![\w./-])((?:calib|gyrosim)(?:\.[A-Za-z_]\w*)+)(?::([A-Za-z_]\w*))?")
_RESULT_BLOCK = re.compile(r"<!-- result:[^>]*-->.*?<!-- /result -->", re.DOTALL)


def _entry_point_groups() -> set[str]:
    """Names that are entry-point groups (``gyrosim.estimators``), not modules."""
    data = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    return set(data.get("project", {}).get("entry-points", {}))


def _resolves(dotted: str, attr: str | None) -> bool:
    parts = dotted.split(".")
    for cut in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:cut]))
        except ImportError:
            continue
        try:
            for name in parts[cut:] + ([attr] if attr else []):
                obj = getattr(obj, name)
        except AttributeError:
            return False
        return True
    return False


def _guides() -> list[Path]:
    """README.md, the guides and the notes beside them (docs/results is generated, not read here)."""
    return [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md")), *sorted((ROOT / "docs" / "notes").glob("*.md"))]


def _dotted_names() -> list[tuple[str, str, str | None]]:
    groups = _entry_point_groups()
    out = []
    for path in _guides():
        text = _RESULT_BLOCK.sub("", path.read_text(encoding="utf-8"))   # generated blocks quote their command
        for span in _CODE.findall(text):
            for m in _DOTTED.finditer(span):
                dotted, attr = m.group(1), m.group(2)
                if dotted in groups or re.search(r"\.(py|md|json|h5|csv|rrd|png|toml)$", dotted):
                    continue   # an entry-point group, a file name
                out.append((path.name, dotted, attr))   # (file names are unique across README, docs, notes)
    return out


def test_the_docs_find_some_dotted_names():
    names = {d for _, d, _ in _dotted_names()}
    assert "calib.session.run.run_session" in names   # the README's own; the scan sees backticks


@pytest.mark.parametrize("guide", [p.name for p in _guides()])
def test_dotted_names_in_the_guides_resolve(guide):
    stale = sorted({f"{d}{':' + a if a else ''}" for g, d, a in _dotted_names() if g == guide and not _resolves(d, a)})
    assert not stale, f"{guide} names code that does not exist (renamed or moved?): " + ", ".join(stale)
