#!/usr/bin/env bash
# Make the anchor's environment: bash benchmarks/anchors/install.sh [VENV]
# (default .venv-anchor), then run the anchor with VENV/bin/python.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "$here/../.." && pwd)"
venv="${1:-$root/.venv-anchor}"
python3 -m venv "$venv"
"$venv/bin/pip" install -q -r "$here/requirements.txt"
"$venv/bin/pip" install -q --no-deps benchmarl==1.5.2
"$venv/bin/pip" install -q -e "$root[deep,envs]"
"$venv/bin/python" -c "import benchmarl, torchrl, cmarlcd; print('anchor environment ready:', \
'benchmarl', benchmarl.__version__, 'torchrl', torchrl.__version__, 'cmarl-cd', cmarlcd.__version__)"
echo "run: $venv/bin/python $here/benchmarl_simple_spread.py --help"
