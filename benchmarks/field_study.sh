#!/usr/bin/env bash
# The field study: every deep learner on the EPyMARL study's seven LBF tasks and on
# simple_spread, at the field's protocol, `cmarl-cd field` into one resumable store.
#
#   tasks     8x8-2p-2f-coop, 2s-8x8-2p-2f-coop, 10x10-3p-3f, 2s-10x10-3p-3f, 15x15-3p-5f,
#             15x15-4p-3f, 15x15-4p-5f (the five-food ones built with the same rules;
#             lbforaging 2.0.0 registers none) and the compiled simple_spread (both the
#             tasks and the protocol below are benchmarks/field_protocol.sh's)
#   learners  deep IQL, hysteretic DQN, VDN and QMIX at EPyMARL's settings and model class
#             (--preset epymarl; one network shared by the agents, two hidden layers,
#             QMIX's two-layer hypernetworks, the fused step: the anchor's form, the
#             EPyMARL anchor page of the documentation); deep CMARL-CD at its default
#             (the field's discount 0.99) and at its best measured design for states that
#             do not recur (shares-range-shared-refresh-slow-td-standardised on the
#             shares' fused step, the twelfth round of the deep CMARL-CD page, the same
#             runs as benchmarks/deep_cmarlcd_design_field.sh with STEP=fused stores; it
#             replaced shares-cold, whose runs stay in the store, in no column); the
#             uniform random policy as each task's floor. Every learner reads its own
#             agent's observation (--inputs own-observations). Tabular CMARL-CD is not in
#             it: its table of one task's states does not fit in memory on any of them
#             (8x8-2p-2f-coop numbers 1.08e9 states, 10x10-3p-3f 1.7e15, the 15x15 tasks
#             more than 2^62).
#   protocol  full: 2.05M environment steps, 5 seeds, 100 greedy episodes every 50k steps
#             (and before learning); quick: 50k steps, 2 seeds, 10 episodes every 25k, the
#             declared check that every task and learner runs end to end.
#
# One store per form (OUT/store.sqlite): every run is stored as it ends, so a killed study
# resumes where it stopped; its progress goes to stderr, one line a minute into a log
# (`bash benchmarks/field_study.sh full OUT 2> OUT/progress.log`); each part's report
# of the tasks named goes to OUT/PART.json once the part ends. Read the store with
#
#   cmarl-cd report --store results/field/study/store.sqlite --format json
#
# Usage: [PARTS="vdn qmix"] [WORKERS=2] [TIME_LEFT=1] [SEED_BATCH=1] [SET=...] bash benchmarks/field_study.sh [full|quick] [OUT] [TASK ...]
#   PARTS: which learners' parts to run, in the study's order unless told (shares, vdn,
#   deep-cmarl-cd, qmix, deep-iql, hysteretic-dqn; default all); WORKERS: worker
#   processes, each a task at a time (default 1, so that the machine's other core stays
#   free); TIME_LEFT=1: every learner also reads the time left in the episode (`cmarl-cd
#   field --time-left`; the study itself is without it: run it into another OUT);
#   SEED_BATCH: seeds of a task trained together in one model (`--seed-batch`; the
#   command's default, 10, trains a task's 5 together, and a run stopped before its end
#   keeps none of them; 1 trains and stores each seed on its own, so a stop loses one
#   seed's run at most, at the cost of the per-call overhead of unstacked steps; the
#   same numbers: deep IQL's and VDN's fused runs, 3 seeds on 8x8-2p-2f-coop and
#   simple_spread, stored batched and apart, are equal bit for bit); SET: settings
#   appended to each part's `--set` (a diagnostic beside the study, into its own OUT:
#   `PARTS=vdn SET=vdn.standardise_rewards=false`; `cmarl-cd field` refuses a setting of
#   a learner the part does not run). Needs the [deep] extra.
set -euo pipefail
# the tasks and the protocol, shared with the design runs
source "$(dirname "${BASH_SOURCE[0]}")/field_protocol.sh"
all_parts=(shares vdn deep-cmarl-cd qmix deep-iql hysteretic-dqn)
read -r -a parts <<<"${PARTS:-${all_parts[*]}}"
for part in "${parts[@]}"; do
  [[ " ${all_parts[*]} " == *" $part "* ]] ||
    { echo "error: unknown part '$part' (${all_parts[*]})" >&2; exit 2; }
done
workers="${WORKERS:-1}"
[[ "$workers" =~ ^[1-9][0-9]*$ ]] || { echo "error: WORKERS must be >= 1 (got '$workers')" >&2; exit 2; }
batch=()
if [ -n "${SEED_BATCH:-}" ]; then
  [[ "$SEED_BATCH" =~ ^[1-9][0-9]*$ ]] ||
    { echo "error: SEED_BATCH must be >= 1 (got '$SEED_BATCH')" >&2; exit 2; }
  batch=(--seed-batch "$SEED_BATCH")
fi
form="${1:-full}"
out="${2:-results/field/study}"
shift $(($# < 2 ? $# : 2))
field_protocol "$form"
field_inputs
tasks=("$@")
[ ${#tasks[@]} -eq 0 ] && tasks=("${field_tasks[@]}")
mkdir -p "$out"

extra="${SET:+,$SET}"  # SET's settings, after each part's own
d=deep-cmarl-cd
# the design's runs as the design script stores them (the settings' order is not part
# of a run's identity), so `cmarl-cd merge` joins that store's runs to the study's
shares="$d.design=shares-range-shared-refresh-slow-td-standardised,$d.step=fused"
model() {  # model LEARNER: the anchor's model class at EPyMARL's settings
  local m="$1.share=true,$1.hidden_layers=2,$1.step=fused"
  [ "$1" = qmix ] && m="$m,qmix.hypernet_layers=2"
  echo "$m"
}

field() {  # field PART LEARNER [ARGS ...]: one learner on every task
  local part="$1" learner="$2"
  shift 2
  echo "$(date +%T) $part" >&2
  python -m cmarlcd field --tasks "$(IFS=,; echo "${tasks[*]}")" --learners "$learner" \
    "${protocol[@]}" "${inputs[@]}" ${batch[@]+"${batch[@]}"} --workers "$workers" --json "$@" \
    --store "$out/store.sqlite" --figures "$out/figures" >"$out/$part.json.partial"
  mv "$out/$part.json.partial" "$out/$part.json"  # a stopped part leaves the last whole one
}
# learner by learner, so that a partial store holds whole columns: deep CMARL-CD's best
# measured design and VDN (the selection run's pair) first, the costliest gradient steps
# (IQL's and hysteretic DQN's 128 hidden units) last
for part in "${parts[@]}"; do
  case "$part" in
    shares) field deep-cmarl-cd-shares "$d" --set "$shares,$d.gamma=0.99$extra" ;;
    deep-cmarl-cd) field deep-cmarl-cd "$d" --set "$d.gamma=0.99$extra" ;;
    *) field "$part" "$part" --preset epymarl --set "$(model "$part")$extra" ;;
  esac
done
echo "$(date +%T) done" >&2
