"""The README's Python quick start runs as written and does what it says (a docs-snippet test).

The block under "## Python: simulate → calibrate → apply" is taken from README.md verbatim and executed in a fresh
namespace in a temporary folder (docs/calibration.md carries the same block); a renamed export, a changed signature or a
broken public API fails here, with the README line to fix.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from gyrosim import truth_calibration

ROOT = Path(__file__).resolve().parents[2]
HEADING = "## Python: simulate → calibrate → apply"


def quickstart_block(path: Path = ROOT / "README.md") -> str:
    text = path.read_text(encoding="utf-8")
    assert HEADING in text, f"{path.name} has no section {HEADING!r} (the quick start this test runs)"
    section = text.split(HEADING, 1)[1].split("\n## ", 1)[0]
    m = re.search(r"```python\n(.*?)```", section, re.S)
    assert m, f"no ```python block under {HEADING!r} in {path.name}"
    return m.group(1)


def docs_block(path: Path = ROOT / "docs" / "calibration.md") -> str:
    blocks = re.findall(r"```python\n(.*?)```", path.read_text(encoding="utf-8"), re.S)
    assert blocks, f"{path.name} has no ```python block"
    return blocks[0]


def test_docs_carry_the_same_quickstart():
    assert docs_block() == quickstart_block(), "docs/calibration.md's Python block differs from the README's"


def test_readme_python_quickstart_runs_and_calibrates(tmp_path, monkeypatch, capsys):
    code = quickstart_block()
    monkeypatch.chdir(tmp_path)  # the block writes cal.json to the working folder
    ns: dict = {"__name__": "__quickstart__"}
    exec(compile(code, "README.md (Python quick start)", "exec"), ns)
    out = capsys.readouterr().out
    rec, cal, corrected = ns["rec"], ns["cal"], ns["corrected"]
    assert (tmp_path / "cal.json").is_file() and out.startswith(cal.status)
    assert cal.status != "diverged"  # ok, or inconsistent with its reason; the estimate is usable either way

    err = ns["gyro_error_dps"]
    raw, calibrated = err(rec), err(corrected)
    # the floor: the device's true linear effects removed (noise, bandwidth, non-linearity remain)
    floor = err(truth_calibration(rec).compensate(rec))
    assert calibrated < raw / 5  # the printed claim: most of the error is gone (1.8 → 0.11 °/s on seed 1)
    # what calibrating adds above the floor must be what the estimate's own σ predicts: per axis
    # σ_b² + σ_S²·⟨ω_i²⟩ + σ_G²·⟨ω_j²⟩ (the error terms of ω̃ = (I + S + N(G))ω + b).  6σ rather than
    # 4σ: the hand-blind filter (calibrate()'s default before it took calib run's) had its σ measured 2.4×
    # optimistic here; the hand-aware default inflates its own ×1.6 on this session — the bound holds for both.
    w2 = np.mean(np.asarray(rec.truth.omega_body_rad_s) ** 2, axis=0)
    predicted = np.sqrt(np.mean(cal.bias_std_rad_s ** 2 + cal.scale_factor_std ** 2 * w2
                                + cal.nonorthogonality_std ** 2 * w2.mean()))
    excess = np.radians(np.sqrt(max(calibrated ** 2 - floor ** 2, 0.0)))
    assert excess < 6 * predicted, (excess, predicted)


CLI_HEADING = "## Quick start: the command line"


def cli_block(path: Path = ROOT / "README.md") -> list[str]:
    """The commands of the README's command-line quick start, comments stripped."""
    text = path.read_text(encoding="utf-8")
    assert CLI_HEADING in text, f"{path.name} has no section {CLI_HEADING!r}"
    m = re.search(r"```bash\n(.*?)```", text.split(CLI_HEADING, 1)[1].split("\n## ", 1)[0], re.S)
    assert m, f"no ```bash block under {CLI_HEADING!r} in {path.name}"
    return [line.split("#", 1)[0].strip() for line in m.group(1).splitlines() if line.split("#", 1)[0].strip()]


def test_readme_command_line_quickstart_runs_as_written_and_says_ok(tmp_path, monkeypatch, capsys):
    """Every command of the block, in order, in a fresh folder: exit 0, and ``calib run`` says ``status: ok`` (the
    README's own session was 'inconsistent' with exit 1 while every error sat within 1.8 σ: the inflation rule
    compared an estimate with its limit without the estimate's own sampling range).  ``rerun FILE`` opens a viewer:
    only its file is checked."""
    import shlex

    from gyrosim.cli import main as gyrosim_main

    from calib.app.cli import main as calib_main

    monkeypatch.chdir(tmp_path)
    commands = cli_block()
    assert [c.split()[:2] for c in commands][:4] == [["gyrosim", "simulate"], ["calib", "inspect"], ["calib", "run"],
                                                      ["calib", "apply"]]
    for command in commands:
        prog, *args = shlex.split(command)
        if prog == "rerun":
            assert all((tmp_path / a).is_file() for a in args), command
            continue
        code = {"gyrosim": gyrosim_main, "calib": calib_main}[prog](args)
        out = capsys.readouterr().out
        assert code == 0, f"{command}: exit {code}\n{out}"
        if args[0] == "run":
            assert "status: ok" in out, out


def test_readme_and_docs_links_resolve():
    # the README was split into docs/ (one file per topic): every relative link and figure must
    # still point at a file, and every anchor at a heading of that file
    def anchors(md: Path) -> set[str]:
        heads = re.findall(r"^#+ (.*)$", md.read_text(encoding="utf-8"), re.M)
        return {re.sub(r"[^\w\- ]", "", h.strip().lower()).replace(" ", "-") for h in heads}

    files = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
    assert len(files) > 10
    broken, n = [], 0
    for md in files:
        text = re.sub(r"```.*?```", "", md.read_text(encoding="utf-8"), flags=re.S)
        for target in re.findall(r"\]\(([^)\s]+)\)", text):
            if re.match(r"[a-z]+:", target):
                continue
            n += 1
            path, _, frag = target.partition("#")
            dest = (md.parent / path).resolve() if path else md
            if not dest.exists():
                broken.append(f"{md.relative_to(ROOT)}: {target} (no such file)")
            elif frag and dest.suffix == ".md" and frag not in anchors(dest):
                broken.append(f"{md.relative_to(ROOT)}: {target} (no such heading)")
    assert n > 20 and not broken, "\n".join(broken)
    assert len((ROOT / "README.md").read_text(encoding="utf-8").splitlines()) <= 250  # details go to docs/
