"""The layers stay one-way and estimators are found by registration, not by gyrosim importing calib.

Floors: gyrosim (simulate) → calib (estimate) → score.  gyrosim must run, and find calib's
estimators by name, without ever importing calib: calib registers them in the entry-point group
``gyrosim.estimators`` (pyproject.toml), read by :mod:`gyrosim.plugins`.
"""

from __future__ import annotations

import ast
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from gyrosim import plugins
from gyrosim.errors import GyrosimError
from gyrosim.estimator import ENTRY_POINT_GROUP, load_estimator, registered_estimators

ROOT = Path(__file__).resolve().parents[1]
UPPER_FLOORS = ("calib",)


def _imports_of(path: Path) -> list[tuple[int, str]]:
    """(line, module) of every import in ``path``, at any depth (lazy imports inside functions count),
    and of every ``importlib.import_module("…")`` / ``__import__("…")`` with a literal name."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            out.append((node.lineno, node.module))
        elif isinstance(node, ast.Call) and node.args and isinstance(node.args[0], ast.Constant) \
                and isinstance(node.args[0].value, str):
            f = node.func
            name = f.attr if isinstance(f, ast.Attribute) else f.id if isinstance(f, ast.Name) else ""
            if name in ("import_module", "__import__"):
                out.append((node.lineno, node.args[0].value))
    return out


def test_gyrosim_source_imports_nothing_from_calib():
    modules = sorted((ROOT / "gyrosim").rglob("*.py"))
    assert len(modules) > 20  # the walk sees the package (a wrong ROOT would pass vacuously)
    back_edges = [f"{m.relative_to(ROOT)}:{line} imports {name}"
                  for m in modules for line, name in _imports_of(m)
                  if name.split(".")[0] in UPPER_FLOORS]
    assert not back_edges, "gyrosim must not import the floors above it:\n" + "\n".join(back_edges)


def test_the_import_walk_sees_lazy_and_dynamic_imports(tmp_path):
    # the walker itself must catch the forms a back-edge takes (else the test above cannot fail)
    src = tmp_path / "m.py"
    src.write_text(textwrap.dedent("""
        import importlib
        def f():
            from calib import estimators
            import calib.session.model as k
            return importlib.import_module("calib.app.cli"), __import__("calib")
    """))
    found = {name for _, name in _imports_of(src)}
    assert {"calib", "calib.session.model", "calib.app.cli"} <= found


BLOCKED_RUN = textwrap.dedent("""
    import importlib, importlib.abc, pkgutil, sys

    class Block(importlib.abc.MetaPathFinder):
        def find_spec(self, name, path=None, target=None):
            if name == "calib" or name.startswith("calib."):
                raise ImportError(f"blocked: gyrosim imported {name}")

    sys.meta_path.insert(0, Block())
    import gyrosim
    names = [m.name for m in pkgutil.walk_packages(gyrosim.__path__, "gyrosim.") if not m.name.endswith("__main__")]
    for name in names:
        importlib.import_module(name)
    from gyrosim.cli import build_parser
    build_parser().format_help()
    from gyrosim.estimator import load_estimator, registered_estimators
    assert "kf" in registered_estimators()  # names are read without importing their package
    try:
        load_estimator("kf")
    except Exception as exc:  # the registered target is calib's: refused with a clear message
        print("REFUSED", type(exc).__name__, exc)
    print("MODULES", len(names), "CALIB", sorted(m for m in sys.modules if m.split(".")[0] == "calib"))
""")


def test_gyrosim_imports_and_lists_estimators_with_calib_blocked():
    run = subprocess.run([sys.executable, "-c", BLOCKED_RUN], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    out = run.stdout
    assert "CALIB []" in out, out
    assert int(out.split("MODULES ")[1].split()[0]) > 20
    # asking for calib's estimator while calib cannot be imported is a GyrosimError naming the module
    assert "REFUSED GyrosimError" in out and "cannot import module 'calib.session.registry'" in out, out


@pytest.mark.filterwarnings("ignore:estimator 'smoother' is deprecated:FutureWarning")  # the alias is exported too
@pytest.mark.filterwarnings("ignore:estimator 'kf_lever_arm' is deprecated:FutureWarning")  # the retired name, too
def test_every_estimator_calib_exports_is_registered_and_resolves():
    import calib.session.registry as est

    assert set(registered_estimators()) >= set(est.__all__)
    for name in est.__all__:
        assert load_estimator(name) is getattr(est, name)
    assert load_estimator("calib.session.registry:kf") is est.kf  # the import-path form still works


def test_orientation_estimators_and_the_magnetometer_calibrator_are_registered():
    # gyrosim's orientation campaign reaches calib's filters and calib mag's fit by entry point only
    from gyrosim.orientation import registered_orientation_estimators

    import calib.orientation.estimators as orientation
    from calib.mag import calibrate_magnetometer

    assert set(registered_orientation_estimators()) >= set(orientation._BUILTINS)
    for name in orientation._BUILTINS:
        assert plugins.load("gyrosim.orientation_estimators", name).args == (name,)  # builtin(name), lazily
    assert plugins.load("gyrosim.magnetometer_calibrators", "ellipsoid") is calibrate_magnetometer


def test_registered_names_come_from_the_source_tree_when_metadata_lacks_them(monkeypatch):
    # a checkout on PYTHONPATH, or an editable install whose metadata predates the table
    import calib.session.registry as est

    monkeypatch.setattr(plugins, "_from_metadata", lambda group: [])
    plugins.clear_cache()
    try:
        assert set(registered_estimators()) >= set(est.__all__)
        assert load_estimator("iterated") is est.iterated
    finally:
        plugins.clear_cache()


def test_no_registration_anywhere_is_a_clear_error(monkeypatch, tmp_path):
    monkeypatch.setattr(plugins, "_from_metadata", lambda group: [])
    monkeypatch.setattr(plugins, "SOURCE_TREE_PYPROJECT", tmp_path / "pyproject.toml")  # none there
    plugins.clear_cache()
    try:
        with pytest.raises(GyrosimError, match=r"unknown estimator 'kf'.*none.*pip install -e"):
            load_estimator("kf")
    finally:
        plugins.clear_cache()


def _user_distribution(root: Path, dist: str, module: str, entries: dict[str, str]) -> None:
    """An installed package as importlib.metadata sees one: a module and its .dist-info."""
    (root / f"{module}.py").write_text(textwrap.dedent("""
        from gyrosim.estimator import Estimate

        def zeros(rec):
            return Estimate([0, 0, 0], [0, 0, 0], [0, 0, 0], method="zeros")

        class Factory:
            def __call__(self, rec):
                return zeros(rec)
    """))
    info = root / f"{dist}-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {dist}\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(f"[{ENTRY_POINT_GROUP}]\n"
                                           + "".join(f"{k} = {v}\n" for k, v in entries.items()))


def test_a_users_installed_package_registers_its_own_estimators(monkeypatch, tmp_path, ideal_session):
    _user_distribution(tmp_path, "my_filters", "my_filters_mod",
                       {"my_zeros": "my_filters_mod:zeros", "my_factory": "my_filters_mod:Factory"})
    monkeypatch.syspath_prepend(str(tmp_path))
    plugins.clear_cache()
    try:
        names = registered_estimators()
        assert {"my_zeros", "my_factory", "kf"} <= set(names)  # beside calib's, not instead
        cal = load_estimator("my_factory")(ideal_session)  # a class is instantiated with no arguments
        assert cal.method == "zeros"
        origin = plugins.registered(ENTRY_POINT_GROUP)["my_zeros"][0].origin
        assert origin == "distribution my_filters"
    finally:
        plugins.clear_cache()


def test_a_name_two_packages_register_differently_is_refused(monkeypatch, tmp_path):
    for i, dist in enumerate(("pkg_a", "pkg_b")):
        d = tmp_path / dist
        d.mkdir()
        _user_distribution(d, dist, f"{dist}_mod", {"shared_name": f"{dist}_mod:zeros"})
        monkeypatch.syspath_prepend(str(d))
    plugins.clear_cache()
    try:
        with pytest.raises(GyrosimError, match=r"more than one package") as exc:
            load_estimator("shared_name")
        assert "pkg_a_mod:zeros" in str(exc.value) and "pkg_b_mod:zeros" in str(exc.value)
        assert load_estimator("pkg_b_mod:zeros").__name__ == "zeros"  # the import path disambiguates
    finally:
        plugins.clear_cache()


def test_public_api_exports_resolve():
    import inspect

    import gyrosim

    import calib

    for pkg in (gyrosim, calib):
        missing = [n for n in pkg.__all__ if not hasattr(pkg, n)]
        assert not missing, f"{pkg.__name__}.__all__ names what it does not export: {missing}"
        assert set(pkg.__all__) <= set(dir(pkg))
    # the function, not the module of the same name; the module stays importable by its path
    from gyrosim import simulate

    from calib import calibrate
    from calib.session import paper
    from calib.session.prepare import prepare

    assert inspect.isfunction(calibrate) and calibrate.__module__ == "calib.session.paper"
    assert prepare.__module__ == "calib.session.prepare" and paper.prepare is prepare   # its old home re-exports it
    assert inspect.isfunction(simulate) and simulate.__module__ == "gyrosim.simulate"
    assert calib.Calibration is gyrosim.Calibration  # one result type, defined in gyrosim's floor
    assert calib.run_closeloop.__module__.startswith("calib.closeloop")  # a lazily imported export


EXPORT_ORDER = textwrap.dedent("""
    import inspect, sys
    import gyrosim.errors
    assert "mujoco" not in sys.modules and "gyrosim.simulate" not in sys.modules  # exports load on use
    import gyrosim.simulate          # the submodule first: the import system announces it to the package
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        import calib.calibrate       # the module's old path (calib.compat) announces a module by that name too
    import calib, gyrosim
    from calib import calibrate
    from gyrosim import simulate
    assert inspect.isfunction(gyrosim.simulate) and gyrosim.simulate is simulate
    assert inspect.isfunction(calib.calibrate) and calib.calibrate is calibrate
    assert inspect.ismodule(sys.modules["calib.calibrate"]) and sys.modules["calib.calibrate"].prepare
    assert sys.modules["calib.calibrate"] is sys.modules["calib.session.paper"]  # one module, two names
    print("OK")
""")


def test_exports_do_not_depend_on_import_order_and_load_on_use():
    run = subprocess.run([sys.executable, "-c", EXPORT_ORDER], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0 and run.stdout.strip() == "OK", run.stderr


def _parsers():
    import argparse

    from gyrosim.cli import build_parser as gyrosim_parser

    from calib.app.cli import build_parser as calib_parser

    for build in (gyrosim_parser, calib_parser):
        top = build()
        (sub,) = [a for a in top._actions if isinstance(a, argparse._SubParsersAction)]
        helped = {c.dest: c.help for c in sub._choices_actions}
        yield top, sub.choices, helped


def test_every_cli_command_and_option_has_help_text():
    import argparse

    missing, n_options = [], 0
    for top, commands, helped in _parsers():
        assert len(commands) >= 10
        # `calib --help` lists every command's help line through %-formatting: a bare "%" in a help
        # text crashed it (TypeError) while each sub-command's own --help worked
        assert all(name in top.format_help() for name in helped)
        for parser in commands.values():
            parser.format_help()
        for name, parser in commands.items():
            if not helped.get(name):
                missing.append(f"{top.prog} {name} (the command itself)")
            for action in parser._actions:
                if isinstance(action, argparse._HelpAction):
                    continue
                n_options += 1
                if not action.help or action.help == argparse.SUPPRESS or not action.help.strip():
                    missing.append(f"{top.prog} {name} {'/'.join(action.option_strings) or action.dest}")
    assert n_options > 100  # the walk reached the options (a broken walk would pass vacuously)
    assert not missing, "options without help text (add help=...):\n" + "\n".join(missing)


ISSUE_REF = r"\bissues? #?\d+"


def test_no_issue_numbers_in_code_or_cli_help():
    import re

    pattern = re.compile(ISSUE_REF, re.I)
    assert pattern.search("see issue 7") and pattern.search("(Issues 13)")  # the pattern bites
    hits = [f"{f.relative_to(ROOT)}:{i}: {line.strip()}"
            for pkg in ("gyrosim", "calib") for f in sorted((ROOT / pkg).rglob("*"))
            if f.suffix in (".py", ".toml") and "__pycache__" not in f.parts
            for i, line in enumerate(f.read_text(encoding="utf-8").splitlines(), 1) if pattern.search(line)]
    for top, commands, _ in _parsers():
        hits += [f"{top.prog} {name} --help" for name, p in commands.items() if pattern.search(p.format_help())]
    assert not hits, "issue numbers belong in the tracker, not the code (say what, not which ticket):\n" + "\n".join(
        hits
    )


def test_calib_uses_only_gyrosims_public_names():
    # a private helper imported across the floor (as _nonortho_matrix was, by five modules) is an API
    # in disguise: make it public in its one module instead
    private = []
    for f in sorted((ROOT / "calib").rglob("*.py")):
        for node in ast.walk(ast.parse(f.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom) and node.level == 0 and (node.module or "").startswith("gyrosim"):
                private += [f"{f.relative_to(ROOT)}:{node.lineno} {node.module}.{a.name}"
                            for a in node.names if a.name.startswith("_")]
            elif isinstance(node, ast.Import):
                private += [f"{f.relative_to(ROOT)}:{node.lineno} {a.name}" for a in node.names
                            if a.name.startswith("gyrosim.") and any(p.startswith("_") for p in a.name.split("."))]
    assert not private, "calib imports gyrosim's private names:\n" + "\n".join(private)


def test_one_meaning_per_unit_constant():
    # DEG is π/180 (degrees → rad) in gyrosim.units; a module redefining a unit constant with the
    # opposite meaning (DEG = 180/π once did in the closeloop) is how a factor 3283 error is written
    import re

    from gyrosim import units

    assert units.DEG * units.RAD2DEG == pytest.approx(1.0) and units.DEG == pytest.approx(0.017453292519943295)
    pattern = re.compile(r"^(DEG|RAD2DEG|RAD|DEG_H|HOUR|G0)\s*=", re.M)
    redefined = [f"{f.relative_to(ROOT)}: {m.group(0)}" for pkg in ("gyrosim", "calib")
                 for f in sorted((ROOT / pkg).rglob("*.py")) if f != ROOT / "gyrosim" / "units.py"
                 for m in pattern.finditer(f.read_text(encoding="utf-8"))]
    assert not redefined, "unit constants are defined once, in gyrosim/units.py:\n" + "\n".join(redefined)


# Places that still compare against an effect kind's literal name, and how many times: the
# magnetometer fit's model assembly.  The
# count may only go down; a new switch anywhere else fails here, naming the line.
_KIND_SWITCH_ALLOWANCE = {"calib/closeloop/mag/fit.py": 6}


def test_no_module_outside_the_effects_package_switches_on_effect_names():
    """Knowledge of an effect kind lives on its class (gyrosim/effects/): a comparison of a kind with
    one of the vocabulary's names (``kind == "white_noise"``, ``k in ("bias", …)``, ``"hard_iron" in
    kinds``) elsewhere is a second place to edit when an effect is added."""
    import re

    from gyrosim.effects import EFFECTS

    names = "|".join(sorted(map(re.escape, EFFECTS), key=len, reverse=True))
    lhs = r"(?:\bkind|\bk|\.effect|\.kind)"
    switch = re.compile(rf"""{lhs}\s*(?:==|!=|\bin\b|\bnot in\b)\s*[(\[{{]?\s*["'](?:{names})["']"""
                        rf"""|["'](?:{names})["']\s*(?:\bin\b|\bnot in\b)\s+\w*kinds\b"""
                        rf"""|\bfor k in \(["'](?:{names})["']""")
    found: dict[str, list[str]] = {}
    for top in ("gyrosim", "calib"):
        for path in sorted((ROOT / top).rglob("*.py")):
            rel = path.relative_to(ROOT).as_posix()
            if rel.startswith("gyrosim/effects/"):
                continue
            for i, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
                if switch.search(line):
                    found.setdefault(rel, []).append(f"{rel}:{i}: {line.strip()}")
    over = [hit for rel, hits in found.items() if len(hits) > _KIND_SWITCH_ALLOWANCE.get(rel, 0) for hit in hits]
    assert not over, "switch on effect names outside gyrosim/effects (declare it on the effect class):\n" + "\n".join(
        over
    )
    fewer = {rel: n for rel, n in _KIND_SWITCH_ALLOWANCE.items() if len(found.get(rel, [])) < n}
    assert not fewer, f"fewer name switches than allowed in {fewer}: lower _KIND_SWITCH_ALLOWANCE to match"
