# The field study's tasks and protocol, in one place: sourced by benchmarks/field_study.sh
# (every learner) and benchmarks/deep_cmarlcd_design_field.sh (one deep CMARL-CD design
# into a store of its own), so that a design's runs are the study's runs by construction.
#
#   field_tasks     the EPyMARL study's seven LBF tasks (the five-food ones built with the
#                   same rules; lbforaging 2.0.0 registers none) and the compiled
#                   simple_spread
#   field_protocol FORM   sets `protocol` to the options of `cmarl-cd field` for FORM:
#                   full (2.05M environment steps, 5 seeds, 100 greedy episodes every 50k
#                   steps and before learning) or quick (50k steps, 2 seeds, 10 episodes
#                   every 25k: the declared check that every task and learner runs end to
#                   end); one error line and status 2 for any other FORM
#   field_inputs    sets `inputs` to what the learners read: each agent its own
#                   observation, and the time left too where TIME_LEFT=1 (`--time-left`;
#                   the study is without it); one error line and status 2 for any other
#                   TIME_LEFT than 0 or 1
field_tasks=(foraging:8x8-2p-2f-coop foraging:2s-8x8-2p-2f-coop foraging:10x10-3p-3f
  foraging:2s-10x10-3p-3f foraging:15x15-3p-5f foraging:15x15-4p-3f foraging:15x15-4p-5f
  simple_spread)

field_protocol() {
  case "$1" in
    full) protocol=(--steps 2.05M --seeds 5 --eval-interval 50k --eval-episodes 100) ;;
    quick) protocol=(--steps 50k --seeds 2 --eval-interval 25k --eval-episodes 10) ;;
    *) echo "error: unknown form '$1' (full or quick)" >&2; exit 2 ;;
  esac
}

field_inputs() {
  inputs=(--inputs own-observations)
  case "${TIME_LEFT:-0}" in
    0) ;;
    1) inputs+=(--time-left) ;;
    *) echo "error: TIME_LEFT must be 0 or 1 (got '$TIME_LEFT')" >&2; exit 2 ;;
  esac
}
