"""``calib`` command line: the parser and the entry point; the commands live one module per group in
:mod:`calib.app.commands`, each a thin layer over one library call.

``calib --help`` lists the commands a person calibrating an IMU needs; the research and benchmark commands are
under ``calib lab`` (:mod:`calib.app.commands.lab`).  Their former top-level spellings (``calib montecarlo`` …)
still run, hidden from the help, with a one-line note on stderr naming the new spelling.  Every command exits
with the one table of :data:`gyrosim.cli.EXIT_CODES` (0 ok, 1 done but not ok, 2 bad input, 3 internal error).
"""

from __future__ import annotations

import argparse
import sys

from gyrosim.cli import EXIT_CODES_HELP, run_cli

from calib import __version__
from calib.app.commands import closeloop, instruments, lab, mag, noise, session, temperature

__all__ = ["build_parser", "main"]

# the command groups in the order of calib --help (lab last)
GROUPS = (session, noise, temperature, closeloop, mag, instruments, lab)


class _HelpFormatter(argparse.RawDescriptionHelpFormatter):
    """The commands listed one per line under their group's title (without the ``COMMAND`` placeholder line
    argparse puts above them); description and epilog as written."""

    def __init__(self, prog: str) -> None:
        super().__init__(prog, max_help_position=15)

    def _format_action(self, action: argparse.Action) -> str:
        if isinstance(action, argparse._SubParsersAction):
            return "".join(self._format_action(a) for a in action._get_subactions())
        return super()._format_action(action)


def build_parser() -> argparse.ArgumentParser:
    """The ``calib`` command line's parser: one subcommand per job, each bound to the ``cmd_*`` function of its
    group's module that runs it; ``lab`` holds the research and benchmark commands."""
    p = argparse.ArgumentParser(
        prog="calib", formatter_class=_HelpFormatter, epilog=EXIT_CODES_HELP)
    p.add_argument("--version", action="version", version=f"calib {__version__}")
    sub = p.add_subparsers(dest="command", required=True, title="commands", metavar="COMMAND")
    for group in GROUPS:
        group.add_parsers(sub)
    return p


def _moved(argv: list[str]) -> list[str]:
    """``argv`` with a former top-level spelling of a lab command (``calib montecarlo``) moved under ``lab``,
    saying so on stderr."""
    if argv and argv[0] in lab.COMMANDS:
        print(f"warning: calib {argv[0]} is deprecated: use calib lab {argv[0]} (the same command; research and "
              "benchmark commands live under calib lab)", file=sys.stderr)
        return ["lab", *argv]
    return argv


def main(argv: list[str] | None = None) -> int:
    """Run the ``calib`` command line on ``argv`` (default ``sys.argv[1:]``) and return its exit code
    (:func:`gyrosim.cli.run_cli`)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    return run_cli(build_parser(), _moved(argv))


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
