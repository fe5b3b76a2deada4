#!/bin/bash
# One call on a lent GPU machine: run cmarl-cd from source over the machine's own PyTorch, run the
# tests that need a GPU, then the GPU benchmark; logs go to $OUT (default ./gpu-out).
#
# The machine reaches no package index, and its image holds torch, numba, numpy, scipy,
# typer, rich and matplotlib but not gymnasium or pettingzoo: carry their wheels. Here,
# before the call (pure-Python wheels, any Python 3):
#
#   pip download --no-deps -d .wheels gymnasium pettingzoo farama-notifications
#
# then run this script with `.wheels` carried (an ignored folder of the checkout), e.g.
# with the device tool: command "bash benchmarks/gpu_session.sh", carry [".wheels"].
# Every step prints what it did; a failing step ends the script with its status.
#
# BENCH_ARGS adds options to bench_gpu.py (e.g. "--episodes 1000" for a shorter run);
# DEVICE=cpu tries the script where there is no GPU.
set -euo pipefail

OUT=${OUT:-gpu-out}
WHEELS=${WHEELS:-.wheels}
mkdir -p "$OUT"
python=${PYTHON:-python3}

echo "== machine"
nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader || true
"$python" - <<'EOF'
import os, platform, torch
print(f"python {platform.python_version()}, torch {torch.__version__}, "
      f"cuda {torch.cuda.is_available()}, {os.cpu_count()} cores")
EOF

echo "== install"
if [ -d "$WHEELS" ]; then
    "$python" -m pip install --quiet --no-index --find-links "$WHEELS" --no-deps \
        gymnasium pettingzoo farama-notifications
fi
# cmarl-cd itself from the source tree, not built: the machine's torch and numba stand
# (the [deep] pin is for installs from an index), and no build tool is asked of it
export PYTHONPATH="$PWD/src${PYTHONPATH:+:$PYTHONPATH}"
"$python" -c "import cmarlcd, gymnasium, pettingzoo, torch; print('cmarl-cd from', cmarlcd.__file__)"

echo "== the tests that need a GPU (and the device tests that run everywhere)"
"$python" -m pytest -q -p no:cacheprovider tests/test_devices.py -rs 2>&1 | tee "$OUT/tests.log"

echo "== benchmark"
# shellcheck disable=SC2086  # BENCH_ARGS is a list of options
PYTHONUNBUFFERED=1 "$python" benchmarks/bench_gpu.py --device "${DEVICE:-cuda}" ${BENCH_ARGS:-} 2>&1 \
    | tee "$OUT/bench.log"
