#!/usr/bin/env bash
# The declared selection run of deep CMARL-CD's designs for states that do not recur:
# each design at its declared settings, `cmarl-cd field` on 8x8-2p-2f-coop,
# 2s-8x8-2p-2f-coop, 10x10-3p-3f and simple_spread, 500k steps, 3 seeds, 100 greedy
# episodes every 50k steps, the field's discount (0.99) for every design. One store, so an
# interrupted run resumes where it stopped; read it with
#
#   cmarl-cd report --store results/deep-cmarlcd-selection/store.sqlite --format json
#
# Designs (the deep CMARL-CD page of the documentation says what each is):
#   keyed      the default: the keyed memory of the table's records and degrees
#   replayed   the first design (REPLAYED_DEEP_CMARLCD)
#   imitation  self-imitation gated by the record (IMITATION_DEEP_CMARLCD)
#   imitation-lambda  the same on λ-returns bootstrapped from the record
#              (IMITATION_LAMBDA_DEEP_CMARLCD, λ 0.9)
#   anneal     the default with its behaviour's T annealed from 1 to 0.1 over 50k steps
#              (VDN's ε anneals over 50k at the field's protocol)
#   spread     the default with the record network's tolerance: a state not kept ties
#              the estimate within 0.25 standard deviations of the returns folded
#   spread-anneal  both
#   range      the record network's tolerance scaled by the range of the returns folded
#              (largest minus smallest), 0.1 of it: the size of a reward where rewards are
#              sparse, where their standard deviation is a small fraction of one
#   range-anneal  range with the anneal
#   imitation-anneal  imitation-lambda with the anneal
#   critic     a centralised critic of joint actions as the record (CRITIC_DEEP_CMARLCD):
#              the mean of the returns, the degrees fitted to its best joint action by
#              cross-entropy, λ-returns (0.9) bootstrapped from its value of the
#              degrees' greedy joint action
#   critic-anneal  critic with the anneal
#   critic-sum     critic in VDN's form, a sum of the agents' outputs (critic_form=sum)
#   critic-best    the critic as first measured (BEST_CRITIC_DEEP_CMARLCD): a
#              0.9-expectile, λ-returns bootstrapped from its best joint action, the
#              degrees moved by the tie of eqs. 14-15
#   critic-best-anneal  critic-best with the anneal
#   shares     the agents' degrees as their shares of the record (SHARES_DEEP_CMARLCD):
#              critic's settings with critic_form=degrees, the record Σ_i c_i(o_i, a_i)
#              fitted to the λ-returns, bootstrapped from the degrees' target copy at
#              their greedy joint action, and acted on directly, the anneal (T 1 to 0.1)
#   shares-cold  shares with T annealed to 0.01 (a share is in the returns' units: on
#              LBF the shares of one state differ by a few hundredths)
#   shares-refresh  shares-cold with every stored λ-return recomputed at each target
#              copy (refresh_returns): one seed located the rest of the loss in returns
#              bootstrapped once, at their episode's end
#   shares-refresh-05  shares-refresh with λ 0.5 (more of each return bootstrapped)
#   shares-range  shares with T in the range of each agent's degrees at the state
#              (temperature_unit=range), annealed 1 to 0.2: as greedy on every game,
#              whatever its returns' scale (SHARES_RANGE_DEEP_CMARLCD)
#   shares-range-bootstrap  shares-range whose episodes cut at max_steps end their
#              λ-returns in the estimate at the state they were cut in (truncation=bootstrap)
#   shares-cold-bootstrap  shares-cold with cut episodes bootstrapped
#   shares-cold-bootstrap-shared, shares-range-bootstrap-shared  the two bootstrapped
#              designs in the field's baselines' model class: one degree network shared by
#              the agents (their index in its input), two hidden layers of 64
#   shares-cold-bootstrap-slow  shares-cold-bootstrap with the target copy every 10,000
#              steps (VDN's), not 500: what the cut episodes' returns bootstrap from moves
#              slower
#   shares-range-bootstrap-shared-slow  shares-range-bootstrap-shared with that interval
#   shares-cold-shared, shares-range-shared  shares-cold and shares-range in the
#              baselines' model class, their cut episodes ending in what they collected
#   shares-range-bootstrap-shared-epymarl  shares-range-bootstrap-shared-slow with the
#              baselines' batch (1,600 visits), buffer (250,000) and learning rate (5e-4)
#   shares-range-shared-refresh  shares-range-shared with every stored λ-return
#              recomputed at each target copy (refresh_returns)
#   shares-range-shared-refresh-slow  that design with VDN's target interval (10,000
#              steps): the returns recomputed at each of VDN's copies
#   shares-range-shared-refresh-slow-td  that design on one-step returns (λ 0): VDN's
#              double estimator targets, through the shares
#   shares-epsilon-shared-refresh-slow-td  that design acting as VDN does: ε-greedy on
#              the shares, ε from 1 to 0.05 over 50,000 steps (behaviour=epsilon-greedy)
#   shares-range-shared-refresh-slow-td-standardised  the one-step design with EPyMARL's
#              standardised rewards (standardise_rewards), as the study's VDN
#
# Usage: bash benchmarks/deep_cmarlcd_selection.sh [OUT] [DESIGN ...]
#   (about 20 minutes a design on one quiet core; needs the [deep] extra)
set -euo pipefail
out="${1:-results/deep-cmarlcd-selection}"
shift || true
designs=("$@")
[ ${#designs[@]} -eq 0 ] && designs=(keyed replayed imitation imitation-lambda)
d=deep-cmarl-cd
anneal="$d.temperature_end=0.1,$d.temperature_steps=50000"
range="$d.unseen_tolerance=0.1,$d.unseen_spread=range"
# the designs by name (--set deep-cmarl-cd.design=NAME): the learner's own list
named="$(python -c 'from cmarlcd.learners.deep.designs import DESIGNS; print(*DESIGNS)')"
composed="keyed anneal spread spread-anneal range range-anneal imitation-anneal critic-anneal"
composed="$composed critic-sum critic-best-anneal shares-refresh-05"
settings_of() {  # settings_of DESIGN: its settings before the discount; status 1 if unknown
  case "$1" in  # a design by name is the same runs as its settings written out
    keyed) echo "" ;;
    anneal) echo "$anneal," ;;
    spread) echo "$d.unseen_tolerance=0.25," ;;
    spread-anneal) echo "$d.unseen_tolerance=0.25,$anneal," ;;
    range) echo "$range," ;;
    range-anneal) echo "$range,$anneal," ;;
    imitation-anneal) echo "$d.design=imitation-lambda,$anneal," ;;
    critic-anneal) echo "$d.design=critic,$anneal," ;;
    critic-sum) echo "$d.design=critic,$d.critic_form=sum," ;;
    critic-best-anneal) echo "$d.design=critic-best,$anneal," ;;
    shares-refresh-05) echo "$d.design=shares-refresh,$d.return_lambda=0.5," ;;
    *) [[ " $named " == *" $1 "* ]] && echo "$d.design=$1," ;;
  esac
}
for design in "${designs[@]}"; do  # every name checked before the first run starts
  settings_of "$design" >/dev/null ||
    { echo "error: unknown design '$design' ($composed $named)" >&2; exit 2; }
done
mkdir -p "$out"
tasks="foraging:8x8-2p-2f-coop,foraging:2s-8x8-2p-2f-coop,foraging:10x10-3p-3f,simple_spread"
for design in "${designs[@]}"; do
  settings="$(settings_of "$design")$d.gamma=0.99"
  echo "$(date +%T) $design" >&2
  python -m cmarlcd field --tasks "$tasks" --learners "$d" --set "$settings" \
    --steps 500k --seeds 3 --eval-interval 50k --eval-episodes 100 --workers 1 \
    --no-progress --json --store "$out/store.sqlite" --figures "$out/figures" \
    >"$out/$design.json"
done
