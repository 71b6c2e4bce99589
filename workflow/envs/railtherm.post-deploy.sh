#!/usr/bin/env bash
# Post-deployment script of railtherm.yaml: `snakemake --sdm conda` runs it once, inside the
# environment it has just created from that file, before any job. It installs railtherm from
# its repository into the environment in editable mode, without dependencies (the env file
# lists them).
#
# Snakemake runs a copy of this script, <conda-prefix>/<hash>.post-deploy.sh (by default
# .snakemake/conda/ in the working directory), with the working directory of the run as the
# current directory; neither $0 nor a path relative to the env file leads to the repository.
# The repository is therefore $RAILTHERM_REPO if set, else the nearest directory at or above
# the current one whose pyproject.toml is railtherm's: the repository itself for
# `snakemake --sdm conda` run from it, or with `--directory validation`.
set -euo pipefail

repo="${RAILTHERM_REPO:-}"
if [ -z "$repo" ]; then
    dir=$(pwd -P)
    while :; do
        if [ -f "$dir/pyproject.toml" ] && grep -qx 'name = "railtherm"' "$dir/pyproject.toml"; then
            repo=$dir
            break
        fi
        [ "$dir" = / ] && break
        dir=$(dirname "$dir")
    done
fi
if [ -z "$repo" ]; then
    echo "railtherm post-deploy: no railtherm repository at or above $(pwd);" \
        "set RAILTHERM_REPO to the repository's path" >&2
    exit 1
fi
echo "railtherm post-deploy: installing railtherm from $repo into $(command -v python)"
python -m pip install --no-deps --disable-pip-version-check --quiet -e "$repo"
