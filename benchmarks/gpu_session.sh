#!/bin/bash
# One call on a lent GPU machine: cmarl-cd from source over the machine's own PyTorch; the
# tests that need a GPU, a small tournament swept over forked GPU workers, then the GPU
# benchmark; logs go to $OUT (default ./gpu-out).
#
# The machine reaches no package index, and its image holds torch, numba, numpy, scipy,
# typer, rich and matplotlib but not gymnasium or pettingzoo: carry their wheels. Here,
# before the call (pure-Python wheels, any Python 3):
#
#   pip download --no-deps -d .wheels gymnasium pettingzoo farama-notifications
#
# then run this script with `.wheels` carried (an ignored folder of the checkout), e.g.
# with the device tool: command "bash benchmarks/gpu_session.sh", carry [".wheels"].
# Each step says what it did; a failing check is reported and the next still runs (the
# device time is spent either way); the script exits with the first failure's status.
#
# BENCH_ARGS adds options to bench_gpu.py (e.g. "--episodes 1000" for a shorter run);
# DEVICE=cpu tries the script where there is no GPU.
set -uo pipefail

OUT=${OUT:-gpu-out}
WHEELS=${WHEELS:-.wheels}
DEVICE=${DEVICE:-cuda}
python=${PYTHON:-python3}
mkdir -p "$OUT"
status=0
step() {  # step NAME COMMAND...: run it, time it, keep the first failure's status
    local name=$1 start=$SECONDS rc
    shift
    echo "== $name"
    "$@"
    rc=$?
    echo "== $name: exit $rc in $((SECONDS - start)) s"
    if [ "$rc" -ne 0 ] && [ "$status" -eq 0 ]; then status=$rc; fi
    return 0
}

echo "== machine"
nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader || true

# the carried wheels into a folder of their own (a system Python may refuse installs into
# itself, PEP 668); cmarl-cd itself from the source tree, not built: the machine's torch
# and numba stand (the [deep] pin is for installs from an index)
if ! "$python" -c "import gymnasium, pettingzoo" 2>/dev/null; then
    if [ ! -d "$WHEELS" ]; then
        echo "error: gymnasium and pettingzoo are missing and no wheels were carried in $WHEELS"
        exit 2
    fi
    "$python" -m pip install --quiet --no-index --find-links "$WHEELS" --no-deps \
        --target "$PWD/.deps" gymnasium pettingzoo farama-notifications || exit 2
    export PYTHONPATH="$PWD/.deps${PYTHONPATH:+:$PYTHONPATH}"
fi
export PYTHONPATH="$PWD/src${PYTHONPATH:+:$PYTHONPATH}"
"$python" - <<'EOF' || exit 2
import os, platform, torch, cmarlcd
print(f"python {platform.python_version()}, torch {torch.__version__}, cuda "
      f"{torch.cuda.is_available()}, {os.cpu_count()} cores; cmarl-cd from {cmarlcd.__file__}")
EOF

tests() {
    "$python" -m pytest -q -p no:cacheprovider tests/test_devices.py -rs 2>&1 \
        | tee "$OUT/tests.log"
}
step "the device tests (those that need a GPU included)" tests

sweep() {  # deep tasks over two forked workers on the card, tabular ones on the others
    local store="$OUT/sweep.sqlite"
    rm -f "$store"
    "$python" -m cmarlcd tournament --algorithms cmarl-cd,vdn,qmix --rounds 4 \
        --learn-episodes 300 --eval-episodes 100 --seed-batch 2 --workers 4 \
        --gpu-tasks 2 --device "$DEVICE" --store "$store" --figures "$OUT/figures" \
        --no-progress >"$OUT/sweep.log" 2>&1 || { tail -5 "$OUT/sweep.log"; return 1; }
    "$python" - "$store" <<'EOF'
import collections, json, sys
from cmarlcd.sweeps.store import ResultStore
with ResultStore(sys.argv[1]) as store:
    seen = collections.Counter(
        (tuple(json.loads(r.key.config)["algorithms"]), r.metrics.get("device", "none"))
        for r in store.records()
    )
for (pair, device), runs in sorted(seen.items()):
    print(f"  {'-'.join(pair):20s} {device}: {runs} matches")
EOF
}
step "a tournament over GPU workers (--gpu-tasks 2 of --workers 4)" sweep

threads() {  # a CPU step's time with 1 to 16 intra-op threads (for the threads' rule)
    "$python" benchmarks/bench_threads.py --threads 1 2 4 8 16 --seeds 1 30 --repeats 3 \
        2>&1 | tee "$OUT/threads.log"
}
step "a gradient step's time by threads, on the CPU" threads

bench() {
    # shellcheck disable=SC2086  # BENCH_ARGS is a list of options
    PYTHONUNBUFFERED=1 "$python" benchmarks/bench_gpu.py --device "$DEVICE" ${BENCH_ARGS:-} \
        2>&1 | tee "$OUT/bench.log"
}
step "the benchmark" bench
exit "$status"
