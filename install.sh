#!/usr/bin/env bash
# Set up DexLite in ./.venv. Usage: bash install.sh [--test]
#   --test   also install the test tools, and (as root, with apt) the Debian packages slurm-wlm
#            and munge that the SLURM integration test runs; without them that test skips.
# Torch: by default the CPU wheel torch==2.13.0 is installed first, so the dependency
# resolver never pulls a multi-GB CUDA build. GPU users: set DEXLITE_TORCH_SPEC, e.g.
#   DEXLITE_TORCH_SPEC="torch==2.13.0 --index-url https://download.pytorch.org/whl/cu128" bash install.sh
set -euo pipefail
cd "$(dirname "$0")"
WITH_TEST=0
[[ "${1:-}" == "--test" ]] && WITH_TEST=1
PYTHON="${PYTHON:-python3}"
[[ -x .venv/bin/python ]] || "$PYTHON" -m venv .venv
.venv/bin/python -m pip install --quiet --upgrade pip
# shellcheck disable=SC2086
.venv/bin/python -m pip install --quiet ${DEXLITE_TORCH_SPEC:-torch==2.13.0}
if [[ $WITH_TEST == 1 ]]; then
    if [[ $(id -u) == 0 ]] && command -v apt-get >/dev/null; then
        if ! { DEBIAN_FRONTEND=noninteractive apt-get update -qq &&
               DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends slurm-wlm munge >/dev/null; }; then
            echo "install.sh: could not apt-get install slurm-wlm munge; the SLURM test will skip" >&2
        fi
    else
        echo "install.sh: not root or no apt-get: slurm-wlm/munge not installed; the SLURM test will skip" >&2
    fi
    .venv/bin/python -m pip install --quiet -e ".[test]"
else
    .venv/bin/python -m pip install --quiet -e .
fi
.venv/bin/python -c "import torch, dexlite_pipeline; print(f'dexlite ready: torch {torch.__version__}, cuda available: {torch.cuda.is_available()}')"
