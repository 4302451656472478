#!/usr/bin/env bash
# Runs inside the freshly built conda env (Snakemake's post-deploy hook): install this
# checkout's package (editable) without touching the dependencies the env file pinned.
# The workflow sets DEXLITE_SOURCE to the checkout (the Snakefile's folder).
set -euo pipefail
python -m pip install --no-deps --editable "${DEXLITE_SOURCE:-$PWD}"
