#!/usr/bin/env bash
# Make an anchor's environment, then run the anchor with VENV/bin/python:
#   bash benchmarks/anchors/install.sh [VENV]           BenchMARL (default .venv-anchor)
#   bash benchmarks/anchors/install.sh epymarl [VENV]   EPyMARL's (default .venv-epymarl);
#     EPyMARL itself is not on PyPI: the anchor takes the path of a checkout of cbc38c0,
#     git clone https://github.com/uoe-agents/epymarl && git -C epymarl checkout cbc38c0
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "$here/../.." && pwd)"
if [[ "${1:-}" == "epymarl" ]]; then
  venv="${2:-$root/.venv-epymarl}"
  python3 -m venv "$venv"
  "$venv/bin/pip" install -q -r "$here/epymarl-requirements.txt"
  "$venv/bin/pip" install -q -e "$root[deep]"
  "$venv/bin/python" -c "import sacred, lbforaging, torch, cmarlcd; print('anchor environment ready:', \
'sacred', sacred.__version__, 'torch', torch.__version__, 'cmarl-cd', cmarlcd.__version__)"
  echo "run: $venv/bin/python $here/epymarl_lbf.py --epymarl PATH-OF-EPYMARL --help"
  exit 0
fi
venv="${1:-$root/.venv-anchor}"
python3 -m venv "$venv"
"$venv/bin/pip" install -q -r "$here/requirements.txt"
"$venv/bin/pip" install -q --no-deps benchmarl==1.5.2
"$venv/bin/pip" install -q -e "$root[deep,envs]"
"$venv/bin/python" -c "import benchmarl, torchrl, cmarlcd; print('anchor environment ready:', \
'benchmarl', benchmarl.__version__, 'torchrl', torchrl.__version__, 'cmarl-cd', cmarlcd.__version__)"
echo "run: $venv/bin/python $here/benchmarl_simple_spread.py --help"
