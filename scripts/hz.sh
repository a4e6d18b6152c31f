#!/usr/bin/env bash
# hertzpetsc entry point: sets up whatever is missing, then runs a job.
#
#   bash scripts/hz.sh main    # set up, then compute the alpha = 3/2 branch on 2 ranks, its figures and table
#   bash scripts/hz.sh paper   # set up, then run every study of sections 3.1-3.5 and the appendix (resumable)
#   bash scripts/hz.sh test    # set up, then run the test suite (serial, then under mpiexec -n 2)
#   bash scripts/hz.sh setup   # set up only
#   bash scripts/hz.sh run CMD...   # run CMD with the project's environment (venv, MPI-as-root variables)
#
# Set-up is idempotent and needs only Debian's archive and PyPI: Debian's PETSc/SLEPc/MPI packages (a PETSc
# source build is far too slow), a venv made from the system interpreter that sees them, a .pth file that
# points it at petsc4py/slepc4py (no PETSC_DIR needed), an offline editable install of hertzpetsc, and the chain's
# compiled right-hand side (gcc; hertzpetsc/kernels.py).
set -euo pipefail

ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
VENV=${HZ_VENV:-$ROOT/.venv}
PY=$VENV/bin/python
NRANKS=${HZ_NRANKS:-2}
DEB_PACKAGES="python3-petsc4py python3-slepc4py python3-mpi4py python3-numpy python3-matplotlib python3-pytest \
python3-scipy python3-venv python3-pip python3-setuptools python3-h5py-mpi openmpi-bin time gcc libc6-dev"

# Open MPI refuses to run as root unless told; two ranks on two cores need no oversubscription, more do.
# A process started without mpiexec initialises MPI alone (no daemon: no host name lookup, which takes seconds
# where the host has no /etc/hosts entry), and the launcher adds no banner to a driver's one-line error.
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_rmaps_base_oversubscribe=1
export OMPI_MCA_ess_singleton_isolated=1 OMPI_MCA_orte_execute_quiet=1
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

# The dist-packages folder of Debian's petsc4py or slepc4py, found from the files of the installed packages
# python3-petsc4py* / python3-slepc4py* (whatever the architecture: .../<multiarch>-real/lib/python3/dist-packages).
debian_dist_packages() {
    local mod=$1 init
    init=$(dpkg-query -W -f='${Package}\n' "python3-$mod*" 2>/dev/null | while read -r pkg; do
        dpkg-query -L "$pkg" 2>/dev/null; done | grep "/$mod/__init__.py\$" | head -n 1)
    [ -n "$init" ] || { log "cannot find $mod in the files of the installed python3-$mod packages"; exit 1; }
    dirname "$(dirname "$init")"
}

need_venv() {
    local PETSC_PY SLEPC_PY
    PETSC_PY=$(debian_dist_packages petsc4py)
    SLEPC_PY=$(debian_dist_packages slepc4py)
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

# The compiled right-hand side of the chain (hertzpetsc/_chain_kernel.c, linked against Debian's libpetsc): built
# when missing or older than its source.
need_kernels() {
    "$PY" -m hertzpetsc.kernels >/dev/null || { log "could not build the chain kernel (gcc, libc6-dev)"; exit 1; }
}

setup() { need_debian_packages; need_venv; need_kernels; }

cmd=${1:-}
[ $# -gt 0 ] && shift
case "$cmd" in
    setup)
        setup ;;
    main)
        setup
        cd "$ROOT"
        mkdir -p results figures
        mpiexec -n "$NRANKS" "$PY" scripts/continuation.py -output results/branch_alpha1.5.npz -force -figures figures "$@"
        "$PY" scripts/paper_table.py -branch results/branch_alpha1.5.npz -output results/paper_table.md ;;
    paper)
        setup
        cd "$ROOT"
        "$PY" scripts/paper.py -ranks "$NRANKS" "$@" ;;
    test)
        setup
        cd "$ROOT"
        "$PY" -m pytest -p no:cacheprovider -q --color=no tests "$@"
        log "re-running the parallel-capable tests under mpiexec -n 2"
        timeout 900 mpiexec -n 2 "$PY" -m pytest -p no:cacheprovider -q --color=no -m "not serial" tests "$@" ;;
    run)
        setup
        cd "$ROOT"
        PATH="$VENV/bin:$PATH" "$@" ;;     # the venv's python first: `run scripts/x.py` and `run python ...` use it
    *)
        echo "usage: bash scripts/hz.sh {main|paper|test|setup|run CMD...}" >&2
        exit 2 ;;
esac
