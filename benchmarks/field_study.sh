#!/usr/bin/env bash
# The field study: every deep learner on the EPyMARL study's seven LBF tasks and on
# simple_spread, at the field's protocol, `cmarl-cd field` into one resumable store.
#
#   tasks     8x8-2p-2f-coop, 2s-8x8-2p-2f-coop, 10x10-3p-3f, 2s-10x10-3p-3f, 15x15-3p-5f,
#             15x15-4p-3f, 15x15-4p-5f (the five-food ones built with the same rules;
#             lbforaging 2.0.0 registers none) and the compiled simple_spread
#   learners  deep IQL, hysteretic DQN, VDN and QMIX at EPyMARL's settings and model class
#             (--preset epymarl; one network shared by the agents, two hidden layers,
#             QMIX's two-layer hypernetworks, the fused step: the anchor's form, the
#             EPyMARL anchor page of the documentation); deep CMARL-CD at its default
#             (the field's discount 0.99) and at its best measured design for states that
#             do not recur (shares-cold of benchmarks/deep_cmarlcd_selection.sh); the
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
# resumes where it stopped. Read it with
#
#   cmarl-cd report --store results/field/study/store.sqlite --format json
#
# Usage: bash benchmarks/field_study.sh [full|quick] [OUT] [TASK ...]
#   (one worker, so that the machine's other core stays free; needs the [deep] extra)
set -euo pipefail
form="${1:-full}"
out="${2:-results/field/study}"
shift $(($# < 2 ? $# : 2))
case "$form" in
  full) protocol=(--steps 2.05M --seeds 5 --eval-interval 50k --eval-episodes 100) ;;
  quick) protocol=(--steps 50k --seeds 2 --eval-interval 25k --eval-episodes 10) ;;
  *) echo "error: unknown form '$form' (full or quick)" >&2; exit 2 ;;
esac
tasks=("$@")
[ ${#tasks[@]} -eq 0 ] && tasks=(foraging:8x8-2p-2f-coop foraging:2s-8x8-2p-2f-coop
  foraging:10x10-3p-3f foraging:2s-10x10-3p-3f foraging:15x15-3p-5f foraging:15x15-4p-3f
  foraging:15x15-4p-5f simple_spread)
mkdir -p "$out"

baselines=(deep-iql hysteretic-dqn vdn qmix)
model=()
for learner in "${baselines[@]}"; do
  model+=("$learner.share=true" "$learner.hidden_layers=2" "$learner.step=fused")
done
model+=(qmix.hypernet_layers=2)
d=deep-cmarl-cd
shares="$d.update=critic,$d.expectile=0.5,$d.return_lambda=0.9,$d.train_every=50"
shares="$shares,$d.target_every=500,$d.critic_bootstrap=greedy,$d.critic_fit=imitation"
shares="$shares,$d.critic_form=degrees,$d.temperature_end=0.01,$d.temperature_steps=50000"

field() {  # field PART TASK LEARNERS [ARGS ...]
  local part="$1" task="$2" learners="$3"
  shift 3
  echo "$(date +%T) $task $part" >&2
  python -m cmarlcd field --tasks "$task" --learners "$learners" "${protocol[@]}" \
    --inputs own-observations --workers 1 --no-progress --json "$@" \
    --store "$out/store.sqlite" --figures "$out/figures" >"$out/$part-${task//[:\/]/-}.json"
}
for task in "${tasks[@]}"; do
  field baselines "$task" "$(IFS=,; echo "${baselines[*]}")" --preset epymarl \
    --set "$(IFS=,; echo "${model[*]}")"
  field deep-cmarl-cd "$task" "$d" --set "$d.gamma=0.99"
  field deep-cmarl-cd-shares "$task" "$d" --set "$shares,$d.gamma=0.99"
done
echo "$(date +%T) done" >&2
