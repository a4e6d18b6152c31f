#!/usr/bin/env bash
# Build a second PETSc/SLEPc stack (the newest release on PyPI, from its sources) and its Python bindings into a
# venv of its own, then run hertzpetsc's test suite on it (issue 40: the package is not tied to Debian's 3.18).
# Run once, by hand, not in CI: the build takes an hour or more on two cores.
#
#   bash scripts/build_petsc_from_sources.sh [VERSION] [PREFIX]       # default: 3.26.1, runs/petsc-sources
#   HZ_PYTHON=PREFIX/bin/python bash scripts/hz.sh test                 # the suite on that stack (the script ends so)
#
# Needs Debian's compilers and the MUMPS/ScaLAPACK libraries that the paper's defaults use on several ranks
# (apt-get, as root; skipped when HZ_NO_APT=1); PETSc's own --download-* options need the internet beyond PyPI,
# which this machine does not have. Every step is logged to PREFIX/build.log; a finished step is not redone.
set -euo pipefail
VERSION=${1:-3.26.1}
ROOT=$(cd "$(dirname "$0")/.." && pwd)
PREFIX=$(realpath -m "${2:-$ROOT/runs/petsc-sources}")
mkdir -p "$PREFIX"
LOG="$PREFIX/build.log"
say() { echo "[build $(date -u +%H:%M:%S)] $*" | tee -a "$LOG"; }

if [ "${HZ_NO_APT:-0}" != 1 ]; then
    say "Debian packages: compilers, BLAS/LAPACK, MUMPS, ScaLAPACK, Open MPI headers"
    DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends gfortran g++ libopenblas-dev \
        libmumps-dev libscalapack-openmpi-dev libopenmpi-dev openmpi-bin python3-venv python3-dev patchelf >>"$LOG" 2>&1
fi
[ -x "$PREFIX/bin/python" ] || python3 -m venv "$PREFIX"
PY="$PREFIX/bin/python"
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
say "build tools"
"$PY" -m pip install -q --upgrade pip setuptools wheel cython numpy >>"$LOG" 2>&1
# MUMPS and ScaLAPACK from Debian (the parallel direct solves of -tw_, -precomp_, -cm_); no debugging build
export PETSC_CONFIGURE_OPTIONS="--with-debugging=0 COPTFLAGS=-O2 CXXOPTFLAGS=-O2 FOPTFLAGS=-O2 \
--with-mumps-include=/usr/include --with-mumps-lib=[-ldmumps,-lmumps_common,-lpord] \
--with-scalapack-lib=-lscalapack-openmpi"
for pkg in petsc petsc4py slepc slepc4py; do
    if "$PY" -m pip show "$pkg" 2>/dev/null | grep -q "^Version: $VERSION$"; then
        say "$pkg $VERSION: already built"
        continue
    fi
    say "$pkg $VERSION from its sources (pip install --no-binary; this is the long part)"
    "$PY" -m pip install -v --no-build-isolation --no-binary "$pkg" "$pkg==$VERSION" >>"$LOG" 2>&1
done
say "mpi4py against this machine's Open MPI, and the package's other dependencies"
"$PY" -m pip install -q --no-binary mpi4py mpi4py >>"$LOG" 2>&1
"$PY" -m pip install -q scipy matplotlib pytest h5py jupytext >>"$LOG" 2>&1
"$PY" - <<'EOF' | tee -a "$LOG"
import petsc4py, slepc4py, mpi4py
from petsc4py import PETSc
from slepc4py import SLEPc
print("built: PETSc", PETSc.Sys.getVersion(), "SLEPc", SLEPc.Sys.getVersion(), "mpi4py", mpi4py.__version__,
      "MUMPS", PETSc.Sys.hasExternalPackage("mumps"))
EOF
say "done; the test suite on this stack: HZ_PYTHON=$PY bash scripts/hz.sh test"
