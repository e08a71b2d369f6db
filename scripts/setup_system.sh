#!/usr/bin/env bash
# Installs the Debian packages qogi builds against, when any is missing.
# As root it runs apt-get itself; otherwise it stops and prints the command.
set -euo pipefail

PACKAGES=(
  g++ make pkg-config
  clang                  # the second compiler: `make check-clang` builds the engine with it, warnings as errors
  ccache                 # compiler cache: a second build (a clone, the wheel) reuses objects
  libeigen3-dev          # Eigen3
  libceres-dev           # Ceres Solver 2.1
  libopencv-dev          # OpenCV 4 (its CMake config lives only in the full dev package)
  libgtest-dev           # GoogleTest for the C++ unit tests
  zlib1g-dev             # zlib: gzip-compressed HITRAN line files
  xvfb xauth             # virtual X server for the viewer's smoke test
  libgl1 libegl1         # OpenGL runtime Dear PyGui loads
  libgl1-mesa-dri        # Mesa's llvmpipe software OpenGL (the viewer under Xvfb; a mere Recommends of libgl1)
  libx11-6 libxrandr2 libxinerama1 libxcursor1 libxi6   # X11 libraries Dear PyGui's GLFW loads
  libxtst6               # XTEST: the smoke test clicks and drags with real X input events
  poppler-utils          # pdftoppm/pdftotext: the tests render and read the PDF report
)

missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
# A Debian system Python needs python3-venv for `python3 -m venv`.
PYTHON=${PYTHON:-python3}
if ! "$PYTHON" -c 'import ensurepip, venv' >/dev/null 2>&1; then
  missing+=(python3-venv)
fi

if [ ${#missing[@]} -eq 0 ]; then
  exit 0
fi
if ! command -v apt-get >/dev/null 2>&1; then
  echo "qogi setup: missing system packages: ${missing[*]}" >&2
  echo "This set-up knows Debian/Ubuntu (apt-get). Install the equivalents of the" >&2
  echo "packages above with your system's package manager, then run make again." >&2
  exit 1
fi
if [ "$(id -u)" -ne 0 ]; then
  echo "qogi setup: missing system packages: ${missing[*]}" >&2
  echo "Run this once, then run make again:" >&2
  echo "  sudo apt-get update && sudo apt-get install -y --no-install-recommends ${missing[*]}" >&2
  exit 1
fi
echo "qogi setup: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
apt-get update -q
apt-get install -y -q --no-install-recommends "${missing[@]}"
