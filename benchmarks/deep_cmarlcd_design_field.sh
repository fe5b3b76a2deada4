#!/usr/bin/env bash
# One deep CMARL-CD design at the field study's protocol, into a store of its own: the
# study's command (benchmarks/field_study.sh, full form) for one learner, its eight tasks
# (or those named), 2.05M steps, 5 seeds, 100 greedy episodes every 50k steps, each agent
# reading its own observation, the field's discount. Resumable: rerun after a stop.
# Compare it with the study's columns by
#
#   python benchmarks/deep_cmarlcd_designs_field.py --study results/field/study/store.sqlite \
#       --design NAME=STORE ...
#
# Usage: [TIME_LEFT=1] [STEP=fused] bash benchmarks/deep_cmarlcd_design_field.sh DESIGN STORE [TASK ...]
#   TIME_LEFT=1: the agents also read the time left (`cmarl-cd field --time-left`); the
#   study's columns are without it
#   STEP: the gradient step (`deep-cmarl-cd.step`: auto, the default, which keeps
#   autograd's for the shares; fused, their compiled step, its runs stored apart)
#   (some 60-90 minutes a design for the eight tasks on a core shared with the study;
#   needs the [deep] extra)
set -euo pipefail
# the study's tasks and protocol (benchmarks/field_protocol.sh)
source "$(dirname "${BASH_SOURCE[0]}")/field_protocol.sh"
[ $# -ge 2 ] || { echo "usage: $0 DESIGN STORE [TASK ...]" >&2; exit 2; }
design="$1" store="$2"
shift 2
field_protocol full
field_inputs
step=""  # the setting as a design's runs were stored, unless STEP names one
case "${STEP:-}" in
  "") ;;
  auto|fused|autograd) step=",deep-cmarl-cd.step=$STEP" ;;
  *) echo "error: STEP must be auto, fused or autograd (got '$STEP')" >&2; exit 2 ;;
esac
tasks=("$@")
[ ${#tasks[@]} -eq 0 ] && tasks=("${field_tasks[@]}")
d=deep-cmarl-cd
mkdir -p "$(dirname "$store")"
echo "$(date +%T) $design" >&2
python -m cmarlcd field --tasks "$(IFS=,; echo "${tasks[*]}")" --learners "$d" \
  "${protocol[@]}" "${inputs[@]}" --workers 1 --json \
  --set "$d.design=$design,$d.gamma=0.99$step" \
  --store "$store" --figures "$(dirname "$store")/figures"
echo "$(date +%T) done" >&2
