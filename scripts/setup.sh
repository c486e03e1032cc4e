#!/usr/bin/env bash
# Set-up shared by the README commands: gfortran (apt-get when root), a venv
# in .venv with the dependencies, and a build + install of this package
# (engine executable `partsim` on the venv's PATH, f2py module pyorch._engine).
# Idempotent: the package is rebuilt only when its sources changed.
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
PY=${PYTHON:-python3}
VENV=${PYORCH_VENV:-$ROOT/.venv}

say() { printf '[setup] %s\n' "$*" >&2; }

if ! command -v gfortran >/dev/null 2>&1; then
  if [ "$(id -u)" = "0" ] && command -v apt-get >/dev/null 2>&1; then
    say "gfortran missing: installing it with apt-get"
    apt-get update -qq >/dev/null
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq gfortran >/dev/null
  elif command -v sudo >/dev/null 2>&1 && sudo -n true 2>/dev/null && command -v apt-get >/dev/null 2>&1; then
    say "gfortran missing: installing it with sudo apt-get"
    sudo apt-get update -qq >/dev/null
    sudo DEBIAN_FRONTEND=noninteractive apt-get install -y -qq gfortran >/dev/null
  else
    echo "error: gfortran (GNU Fortran >= 10) is required and could not be installed automatically." >&2
    echo "       Debian/Ubuntu: sudo apt-get install gfortran;  Fedora: sudo dnf install gcc-gfortran;" >&2
    echo "       conda: conda install -c conda-forge gfortran. Then run this command again." >&2
    exit 1
  fi
fi

if ! "$PY" -c 'import sys; sys.exit(0 if sys.version_info >= (3, 10) else 1)'; then
  echo "error: Python >= 3.10 is required ($PY is $("$PY" --version 2>&1))" >&2
  exit 1
fi

if [ ! -x "$VENV/bin/python" ]; then
  say "creating virtual environment $VENV"
  "$PY" -m venv "$VENV"
fi
PIP=("$VENV/bin/python" -m pip --disable-pip-version-check -q)
export PATH="$VENV/bin:$PATH"   # meson and ninja of the venv for the build

DEPS_STAMP="$VENV/.pyorch-deps"
deps_hash=$(sha256sum "$ROOT/pyproject.toml" "$ROOT/scripts/setup.sh" | sha256sum | cut -c1-16)
if [ "$(cat "$DEPS_STAMP" 2>/dev/null)" != "$deps_hash" ]; then
  say "installing dependencies into $VENV"
  "${PIP[@]}" install --upgrade pip >/dev/null
  "${PIP[@]}" install "numpy>=2.0" "scipy>=1.10" "pandas>=2.0" "matplotlib>=3.7" "f90nml>=1.4" \
    "tqdm>=4.60" "astropy>=5.0" "dask[distributed]>=2023.1" "dask-jobqueue>=0.8" \
    "tomli>=1.1; python_version < '3.11'" "pytest>=7" "hypothesis>=6" \
    "nbformat>=5.7" "nbclient>=0.7" "ipykernel>=6" \
    "meson-python>=0.15" "meson>=1.4" ninja \
    "gsd>=3.2" "imageio>=2.28" "imageio-ffmpeg>=0.4.8" "ase>=3.22"
  echo "$deps_hash" > "$DEPS_STAMP"
fi

BUILD_STAMP="$VENV/.pyorch-build"
src_hash=$( (cd "$ROOT" && find fortran pyorch meson.build meson.options pyproject.toml -type f \
  ! -name '*.pyc' -print0 | sort -z | xargs -0 sha256sum; echo "native=${PYORCH_NATIVE:-1}") \
  | sha256sum | cut -c1-16)
if [ "$(cat "$BUILD_STAMP" 2>/dev/null)" != "$src_hash" ] || [ ! -x "$VENV/bin/partsim" ]; then
  say "building and installing pyorch + partsim (meson-python)"
  # tuned for this machine (-march=native) unless PYORCH_NATIVE=0
  native=()
  [ "${PYORCH_NATIVE:-1}" = "1" ] && native=(-Csetup-args=-Dnative=true)
  (cd "$ROOT" && "${PIP[@]}" install --no-build-isolation --no-deps "${native[@]}" . )
  echo "$src_hash" > "$BUILD_STAMP"
fi
