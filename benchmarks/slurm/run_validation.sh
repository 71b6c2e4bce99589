#!/usr/bin/env bash
# The validation study run twice from clean, locally and through Slurm with profiles/slurm,
# and the two results compared (docs/cluster.md). Needs a Slurm cluster this host submits to
# (benchmarks/slurm/setup_local_slurm.sh makes one here) and snakemake-executor-plugin-slurm
# in the Python environment. Not part of the tests.
#
#     bash benchmarks/slurm/run_validation.sh [--worktree] [--scratch DIR] [--cores N] \
#         [-- EXTRA SNAKEMAKE ARGUMENTS OF THE SLURM RUN]
#
# It copies the repository's committed state (HEAD; with --worktree the working tree's tracked
# and untracked files instead) into two scratch trees, DIR/local/railtherm and
# DIR/slurm/railtherm (default DIR /tmp/railtherm-slurm, emptied first), each with `shared`
# beside it as in CI, and deletes their committed validation/results. Then, from each tree:
#
#     snakemake --cores N --directory validation                                  # local
#     snakemake --profile profiles/slurm --workflow-profile none --directory validation  # Slurm
#
# with account and partition from SBATCH_ACCOUNT and SBATCH_PARTITION (default: railtherm and
# debug, the local cluster's). Both runs use $PYTHON (default: the repository's .venv) with
# PYTHONPATH set to their tree, so railtherm is imported from the copy, not from an editable
# install; the Slurm jobs run the same interpreter (the plugin submits `<python> -m
# snakemake`) and inherit the environment (sbatch --export=ALL), so the scratch tree and the
# environment must be on a filesystem the compute nodes see at the same path.
#
# It prints both wall times and the Slurm jobs' states (sacct), then compares every table
# (.csv, .md) and fit (.yaml) under validation/results of the Slurm run with the local run's
# with tests/compare_outputs.py (text exact, numbers within its RTOL) and exits 1 on any
# difference. Each run is also compared with the committed tables, for information.
set -euo pipefail

REPO=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
PYTHON=${PYTHON:-$REPO/.venv/bin/python}
SCRATCH=/tmp/railtherm-slurm
CORES=2
SOURCE=HEAD
while [ $# -gt 0 ]; do
    case "$1" in
        --worktree) SOURCE=worktree ;;
        --scratch) SCRATCH=$2; shift ;;
        --cores) CORES=$2; shift ;;
        --) shift; break ;;
        *) echo "run_validation: unknown argument $1" >&2; exit 2 ;;
    esac
    shift
done
export SBATCH_ACCOUNT=${SBATCH_ACCOUNT:-railtherm}
export SBATCH_PARTITION=${SBATCH_PARTITION:-debug}

# --- preflight --------------------------------------------------------------------------------
command -v sinfo >/dev/null && sinfo -h >/dev/null 2>&1 || {
    echo "run_validation: no Slurm cluster answers (sinfo); see setup_local_slurm.sh" >&2
    exit 1
}
"$PYTHON" -c "import snakemake_executor_plugin_slurm" 2>/dev/null || {
    echo "run_validation: $PYTHON has no snakemake-executor-plugin-slurm;" \
        "install it: $PYTHON -m pip install snakemake-executor-plugin-slurm" >&2
    exit 1
}
versions=$("$PYTHON" - <<'EOF'
import importlib.metadata as m
print(", ".join(f"{p} {m.version(p)}" for p in (
    "snakemake", "snakemake-executor-plugin-slurm", "snakemake-executor-plugin-slurm-jobstep")))
EOF
)
echo "python $("$PYTHON" -c 'import sys; print(sys.version.split()[0])') ($PYTHON), $versions"
echo "$(sinfo --version); partition $SBATCH_PARTITION, account $SBATCH_ACCOUNT"
sinfo -h -p "$SBATCH_PARTITION" -o "nodes %D, cpus %c, memory %m MB, state %T"

# --- scratch trees ----------------------------------------------------------------------------
rm -rf "$SCRATCH"
mkdir -p "$SCRATCH"
snapshot=$SCRATCH/source.tar
if [ "$SOURCE" = HEAD ]; then
    git -C "$REPO" archive --format=tar HEAD >"$snapshot"
    echo "source: HEAD $(git -C "$REPO" rev-parse --short HEAD)"
else
    (cd "$REPO" && git ls-files -z --cached --others --exclude-standard \
        | tar --null --ignore-failed-read -cf "$snapshot" -T - 2>/dev/null)
    echo "source: working tree of $REPO (HEAD $(git -C "$REPO" rev-parse --short HEAD) + edits)"
fi
for run in local slurm; do
    mkdir -p "$SCRATCH/$run/railtherm"
    tar -xf "$snapshot" -C "$SCRATCH/$run/railtherm"
    [ -d "$REPO/../shared" ] && ln -s "$(cd "$REPO/../shared" && pwd)" "$SCRATCH/$run/shared"
    if [ "$run" = local ]; then  # the committed results, kept to compare with
        mkdir -p "$SCRATCH/committed/validation"
        mv "$SCRATCH/local/railtherm/validation/results" "$SCRATCH/committed/validation/results"
    else
        rm -rf "$SCRATCH/$run/railtherm/validation/results"
    fi
    where=$(cd "$SCRATCH/$run/railtherm" && PYTHONPATH=$PWD "$PYTHON" -c \
        'import railtherm, pathlib; print(pathlib.Path(railtherm.__file__).resolve())')
    case "$where" in
        "$SCRATCH/$run/railtherm/"*) ;;
        *) echo "run_validation: railtherm imports from $where, not the copy" >&2; exit 1 ;;
    esac
done

# --- the two runs -----------------------------------------------------------------------------
elapsed() { "$PYTHON" -c "import sys; print(f'{float(sys.argv[2]) - float(sys.argv[1]):.0f}')" "$@"; }

echo
echo "local run: snakemake --cores $CORES --directory validation"
cd "$SCRATCH/local/railtherm"
t0=$(date +%s.%N)
PYTHONPATH=$PWD "$PYTHON" -m snakemake --cores "$CORES" --directory validation \
    >"$SCRATCH/local.log" 2>&1 || { tail -30 "$SCRATCH/local.log"; echo "local run failed"; exit 1; }
t1=$(date +%s.%N)
local_s=$(elapsed "$t0" "$t1")
echo "  done in $local_s s (log $SCRATCH/local.log)"

echo "Slurm run: snakemake --profile profiles/slurm --workflow-profile none --directory validation $*"
cd "$SCRATCH/slurm/railtherm"
sacct_start=$(date +%Y-%m-%dT%H:%M:%S)
t0=$(date +%s.%N)
PYTHONPATH=$PWD "$PYTHON" -m snakemake --profile profiles/slurm --workflow-profile none \
    --directory validation "$@" >"$SCRATCH/slurm.log" 2>&1 \
    || { tail -40 "$SCRATCH/slurm.log"; echo "Slurm run failed"; exit 1; }
t1=$(date +%s.%N)
slurm_s=$(elapsed "$t0" "$t1")
echo "  done in $slurm_s s (log $SCRATCH/slurm.log)"
if command -v sacct >/dev/null; then
    sacct -X -n -P --starttime "$sacct_start" --format=JobName,State,Account,Partition \
        >"$SCRATCH/sacct.txt" 2>/dev/null || true
    echo "  Slurm jobs since $sacct_start (sacct: count, state, account, partition):"
    cut -d'|' -f2- "$SCRATCH/sacct.txt" | sort | uniq -c | sed 's/^/   /'
fi
echo
echo "wall time: local $local_s s, Slurm $slurm_s s"

# --- comparison -------------------------------------------------------------------------------
cd "$SCRATCH"
"$PYTHON" - "$SCRATCH" <<'EOF'
import sys
from pathlib import Path

scratch = Path(sys.argv[1])
sys.path.insert(0, str(scratch / "local/railtherm/tests"))
from compare_outputs import RTOL, compare_files  # noqa: E402

local = scratch / "local/railtherm/validation"
slurm = scratch / "slurm/railtherm/validation"
committed = scratch / "committed/validation"
suffixes = {".csv", ".md", ".yaml"}
rels = sorted(
    p.relative_to(local)
    for p in (local / "results").rglob("*")
    if p.is_file() and p.suffix in suffixes
)
only_slurm = sorted(
    str(p.relative_to(slurm))
    for p in (slurm / "results").rglob("*")
    if p.is_file() and not (local / p.relative_to(slurm)).exists()
)
failed = 0
identical = 0
worst = 0.0
print(f"\nSlurm run vs local run: {len(rels)} files (.csv, .md, .yaml), rtol {RTOL:g}")
for rel in rels:
    c = compare_files(slurm / rel, local / rel, str(rel))
    failures = c.failures()
    fresh = slurm / rel
    identical += fresh.is_file() and fresh.read_bytes() == (local / rel).read_bytes()
    worst = max(worst, c.max_relative_difference())
    if failures:
        failed += 1
        print(f"  DIFFERS {rel}")
        for message in failures[:5]:
            print(f"    {message}")
for rel in only_slurm:
    failed += 1
    print(f"  only in the Slurm run: {rel}")
print(
    f"  {len(rels) - failed} of {len(rels)} agree; {identical} identical byte for byte; "
    f"largest relative difference {worst:.2g}"
)

print("\ncommitted tables (for information):")
for table in sorted((committed / "results/tables").iterdir()):
    rel = table.relative_to(committed)
    verdicts = [
        "agrees" if not compare_files(run / rel, table).failures() else "DIFFERS"
        for run in (local, slurm)
    ]
    print(f"  {str(rel):<36} local {verdicts[0]:<8} Slurm {verdicts[1]}")
sys.exit(1 if failed else 0)
EOF
echo "run_validation: the Slurm run's results agree with the local run's"
