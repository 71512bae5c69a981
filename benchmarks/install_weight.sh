#!/usr/bin/env bash
# What `pip install .` brings into a fresh virtual environment: packages and MB of site-packages.
#   bash benchmarks/install_weight.sh [SOURCE_TREE] [VENV_DIR]     # defaults: this checkout, a temporary folder
# Prints one line: the commit of the tree (when it is a git checkout), the package count (pip list, the
# project and pip/setuptools included) and the MB of site-packages.  Minutes: every wheel is downloaded or
# taken from pip's cache.  Compare two commits with `git worktree add` or `git archive` into two folders.
set -euo pipefail
SRC=${1:-$(cd "$(dirname "$0")/.." && pwd)}
V=${2:-$(mktemp -d)/venv}
python -m venv "$V"
"$V/bin/pip" install -q "$SRC"
n=$("$V/bin/pip" list --format=freeze | wc -l)
mb=$(du -sm "$V"/lib/python3*/site-packages | cut -f1)
commit=$(git -C "$SRC" rev-parse --short HEAD 2>/dev/null || echo "not a git checkout")
echo "tree $SRC ($commit): $n packages, $mb MB of site-packages ($(date -u '+%Y-%m-%d %H:%M UTC'))"
