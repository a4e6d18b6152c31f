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
#
# A PETSc of your own (conda-forge, a cluster's module, a source build): with HZ_PYTHON=/path/to/python, or in an
# active conda environment ($CONDA_PREFIX) whose python imports petsc4py, slepc4py and mpi4py, the venv is made
# from that interpreter instead and nothing is installed with apt-get (docs/running.md, "Install into your own
# environment"). Either way set-up says which PETSc it uses.
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

# The interpreter of a PETSc of the user's own: HZ_PYTHON (which must import the stack), else the active conda
# environment's python when it imports petsc4py, slepc4py and mpi4py; empty: Debian's packages. A Debian root with
# neither (CI, a fresh machine) takes the Debian route, whatever other pythons are on its PATH.
STACK='import petsc4py, slepc4py, mpi4py'
own_python() {
    if [ -n "${HZ_PYTHON:-}" ]; then
        "$HZ_PYTHON" -c "$STACK" 2>/dev/null \
            || { log "HZ_PYTHON=$HZ_PYTHON does not import petsc4py, slepc4py and mpi4py"; exit 1; }
        echo "$HZ_PYTHON"
    elif [ -n "${CONDA_PREFIX:-}" ] && [ -x "$CONDA_PREFIX/bin/python" ] \
            && "$CONDA_PREFIX/bin/python" -c "$STACK" 2>/dev/null; then
        echo "$CONDA_PREFIX/bin/python"
    fi
}

# The venv $VENV made from interpreter $1 (with its site packages), remade when it was made from another one.
make_venv() {
    local base=$1 made=""
    [ -f "$VENV/.hz-python" ] && made=$(cat "$VENV/.hz-python")
    if [ -x "$PY" ] && [ -n "$made" ] && [ "$made" != "$base" ]; then
        log "remaking venv $VENV from $base (it was made from $made)"
        rm -rf "$VENV"
    fi
    if [ ! -x "$PY" ]; then
        log "creating venv $VENV from $base"
        "$base" -m venv --system-site-packages "$VENV"
    fi
    echo "$base" > "$VENV/.hz-python"
}

# hertzpetsc in the venv, editable, without dependency resolution (the environment provides them), offline when
# the environment has setuptools >= 64, else with pip's build isolation (which downloads setuptools).
install_hertzpetsc() {
    if ! "$PY" -c 'import hertzpetsc' 2>/dev/null || [ "$ROOT/pyproject.toml" -nt "$VENV/.hz-installed" ]; then
        log "installing hertzpetsc (editable, no dependency resolution)"
        "$PY" -m pip install -q --no-build-isolation --no-index --no-deps -e "$ROOT" 2>/dev/null \
            || "$PY" -m pip install -q --no-deps -e "$ROOT"
        touch "$VENV/.hz-installed"
    fi
}

# The stack must import in the venv, at PETSc >= 3.18 (else one line says what is missing); say which PETSc it is.
check_stack() {
    "$PY" - <<'PYEOF' || exit 1
import importlib, sys
missing = []
for name in ("petsc4py.PETSc", "slepc4py.SLEPc", "mpi4py.MPI", "numpy", "scipy", "matplotlib"):
    try:
        importlib.import_module(name)
    except ImportError as err:
        missing.append("%s (%s)" % (name.split(".")[0], err))
if missing:
    sys.exit("[hz] %s lacks %s: install them into the environment (conda install -c conda-forge petsc4py "
             "slepc4py mpi4py numpy scipy matplotlib)" % (sys.prefix, ", ".join(missing)))
import petsc4py
from petsc4py import PETSc
version = PETSc.Sys.getVersion()
if version < (3, 18):
    sys.exit("[hz] PETSc %s is too old: hertzpetsc needs PETSc, SLEPc and their bindings >= 3.18"
             % ".".join(map(str, version)))
config = petsc4py.get_config()
where = config.get("PETSC_DIR", "") + (("/" + config["PETSC_ARCH"]) if config.get("PETSC_ARCH") else "")
print("[hz] using PETSc %s from %s (petsc4py %s)" % (".".join(map(str, version)), where or petsc4py.__file__,
                                                     petsc4py.__version__), file=sys.stderr)
PYEOF
}

need_venv() {
    local PETSC_PY SLEPC_PY
    PETSC_PY=$(debian_dist_packages petsc4py)
    SLEPC_PY=$(debian_dist_packages slepc4py)
    make_venv /usr/bin/python3
    local site
    site=$("$PY" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')
    printf '%s\n%s\n' "$PETSC_PY" "$SLEPC_PY" > "$site/hertzpetsc-petsc-debian.pth"
    install_hertzpetsc
    check_stack
}

# The venv from the user's own interpreter, with a .pth file naming the folders its stack imports from (its site
# packages when it is a base interpreter, a conda environment's; those of a venv it belongs to, which a venv made
# from it would not see); its bin folder (mpiexec) on the PATH after the venv's.
need_own_venv() {
    make_venv "$1"
    local site
    site=$("$PY" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')
    rm -f "$site/hertzpetsc-petsc-debian.pth"
    "$1" -c 'import importlib, os
for name in ("petsc4py", "slepc4py", "mpi4py", "numpy", "scipy", "matplotlib", "pytest", "h5py"):
    try:
        print(os.path.dirname(os.path.dirname(importlib.import_module(name).__file__)))
    except ImportError:
        pass' | sort -u > "$site/hertzpetsc-own-stack.pth"
    install_hertzpetsc
    check_stack
    export PATH="$(dirname "$1"):$PATH"
}

# The compiled right-hand side of the chain (hertzpetsc/_chain_kernel.c, linked against the libpetsc the venv
# uses): built when missing, older than its source or built against another PETSc. On Debian a failure is an error
# (hz.sh installs gcc); with the user's own PETSc the chains then use the numpy right-hand side, and set-up says so.
need_kernels() {
    if [ -n "$OWN" ]; then
        "$PY" -m hertzpetsc.kernels >/dev/null \
            || log "the chains will use the numpy right-hand side (same results, slower); a C compiler builds the other"
    else
        "$PY" -m hertzpetsc.kernels >/dev/null || { log "could not build the chain kernel (gcc, libc6-dev)"; exit 1; }
    fi
}

setup() {
    OWN=$(own_python) || exit 1
    if [ -n "$OWN" ]; then
        need_own_venv "$OWN"
    else
        need_debian_packages
        need_venv
    fi
    need_kernels
}

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
        "$PY" -c 'import pytest' 2>/dev/null \
            || { log "the tests need pytest in the environment of $VENV (conda install pytest)"; exit 1; }
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
