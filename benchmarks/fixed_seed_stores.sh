#!/usr/bin/env bash
# Fixed-seed stores of every experiment, computed through the command line on worker
# processes, for proving that a change to the sweeps, the backends or a numeric path left
# every number as it was: run it with the old code and the new into two folders, then
#
#   for s in OLD/*.sqlite; do python benchmarks/compare_stores.py "$s" NEW/$(basename "$s"); done
#
# Usage: bash benchmarks/fixed_seed_stores.sh DIR [WORKERS]   (about 8 minutes on 2 cores;
# needs the [deep] extra for the deep learners' runs)
set -euo pipefail
workers="${2:-2}"
mkdir -p "${1:?usage: fixed_seed_stores.sh DIR [WORKERS]}"
out="$(cd "$1" && pwd)"
here="$(cd "$(dirname "$0")/.." && pwd)"
common=(--workers "$workers" --no-progress --json)
figures="$(mktemp -d)"
cd "$here"  # the train run's environment is a module of tests/
run() {  # NAME COMMAND...: one store, its JSON report kept beside it
  local name="$1"
  shift
  echo "$(date +%T) $name" >&2
  python -m cmarlcd "$@" "${common[@]}" --store "$out/$name.sqlite" --figures "$figures/$name" \
    >"$out/$name.json"
}
# Tables 1-2, the DSN (tabular and deep), the battlefield tournament (tabular and deep
# sides), Theorem 1 and the comparison: the quick preset of the paper run
run reproduce reproduce --preset quick --seed 3
run scaling scaling --preset quick --sizes 2x3/2,3x4/3 --runs 2 --seed 5 \
  --algorithms cmarl-cd,deep-cmarl-cd,vdn,qmix,distributed-q
run train train --env tests.tiny_env:make --algorithms vdn,qmix,deep-cmarl-cd \
  --episodes 600 --runs 2 --eval-episodes 5 --curve-points 3 --seed 11
run readings readings --algorithms cmarl-cd,la-oca --rounds 2 --learn-episodes 2000 \
  --eval-episodes 1000 --hit-rates 0.8,1 --gammas 0,0.3 --seed 2
# the compiled field games (since 0.7): LBF with every kind of learner, simple_spread
# with a budget of steps and each agent on its own observation
run foraging train --game foraging:5x5-2p-1f,penalty=0.1 --algorithms cmarl-cd,vdn,qmix \
  --episodes 400 --runs 2 --eval-episodes 20 --curve-points 2 --seed 7
run spread train --game simple_spread:N=3 --inputs own-observations --algorithms vdn,qmix \
  --steps 5k --runs 2 --eval-episodes 10 --curve-points 2 --seed 9
echo "stores in $out (figures in $figures)" >&2

