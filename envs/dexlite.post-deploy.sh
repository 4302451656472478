#!/usr/bin/env bash
# Runs inside the freshly built conda env (Snakemake's post-deploy hook), from the
# directory snakemake was started in: install this checkout's package without touching
# the dependencies the env file pinned. DEXLITE_SOURCE overrides the checkout location.
set -euo pipefail
python -m pip install --no-deps --editable "${DEXLITE_SOURCE:-$PWD}"
