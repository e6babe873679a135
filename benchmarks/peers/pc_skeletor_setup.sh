#!/usr/bin/env bash
# Set up the isolated venv for the pc-skeletor peer (benchmarks/peers/pc_skeletor_run.py).
#
#   bash benchmarks/peers/pc_skeletor_setup.sh        # idempotent: skips when already set up
#
# Creates benchmarks/peers/.venv-pcs (git-ignored) and never touches the project's .venv.
#
# Why not a plain `pip install pc-skeletor==1.0.0`: its pinned dependency mistree==1.2.0 is an
# sdist only (no Linux wheel) whose setup.py needs numpy.distutils + a Fortran compiler, so it
# fails to build on Python 3.11 ("No module named 'numpy'" / no gfortran). pc-skeletor 1.0.0
# also lists dgl and torch, but no module of pc_skeletor 1.0.0 imports either (they are for a
# Point2Skeleton model that is not in this release), and the Laplacian-based contraction (LBC)
# path imports only: numpy, scipy, matplotlib, imageio, open3d, robust_laplacian, mistree,
# networkx, tqdm. So: pc-skeletor with --no-deps, plus those, with mistree==2.0.0 - a pure
# Python (numba) rewrite of 1.2.0's Fortran kernels with the same GetMST/get_stats API.
#
# Prints one line and exits non-zero when it cannot set up (details in .venv-pcs/setup.log).
set -u

HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
VENV="$HERE/.venv-pcs"
PY_BIN="${PCS_PYTHON:-python3.11}"
PIP_SPECS=(
  "pc-skeletor==1.0.0"
)
DEP_SPECS=(
  "mistree==2.0.0"
  numpy scipy matplotlib imageio open3d robust-laplacian networkx tqdm
)
CHECK='from pc_skeletor.laplacian import LBC; import open3d, robust_laplacian, mistree, networkx'

fail() { echo "pc-skeletor setup FAILED: $*" >&2; exit 1; }

if [ -x "$VENV/bin/python" ] && "$VENV/bin/python" -c "$CHECK" >/dev/null 2>&1; then
  echo "pc-skeletor peer venv already set up: $VENV"
  exit 0
fi

command -v "$PY_BIN" >/dev/null 2>&1 || fail "$PY_BIN not found (set PCS_PYTHON to a Python 3.11 interpreter)"

if [ ! -x "$VENV/bin/python" ]; then
  "$PY_BIN" -m venv "$VENV" >/dev/null 2>&1 || fail "'$PY_BIN -m venv $VENV' failed"
fi
LOG="$VENV/setup.log"
: >"$LOG"

"$VENV/bin/python" -m pip install "${DEP_SPECS[@]}" >>"$LOG" 2>&1 \
  || fail "pip install of the LBC dependencies (${DEP_SPECS[*]}) failed; see $LOG"
"$VENV/bin/python" -m pip install --no-deps "${PIP_SPECS[@]}" >>"$LOG" 2>&1 \
  || fail "pip install --no-deps ${PIP_SPECS[*]} failed; see $LOG"
"$VENV/bin/python" -c "$CHECK" >>"$LOG" 2>&1 \
  || fail "installed, but 'from pc_skeletor.laplacian import LBC' does not import; see $LOG"

echo "pc-skeletor peer venv ready: $VENV ($("$VENV/bin/python" -c 'import importlib.metadata as m; print(", ".join(p + " " + m.version(p) for p in ("pc-skeletor", "open3d", "robust-laplacian", "mistree", "numpy", "scipy")))'))"
