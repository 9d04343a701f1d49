#!/usr/bin/env bash
# Build the side environment that runs DexGraspBench's own evaluator, outside dexaug's repo and venv.
#
# Usage: setup.sh [VENV_DIR] [DGB_SOURCE] [MENAGERIE_ROOT]
#   VENV_DIR        where the venv goes (default /tmp/exp/dgb-venv); DGB's source is extracted into
#                   VENV_DIR/dgb-src
#   DGB_SOURCE      a DexGraspBench git directory (bare mirror or clone) or an extracted source tree
#                   (default /work/.mirror/JYChen18+DexGraspBench/repo)
#   MENAGERIE_ROOT  a MuJoCo Menagerie checkout: DGB's Shadow asset takes its meshes from the
#                   submodule third_party/mujoco_menagerie (default $MENAGERIE_ROOT, else
#                   /work/shared/assets/menagerie)
#
# Why a side venv: DGB pins MuJoCo 3.3.2 and numpy 1.26.4 while dexaug runs a newer MuJoCo; the
# comparison must run DGB's code under its own pins. The other packages are those DGB's README
# installs and its `task` package imports when the evaluator is imported (torch for
# util/rot_util.py, matplotlib and scikit-learn for task/statistic.py, usd-core for
# task/vis_usd.py, omegaconf for its configs); the fc evaluation itself uses only the numpy,
# scipy, mujoco, transforms3d and qpsolvers parts. A CPU torch is enough. Python 3.11 instead of
# DGB's suggested 3.10: the pinned wheels exist for both.
set -euo pipefail

VENV_DIR="${1:-/tmp/exp/dgb-venv}"
DGB_SOURCE="${2:-/work/.mirror/JYChen18+DexGraspBench/repo}"
MENAGERIE="${3:-${MENAGERIE_ROOT:-/work/shared/assets/menagerie}}"
PYTHON="${PYTHON:-python3.11}"

if [ ! -e "$DGB_SOURCE" ]; then
    echo "setup.sh: DexGraspBench source not found at $DGB_SOURCE (pass a git directory or a source tree)" >&2
    exit 2
fi
if [ ! -d "$MENAGERIE/shadow_hand/assets" ]; then
    echo "setup.sh: no Menagerie Shadow Hand meshes at $MENAGERIE/shadow_hand/assets (pass MENAGERIE_ROOT)" >&2
    exit 2
fi

"$PYTHON" -m venv "$VENV_DIR"
PIP="$VENV_DIR/bin/python -m pip"
$PIP install --quiet --upgrade pip
$PIP install --quiet "numpy==1.26.4" "mujoco==3.3.2" "scipy<1.16" trimesh transforms3d imageio \
    "qpsolvers[clarabel]" hydra-core matplotlib scikit-learn usd-core
# torch: a CPU wheel (a local find-links wheel, else the PyTorch CPU index) rather than PyPI's CUDA build
if $PIP install --quiet --no-index --no-deps torch 2>/dev/null; then
    # the local wheel came without its pure-Python dependencies: pip adds those from the index
    $PIP install --quiet "torch==$("$VENV_DIR/bin/python" -m pip show torch | sed -n 's/^Version: //p')"
else
    $PIP install --quiet torch --index-url https://download.pytorch.org/whl/cpu || $PIP install --quiet torch
fi
$PIP install --quiet "numpy==1.26.4"   # keep DGB's pin whatever a resolver did

SRC_DIR="$VENV_DIR/dgb-src"
rm -rf "$SRC_DIR"
mkdir -p "$SRC_DIR"
if [ -f "$DGB_SOURCE/src/task/eval_func/fc_mocap.py" ]; then
    cp -r "$DGB_SOURCE/." "$SRC_DIR/"
else
    git -C "$DGB_SOURCE" archive HEAD | tar -x -C "$SRC_DIR"
    git -C "$DGB_SOURCE" rev-parse HEAD > "$SRC_DIR/COMMIT"
fi
rm -rf "$SRC_DIR/third_party/mujoco_menagerie"
mkdir -p "$SRC_DIR/third_party"
ln -s "$(cd "$MENAGERIE" && pwd)" "$SRC_DIR/third_party/mujoco_menagerie"

"$VENV_DIR/bin/python" - "$SRC_DIR" <<'PY'
import sys
sys.path.insert(0, sys.argv[1] + "/src")
import mujoco, numpy
from task.eval_func.fc_mocap import fcMocapEval  # noqa: F401  (DGB's evaluator must import)
mujoco.MjSpec.from_file(sys.argv[1] + "/assets/hand/shadow/right_hand.xml").compile()
print(f"dgb side venv ready: mujoco {mujoco.__version__}, numpy {numpy.__version__}, source {sys.argv[1]}")
PY
