#!/usr/bin/env bash
# Fixed-seed stores of deep CMARL-CD's updates on the field's kinds of game, for proving
# that a change to its numeric path left every other design's numbers as they were (the
# paper's experiments: benchmarks/fixed_seed_stores.sh). Run it with the old code and the
# new into two folders, then
#
#   for s in OLD/*.sqlite; do python benchmarks/compare_stores.py "$s" NEW/$(basename "$s"); done
#
# Stores: the keyed default on LBF (features), self-imitation on λ-returns on LBF (the
# bootstrapped ring), the summed critic bootstrapped from the greedy joint action on LBF, the agents' degrees
# as their shares of the record on LBF, the keyed memory with first visits on simple_spread, the keyed
# default on the DSN (one-hot states), the replayed design on the tests' tiny environment
# (the object API). Usage: bash benchmarks/fixed_seed_stores_deep_cmarlcd.sh DIR
# (about 5 minutes on one core; needs the [deep] extra)
set -euo pipefail
mkdir -p "${1:?usage: fixed_seed_stores_deep_cmarlcd.sh DIR}"
out="$(cd "$1" && pwd)"
here="$(cd "$(dirname "$0")/.." && pwd)"
figures="$(mktemp -d)"
cd "$here"  # the tiny environment is a module of tests/
d=deep-cmarl-cd
run() {  # NAME COMMAND...: one store
  local name="$1"
  shift
  echo "$(date +%T) $name" >&2
  python -m cmarlcd "$@" --algorithms "$d" --workers 1 --no-progress \
    --store "$out/$name.sqlite" --figures "$figures/$name" >"$out/$name.txt"
}
lbf=(train --game foraging:5x5-2p-1f --steps 20k --runs 2 --curve-points 2 --eval-episodes 5)
run keyed-lbf "${lbf[@]}"
run imitation-lambda-lbf "${lbf[@]}" --set "$d.update=imitation,$d.return_lambda=0.9"
run critic-sum-lbf "${lbf[@]}" --set "$d.update=critic,$d.return_lambda=0.9,$d.critic_form=sum,$d.critic_bootstrap=greedy,$d.critic_fit=imitation"
run shares-lbf "${lbf[@]}" --set "$d.update=critic,$d.return_lambda=0.9,$d.critic_form=degrees,$d.critic_bootstrap=greedy,$d.critic_fit=imitation"
run first-visit-spread train --game simple_spread:N=3 --steps 10k --runs 2 --curve-points 2 \
  --eval-episodes 5 --set "$d.unseen_record=first-visit"
run keyed-dsn dsn --episodes 2000 --eval-episodes 50 --runs 2
run replayed-tiny train --env tests.tiny_env:make --episodes 300 --runs 2 --eval-episodes 5 \
  --curve-points 2 --set "$d.update=replayed"
