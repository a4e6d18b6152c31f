#!/usr/bin/env bash
# hertzpetsc entry point: sets up whatever is missing, then runs a job.
#
#   bash scripts/hz.sh main    # set up, then compute the alpha = 3/2 branch on 2 ranks, its figures and table
#   bash scripts/hz.sh test    # set up, then run the test suite (serial, then under mpiexec -n 2)
#   bash scripts/hz.sh setup   # set up only
#   bash scripts/hz.sh run CMD...   # run CMD with the project's environment (venv, MPI-as-root variables)
#
# Set-up is idempotent and needs only Debian's archive and PyPI: Debian's PETSc/SLEPc/MPI packages (a PETSc
# source build is far too slow), a venv made from the system interpreter that sees them, a .pth file that
# points it at petsc4py/slepc4py (no PETSC_DIR needed), and an offline editable install of hertzpetsc.
set -euo pipefail

ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
VENV=${HZ_VENV:-$ROOT/.venv}
PY=$VENV/bin/python
NRANKS=${HZ_NRANKS:-2}
PETSC_PY=/usr/lib/petscdir/petsc3.18/x86_64-linux-gnu-real/lib/python3/dist-packages
SLEPC_PY=/usr/lib/slepcdir/slepc3.18/x86_64-linux-gnu-real/lib/python3/dist-packages
DEB_PACKAGES="python3-petsc4py python3-slepc4py python3-mpi4py python3-numpy python3-matplotlib python3-pytest \
python3-scipy python3-venv python3-pip python3-setuptools openmpi-bin time"

# Open MPI refuses to run as root unless told; two ranks on two cores need no oversubscription, more do.
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_rmaps_base_oversubscribe=1
export MPLBACKEND=Agg PYTHONDONTWRITEBYTECODE=1

log() { echo "[hz] $*" >&2; }

need_debian_packages() {
    local missing=()
    for p in $DEB_PACKAGES; do
        dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
    done
    if [ ${#missing[@]} -gt 0 ]; then
        log "installing Debian packages: ${missing[*]}"
        local sudo=""
        [ "$(id -u)" -eq 0 ] || sudo="sudo"
        $sudo apt-get update -qq
        DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
    fi
}

need_venv() {
    if [ ! -x "$PY" ]; then
        log "creating venv $VENV from /usr/bin/python3"
        /usr/bin/python3 -m venv --system-site-packages "$VENV"
    fi
    local site
    site=$("$PY" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')
    printf '%s\n%s\n' "$PETSC_PY" "$SLEPC_PY" > "$site/hertzpetsc-petsc-debian.pth"
    if ! "$PY" -c 'import hertzpetsc' 2>/dev/null || [ "$ROOT/pyproject.toml" -nt "$VENV/.hz-installed" ]; then
        log "installing hertzpetsc (editable, offline, no dependency resolution)"
        "$PY" -m pip install -q --no-build-isolation --no-index --no-deps -e "$ROOT"
        touch "$VENV/.hz-installed"
    fi
    "$PY" -c 'from petsc4py import PETSc; from slepc4py import SLEPc; from mpi4py import MPI; import matplotlib' \
        || { log "the PETSc/SLEPc/MPI stack does not import in $VENV"; exit 1; }
}

setup() { need_debian_packages; need_venv; }

cmd=${1:-}
[ $# -gt 0 ] && shift
case "$cmd" in
    setup)
        setup ;;
    main)
        setup
        cd "$ROOT"
        mkdir -p results figures
        mpiexec -n "$NRANKS" "$PY" scripts/continuation.py -output results/branch_alpha1.5.npz -figures figures "$@"
        "$PY" scripts/paper_table.py -branch results/branch_alpha1.5.npz -output results/paper_table.md ;;
    test)
        setup
        cd "$ROOT"
        "$PY" -m pytest -p no:cacheprovider -q --color=no tests "$@"
        log "re-running the parallel-capable tests under mpiexec -n 2"
        timeout 900 mpiexec -n 2 "$PY" -m pytest -p no:cacheprovider -q --color=no -m "not serial" tests "$@" ;;
    run)
        setup
        cd "$ROOT"
        "$@" ;;
    *)
        echo "usage: bash scripts/hz.sh {main|test|setup|run CMD...}" >&2
        exit 2 ;;
esac
